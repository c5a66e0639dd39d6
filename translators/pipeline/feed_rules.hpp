// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware's feed rule: the length a firmware divides F by for a move of its joints, one
// function per rule, and the F a piece needs so that the firmware gives it the time the
// programmed feed asks (docs/firmware.md gives each firmware's rule). Stage: motion (each piece's F); the
// report and the tests measure with firmware_length. May call: the machine data.
#pragma once
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include "translators/machine/machine.hpp"
#include "translators/pipeline/emitter.hpp"

namespace xlate5 {

// The machine's joints by kind, looked up once (each rule sums over them in this order).
struct JointKinds {
    std::vector<std::size_t> linear, rotary;
};

// A rule: the length of the move between two ends as printed, `e` the move's extrusion (mm,
// its size; only Klipper counts it).
using LengthRule = double (*)(const double* q0, const double* q1, const JointKinds& kinds, double e);

// Marlin, RepRapFirmware and the generic dialect (NIST RS274NGC's rule): the XYZ length when a
// linear joint moves, else the rotaries' length.
double nist_length(const double* q0, const double* q1, const JointKinds& kinds, double e);
// Marlin built with ARTICULATED_ROBOT_ARM: every axis counts, millimetres and degrees alike.
double marlin_articulated_length(const double* q0, const double* q1, const JointKinds& kinds, double e);
// Klipper's toolhead: the XYZ length when one moves, else the largest single move of E and the
// extra axes.
double klipper_length(const double* q0, const double* q1, const JointKinds& kinds, double e);

LengthRule length_rule(FirmwareDialect firmware);

// The rule of the machine's dialect between q0 and q1, each joint first rounded as it is printed.
double firmware_length(const Machine& machine, const std::vector<double>& q0, const std::vector<double>& q1);

// A positive feed that would be written as 0 at `decimals`, written with more (Marlin reads F0 as
// no F and keeps the last feed).
PassedNumber feed_number(double v, int decimals);

// One move's terms of its pieces' feeds.
struct MoveFeed {
    double minutes = 0;        // the whole move's duration at the programmed feed (0: none)
    double length = 0;         // its tip length (0: a pure turn)
    double feed = 0;           // the programmed feed, mm/min (0: none yet)
    double inverse_time = 0;   // G93 input: the move's F
    std::optional<PassedNumber> f;  // F as written on the line
    double e = 0;              // the move's extrusion, mm (its size)
    bool inverse_time_out = false;  // the firmware is given G93 feeds
};

// A piece's F and the time it takes (minutes).
struct PieceFeed {
    std::optional<PassedNumber> f;
    double minutes = 0;
};

// The feed rule of one machine: the time each piece must take (its share of the move, no joint
// above its max_feed, a pure turn at the rotary feed) and the F that gives it.
class FeedRule {
public:
    explicit FeedRule(const Machine& machine);
    // The piece from qprev to qk (as printed) that is `share` of the move.
    PieceFeed piece(const MoveFeed& move, std::span<const double> qprev, std::span<const double> qk, double share) const;
    const JointKinds& kinds() const { return kinds_; }

private:
    struct FeedLimit {
        std::size_t joint;
        double max_feed;
    };
    LengthRule length_;
    JointKinds kinds_;
    std::vector<FeedLimit> limits_;
    double rotary_feed_;
};

}  // namespace xlate5
