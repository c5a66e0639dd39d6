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

class Preflight {
public:
    static constexpr std::size_t kMaxRanges = 100;
    Preflight(const Machine& machine, double baud);

    void scan(std::string_view output);  // whole lines of written output
    void finish();                        // the end of the file: the planner runs out

    double seconds() const { return done_; }             // planned motion and dwells, without link stalls
    double dwell_seconds() const { return dwell_; }       // of which the dwells (G4)
    std::uint64_t dwells() const { return dwells_; }
    std::uint64_t heat_waits() const { return heat_waits_; }  // M109, M190, M191, M116: not in the time
    double seconds_with_link() const { return clock_; }  // with the link's stalls
    std::string json() const;                            // the report's "preflight" object
    std::string summary() const;                         // one paragraph for a terminal

    struct Range {
        std::uint64_t first, last;  // output lines
        double stall;               // seconds the planner sat empty
    };
    const std::vector<Range>& drains() const { return ranges_; }

    // Told of each block as the planner executes it, in order, and of each dwell when it runs:
    // the output line of its move or dwell and the seconds it takes (the slicer's time lines are
    // rewritten from these).
    std::function<void(std::uint64_t line, double seconds)> executed;

private:
    struct Block {
        double length, nominal, entry_max, entry = 0, time = 0;
        std::vector<double> unit;
        std::uint64_t line;
        double bytes_at;  // link time at which it arrived
    };
    void line(std::string_view l);
    void add_move(const std::vector<double>& from, const std::vector<double>& to, double feed);
    void plan_and_pop();
    void wait(double seconds);  // the planner runs out, then the firmware waits
    void execute(Block& b, double exit);

    const Machine& m_;
    double link_bytes_per_s_;
    double dwell_ = 0;
    std::uint64_t dwells_ = 0, heat_waits_ = 0;
    std::vector<double> q_;
    double f_ = 0;
    std::uint64_t lines_ = 0, sent_ = 0, bytes_ = 0, moves_ = 0, short_moves_ = 0;
    std::string pending_;
    std::deque<Block> window_;
    double link_ = 0;          // when the link has sent everything so far (s)
    double clock_ = 0;         // when the firmware finished the last executed block (s), stalls included
    double done_ = 0;
    double line_seconds_ = 0;  // the link's time for the line read
    double prev_exit_ = 0;
    std::vector<double> prev_unit_;
    std::deque<double> finished_;  // when each of the last `blocks` executed blocks ended (buffer room)
    std::vector<Range> ranges_;
    std::uint64_t drains_ = 0;
    double stall_ = 0, peak_need_ = 0;
    std::deque<std::pair<double, double>> need_;  // last blocks' (bytes, seconds)
};

}  // namespace xlate5
