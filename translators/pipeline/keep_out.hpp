// SPDX-License-Identifier: GPL-3.0-or-later
// The keep-out stage, between the interpreter and the planner (ADD_IN team, 2015:
// a 4-axis printer whose nozzle turns about its own vertical axis R to keep clear of parts placed
// inside the print). For each printing move R is set normal to the path, toward the nearest
// keep-out item whose height is at or below the current Z, the side chosen by the source's
// determinant test (its step 4); an item on the line of a move is an error (its step 7). The two
// problems the source left open:
//  - direction of rotation: R is continuous (programmed angles never wrap); where R must change
//    it turns in place before the move, the way on which the nozzle never points away from the
//    nearest item (while the item stays the same this is the shorter way, since R stays within
//    90 degrees of the item's direction on both sides). Only travel moves may end on another
//    turn of R (the planner's and the look-back's unwinding inside the joint limits); a turn in
//    place that would pass a limit is reported as a limit hit, so the look-back unwinds on the
//    travel move before it.
//  - long moves: a printing move is split where the nearest item changes (where it crosses the
//    bisector between two items, or reaches the height of another), each piece with its own R,
//    so the nozzle never points away mid-move. Within a piece R is constant: the side of a
//    straight line an item lies on does not change along it.
// Travel moves get R the same way at their end (no split, no turn in place). Moves without an
// X/Y change keep R. Stateless between moves (everything it needs is in the planner's state, which
// it reads), so the look-back's copies of the state and its replays need nothing from it. It hands
// its moves on as values (KeepOutMoves), which translator.cpp runs through the planner in turn.
// May call: kinematics (the machine's check), the planner's angle map.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "translators/error.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/pipeline/planner.hpp"

namespace xlate5 {

struct KeepOutItem {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    double height = 0;         // the item counts once the nozzle is at or above this Z
    std::uint64_t line = 0;    // in its file, for messages
};

struct KeepOutItems {
    std::string file;
    std::vector<KeepOutItem> items;
};

// The largest keep-out file read (docs/limits.md): a few thousand items, where a print holds a
// handful; every printing move is checked against every item.
inline constexpr std::size_t kMaxKeepOutBytes = 64u << 10;

// Reads `x, y, height` per line (commas or blanks; `#` comments; blank lines). Throws
// InputError(file, line, column, cause) for anything else or a file past kMaxKeepOutBytes,
// IoError if it cannot be read. Numbers are within +-1e9 (the lexer's bound).
KeepOutItems load_keep_out(const std::string& path);
KeepOutItems parse_keep_out(const std::string& text, const std::string& name);

// What the keep-out stage makes of one tool move: the moves for the planner, to be run in order,
// and then, when it refuses the move at some point, the refusal (after the moves before that
// point, as a refusal found while running them).
struct KeepOutMoves {
    struct Step {
        ToolMove move;
        // A turn of R in place before a piece: no travel move, so it never unwinds (run on a
        // LineRun of its own; only its limit hit is the line's).
        bool turn = false;
    };
    std::vector<Step> steps;
    std::optional<LineError> refusal;
    bool refused_at_limit = false;  // the refusal is a limit hit (the look-back unwinds before it)
};

class KeepOutStage {
public:
    // Throws MachineError unless the machine has one rotary joint and turning it leaves the tool
    // axis vertical (it turns the nozzle about its own axis), and the input is in angle form.
    // `state` is the planner's: where the machine is before each move.
    KeepOutStage(const Kinematics& kinematics, const KeepOutItems& items, const PlannerState& state);
    // The move with R set (split, with turns in place, when printing), from where the machine
    // is; valid until the next call.
    const KeepOutMoves& tool_move(const ToolMove& mv);

private:
    // The item nearest to p among those at or below z (-1: none).
    int nearest(const Eigen::Vector2d& p, double z) const;
    // Pointing angle (deg) normal to direction d toward item k from p; throws if on the line.
    double normal_toward(const Eigen::Vector2d& p, const Eigen::Vector2d& d, int k, std::uint32_t column) const;
    // The continuous R nearest `from` that points along `r` (mod 360), turning the way on which
    // the nozzle never points directly away from items a or b (at p); `shift` maps it to the joint.
    double continuous(double from, double r, const Eigen::Vector2d& p, int a, int b, double shift) const;
    // tool_move's moves into moves_; throws LineError where it refuses the move.
    void make_moves(const ToolMove& mv);
    // A move with R at `r` (programmed), after those made so far.
    void send(const ToolMove& mv, double r, bool turn = false);
    // A printing move's pieces into pieces_: constant eligibility, then constant nearest item.
    void find_pieces(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2);
    // Before a piece: R turned in place to `target` (programmed; + shift: the joint) at `at`;
    // throws at R's limits.
    void turn_in_place(const ToolMove& mv, const Eigen::Vector3d& at, double target, double shift, double e_at);

    const Kinematics& kin_;
    const KeepOutItems& items_;
    const PlannerState& state_;
    const AngleMap angles_;  // programmed angles <-> joints
    KeepOutMoves moves_;
    int r_ = -1;  // the rotary joint
    Joints current_;  // scratch: the programmed angles where the machine is
    std::vector<std::pair<double, int>> pieces_;  // (end parameter, nearest item)
};

}  // namespace xlate5
