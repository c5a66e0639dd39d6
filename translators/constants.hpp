// SPDX-License-Identifier: GPL-3.0-or-later
// Shared numbers of the library: pi and its degree factors, and the tolerances more than one
// stage must agree on. No stage; included by any file that needs them, and calls nothing.
#pragma once

namespace xlate5 {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTwoPi = 2.0 * kPi;
inline constexpr double kRadPerDeg = kPi / 180.0;
inline constexpr double kDegPerRad = 180.0 / kPi;

// A joint value this far outside its limits still counts as inside: solved values carry
// rounding of that order, and a limit written in the machine file must be reachable exactly.
inline constexpr double kLimitSlack = 1e-9;
// An absent joint (a machine without that axis, e.g. a polar printer's Y): the solve may put it
// this far from its home (mm), no more: what tool-space rounding leaves in a pose the machine
// reaches (a tool-space file's 7 decimals give microns at most). Never written to the firmware.
inline constexpr double kAbsentSlack = 1e-3;
// Two solutions whose rotaries differ by less than this (degrees) are the same solution.
inline constexpr double kSameAngle = 1e-6;

// Output moves one input line may become (the pieces of a split move, the chords of an arc and
// their pieces together): a line that needs more is refused at its column, so one short line
// cannot turn into an unbounded output (docs/limits.md).
inline constexpr int kMaxPiecesPerLine = 10000;

// The bound in force for a machine's `motion.max_pieces`: 0 (unset) or above the bound is the
// bound; a program may only lower it.
inline constexpr int pieces_bound(int requested) {
    return requested <= 0 || requested > kMaxPiecesPerLine ? kMaxPiecesPerLine : requested;
}

}  // namespace xlate5
