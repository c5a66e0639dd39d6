// SPDX-License-Identifier: GPL-3.0-or-later
// The slicer's progress and time lines of a written file, rewritten from xlate5's own pre-flight
// estimate of that file (docs/preflight.md, "The slicer's time lines"): splitting and joint
// limits change the time, and a printer's display or OctoPrint shows what the file says.
// Stage: after the sink, on the whole written file before it is renamed into place (the total
// is known only at the end). May call: Preflight, the output sink.
// Lines: `M73 P.. R..` and `M73 Q.. S..` (Marlin, Prusa firmware; PrusaSlicer writes them),
// Cura's `;TIME:` and `;TIME_ELAPSED:`, PrusaSlicer's `; estimated printing time (... mode) =`.
// Memory: 24 bytes a time line found, and the pre-flight's own bound.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/inspect/preflight.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/output_sink.hpp"

namespace xlate5 {

enum class SlicerTimeLine : std::uint8_t { None, M73, Total, Elapsed, Estimate };

// What a written line is (without its newline).
SlicerTimeLine slicer_time_line(std::string_view line);

// Whether a block of written text may hold such a line: a cheap test of each block as it is
// written, so that a file without them is never read back.
bool may_hold_slicer_times(std::string_view block);

// The line with its values from the estimate: `elapsed` seconds of motion before it of `total`.
// M73: P and Q the percent done, truncated (as PrusaSlicer writes it), R and S the minutes left,
// (remaining + 0.5 s) / 60 truncated (as PrusaSlicer 2.9); other words and the comment kept.
// ;TIME: the total in whole seconds, ;TIME_ELAPSED: the elapsed with 6 decimals (as Cura), the
// estimate the total as PrusaSlicer's "1h 2m 3s".
std::string retimed_line(std::string_view line, double elapsed, double total);

// PrusaSlicer's get_time_dhms: "1d 2h 3m 4s", leading zero units left out.
std::string time_dhms(double seconds);

// The file at `path` (a finished translation) into `out` with its time lines rewritten: read
// twice. Returns the time lines rewritten.
std::uint64_t retime_file(const Machine& machine, double baud, const std::string& path, OutputSink& out);

// Two passes over the written text: scan() it all (the estimate, and where the time lines are),
// finish(), then rewrite() it all again, in the same pieces or others.
class SlicerTimes {
public:
    SlicerTimes(const Machine& machine, double baud);

    void scan(std::string_view text);
    void finish();
    void rewrite(std::string_view text, std::string& out);
    void rewrite_end(std::string& out);  // a last line without a newline

    std::uint64_t lines() const { return at_.size(); }  // time lines found
    double seconds() const { return total_; }          // the estimate's total

private:
    struct At {
        std::uint64_t offset;  // of the line's first byte
        std::uint64_t line;    // its number (1-based)
        double elapsed;        // motion seconds before it
    };
    void line(std::string_view l, std::uint64_t offset);

    Preflight preflight_;
    std::vector<At> at_;
    std::size_t resolved_ = 0;
    double elapsed_ = 0, total_ = 0;
    std::uint64_t offset_ = 0, lines_ = 0;
    std::string pending_;  // a line across pieces
    // The second pass.
    std::uint64_t out_offset_ = 0;
    std::size_t next_ = 0;
    bool in_line_ = false;
};

}  // namespace xlate5
