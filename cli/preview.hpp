// SPDX-License-Identifier: GPL-3.0-or-later
// `--preview FILE.html`: one self-contained page to look at a translation before printing it:
// the tip path in 3D coloured by tilt or by deviation, tool-axis whiskers, pole crossings,
// unwinds, branch changes and re-zeros marked, and every joint over the file against its limits
// (stage: command line; reads the written output back through forward kinematics, so it shows
// what the firmware will be told; the marks are the report's events, each joined to the written
// move line it ended on, so the page and the report count the same; may call
// translators/kinematics and read the report's marks).
// Deviation of a written move: how far the firmware's joint-linear path leaves the straight line
// between the tips at its two ends (where every piece of a split move starts and ends on the
// programmed line), sampled; a thinned-out point keeps the worst of the moves it stands for.
// Memory is bounded whatever the file size: at most kMaxPoints moves are kept, evenly spaced
// (when full, every other one is dropped and the spacing doubles).
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/kinematics/kinematics.hpp"
#include "translators/inspect/report.hpp"

namespace xlate5::cli {

class Preview {
public:
    static constexpr std::size_t kMaxPoints = 4000;

    // `events`: the translation's report, whose marks arrive before the output lines they belong to.
    Preview(const Kinematics& kinematics, const DeviationReport& events);

    // A block of written output (whole lines); G0/G1 and G92 lines move or set the joints.
    void scan(std::string_view output);
    // The page: `title` names the input file and machine.
    std::string html(const std::string& title) const;

    std::size_t points() const { return q_.size() / joints_; }

    // The report's events at the written moves they ended on.
    using MarkKind = DeviationReport::MarkKind;
    struct Mark {
        MarkKind kind;
        std::uint64_t move;  // written move number, from 0
        double tip[3];
    };
    const std::vector<Mark>& marks() const { return marks_; }

private:
    void line(std::string_view l);
    void keep();
    double deviation(const std::vector<double>& from, const std::vector<double>& to) const;
    void join_marks(std::uint64_t through);

    const Kinematics& kin_;
    const DeviationReport& events_;
    std::size_t joined_ = 0;       // the report's marks placed so far
    std::size_t joints_;
    std::vector<double> q_now_;
    std::vector<double> q_;        // kept moves: joints, row by row
    std::vector<char> prints_;     // kept moves: 1 when the move extrudes (it has an E word)
    bool printing_ = false;        // the line being read extrudes
    std::vector<double> low_, high_;  // every move's joints, not only the kept ones
    std::uint64_t moves_ = 0, every_ = 1;
    std::string pending_;          // a line cut by the block boundary
    std::vector<double> dev_;      // kept moves: worst tip deviation (mm) of the moves each stands for
    double dev_since_ = 0;         // worst deviation of the moves since the last kept one
    std::vector<double> q_before_; // joints before the move being read
    std::vector<Mark> marks_;
};

}  // namespace xlate5::cli
