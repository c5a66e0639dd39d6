// SPDX-License-Identifier: GPL-3.0-or-later
// The pre-flight estimate of a written file (--report's "preflight", and a summary on a
// terminal): how long the firmware takes, with its own acceleration and junction rules, and
// whether a serial link keeps its planner fed. Stage: an observer of the written output, like
// the preview. May call: the machine data, firmware_length (the dialect's length rule).
// The model (docs/preflight.md): each written move a block of the dialect's length at its
// feed, capped by each joint's max_feed; Marlin's junction deviation limits the speed between
// blocks; the planner plans over its horizon of `blocks` blocks (each block's exit speed such
// that the last can stop), a trapezoid per block. The link sends every line as Marlin's hosts
// do ("N<n> <line>*<checksum>", 10 bits a byte); the firmware takes a line when its buffer has
// room, and the buffer drains when the next move has not arrived as the last one ends.
// Waits (docs/preflight.md): a dwell (G4 P<ms>, S<s>; Klipper reads P only) and M400 first let
// the planner run out, as the firmware does, then G4 waits its time; waits for heating
// (M109, M190, M191, M116) cannot be known and are counted apart, not in the time.
// Memory is bounded: the horizon's blocks, and at most kMaxRanges drain ranges.
#pragma once
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "translators/machine/machine.hpp"

namespace xlate5 {

// The firmware's planner as the pre-flight models it: a horizon of `blocks` blocks planned
// backward for their entry speeds (each block's exit such that the last can stop), the first
// executed as a trapezoid when the horizon is full; a block starts when the last has ended and
// its line has arrived over the link, and where it had to wait the buffer drained.
class PlannerModel {
public:
    static constexpr std::size_t kMaxRanges = 100;
    struct Block {
        double length = 0, nominal = 0, entry_max = 0, time = 0;
        std::vector<double> unit;
        std::uint64_t line = 0;
        double bytes_at = 0;  // link time at which it arrived
    };
    struct Range {
        std::uint64_t first, last;  // output lines
        double stall;               // seconds the planner sat empty
    };
    using Executed = std::function<void(std::uint64_t line, double seconds)>;

    // `executed` (may be empty) is told of each block and wait as it runs.
    PlannerModel(const Machine& machine, const Executed& executed) : m_(machine), executed_(executed) {}

    // A block (its length, nominal speed, unit direction and line set; the junction from the last
    // block is found here) whose line took `line_seconds` over the link: it arrives when the link
    // has sent it and the planner has room, and `link` (s) comes back as when it did.
    void add(Block b, double line_seconds, double& link);
    // The planner runs out, then the firmware waits `seconds` (G4; 0: M400) from when the line
    // arrived (`link`), told as a run at `line`.
    void wait(double seconds, double link, std::uint64_t line);
    void finish() {
        while (!window_.empty()) plan_and_pop();
    }

    double seconds() const { return done_; }  // blocks and waits, without link stalls
    double clock() const { return clock_; }   // with them
    const std::vector<Range>& drains() const { return ranges_; }
    std::uint64_t drain_count() const { return drains_; }
    double stall_seconds() const { return stall_; }

private:
    void plan_and_pop();
    void execute(Block& b, double exit);

    const Machine& m_;
    const Executed& executed_;
    std::deque<Block> window_;
    double clock_ = 0;  // when the firmware finished the last executed block (s), stalls included
    double done_ = 0;
    double prev_exit_ = 0;
    std::vector<double> prev_unit_;
    std::deque<double> finished_;  // when each of the last `blocks` executed blocks ended (buffer room)
    std::vector<Range> ranges_;
    std::uint64_t drains_ = 0;
    double stall_ = 0;
};

class Preflight {
public:
    static constexpr std::size_t kMaxRanges = PlannerModel::kMaxRanges;
    using Range = PlannerModel::Range;
    Preflight(const Machine& machine, double baud);

    void scan(std::string_view output);  // whole lines of written output
    void finish() { planner_.finish(); }  // the end of the file: the planner runs out

    double seconds() const { return planner_.seconds(); }  // planned motion and dwells, without link stalls
    double seconds_with_link() const { return planner_.clock(); }
    struct Waits {
        std::uint64_t dwells = 0;      // G4
        double dwell_seconds = 0;      // counted in seconds()
        std::uint64_t heat_waits = 0;  // M109, M190, M191, M116: not in the time
    };
    const Waits& waits() const { return waits_; }
    const std::vector<Range>& drains() const { return planner_.drains(); }
    std::string json() const;     // the report's "preflight" object
    std::string summary() const;  // one paragraph for a terminal

    // Told of each block as the planner executes it, in order, and of each dwell when it runs:
    // the output line of its move or dwell and the seconds it takes (the slicer's time lines are
    // rewritten from these).
    PlannerModel::Executed executed;

private:
    // What a host sends: each line numbered and checksummed, 10 bits a byte.
    struct Link {
        double bytes_per_s;
        std::uint64_t sent = 0, bytes = 0;
        double at = 0;            // when the link has sent everything so far (s)
        double line_seconds = 0;  // the link's time for the line read
    };
    void line(std::string_view l);
    void add_move(const std::vector<double>& from, const std::vector<double>& to, double feed);

    const Machine& m_;
    Link link_;
    Waits waits_;
    std::vector<double> q_;
    double f_ = 0;
    std::uint64_t lines_ = 0, moves_ = 0, short_moves_ = 0;
    std::string pending_;
    PlannerModel planner_{m_, executed};
};

}  // namespace xlate5
