// SPDX-License-Identifier: GPL-3.0-or-later
// The kinematic-error report: how far the firmware's joint-linear path leaves the programmed
// tool-space path, per file, so a user can inspect a file before printing it. Memory is bounded
// whatever the file size (histograms and a series that halves its resolution as it grows).
// Beside the stages: the planner logs each measured move into it. May call: nothing of the
// pipeline.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "translators/inspect/report_events.hpp"
#include "translators/inspect/report_stats.hpp"

namespace xlate5 {

// The report: the values it accumulates are its parts (report_stats.hpp, report_events.hpp),
// added to by the planner's MoveLog and the collision check, read by its writers (json: report_json.cpp,
// svg: report_plot.cpp) and by the preview.
class DeviationReport {
public:
    using MarkKind = EventLog::MarkKind;
    using Mark = EventLog::Mark;
    using CollisionMark = CollisionLog::Mark;

    DeviationReport(std::string file, std::string machine, double tolerance, double angle_tolerance);

    // One input move (MoveStats::add).
    void add_move(std::uint64_t line, double tip, double angle, double feed_error, int pieces) {
        stats.add(line, tip, angle, feed_error, pieces);
    }
    void set_lines(std::uint64_t in, std::uint64_t out) { lines_in_ = in, lines_out_ = out; }
    // Members an observer of the written output adds to json() (the preview's scan: what only the
    // written lines tell), each line "  \"name\": value,\n".
    void set_written(std::string members) { written_ = std::move(members); }
    std::string json() const;
    std::string svg() const;

    const std::vector<Mark>& marks() const { return events.marks(); }
    double max_tip() const { return stats.tip.max; }
    std::uint64_t worst_tip_line() const { return stats.tip.max_line; }

    MoveStats stats;
    EventLog events;
    JointTotals joints;
    CollisionLog collisions;

private:
    std::string file_, machine_;
    double tolerance_, angle_tolerance_;
    std::uint64_t lines_in_ = 0, lines_out_ = 0;
    std::string written_;
};

struct Machine;
struct MoveResult;

// Measured moves on their way to the report: added at once, or, while the look-back holds the
// output they belong to (at least their own line's), held and released with it (dropped when it
// translates them again or refuses their line).
class MoveLog {
public:
    MoveLog(DeviationReport& report, const Machine& machine) : report_(report), machine_(machine) {}

    void hold(bool on) { hold_ = on; }
    void set_rotary_bound(double degrees) { report_.joints.set_rotary_bound(degrees); }
    void add(std::uint64_t line, const MoveResult& m);
    // G92s that re-zeroed a rotary after a move that is not measured (a joint move before the
    // program placed the tip): counted and marked like a measured move's.
    void add_rezeros(std::uint64_t line, std::uint64_t moves_written, int rezeros);

    // A held move, and the rotary travel of the held moves (each move's ends at travel_end).
    struct Pending {
        std::uint64_t line;
        double tip, angle, feed;
        int pieces;
        std::size_t travel_end;
        double minutes;
        int change;  // SolutionChange
        int pole_crossings;
        bool half_turn;
        int rezeros;
        bool printing_turn;
        std::uint64_t moves_written;
        bool measured;  // false: only its re-zeros (add_rezeros)
    };
    struct Held {
        std::vector<Pending> moves;
        std::vector<std::pair<char, double>> travel;
        std::vector<double> ranges;  // per held move, low and high of every joint
    };
    std::size_t held_count() const { return held_.moves.size(); }
    void release(std::size_t moves);  // the first `moves` held moves go to the report
    const Held& held() const { return held_; }
    void set_held(const Held& h) { held_ = h; }
    void drop_held() {
        held_.moves.clear();
        held_.travel.clear();
        held_.ranges.clear();
    }
    // The held moves from the `moves`-th on are dropped: a refused line's, whose output is dropped.
    void drop_held_from(std::size_t moves);

private:
    void add_rest(const double* ranges, double minutes, int change);  // ranges: low, high of every joint
    DeviationReport& report_;
    const Machine& machine_;
    bool hold_ = false;
    Held held_;
    std::vector<double> ranges_;  // scratch: one move's low and high of every joint
};

}  // namespace xlate5
