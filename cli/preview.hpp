// `--preview FILE.html`: one self-contained page to look at a translation before printing it:
// the tip path in 3D coloured by tilt, tool-axis whiskers, and every joint over the file against
// its limits (stage: command line; reads the written output back through forward kinematics, so
// it shows what the firmware will be told; may call translators/kinematics only).
// Memory is bounded whatever the file size: at most kMaxPoints moves are kept, evenly spaced
// (when full, every other one is dropped and the spacing doubles).
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "translators/kinematics.hpp"

namespace xlate5::cli {

class Preview {
public:
    static constexpr std::size_t kMaxPoints = 4000;

    explicit Preview(const Kinematics& kinematics);

    // A block of written output (whole lines); G0/G1 and G92 lines move or set the joints.
    void scan(std::string_view output);
    // The page: `title` names the input file and machine.
    std::string html(const std::string& title) const;

    std::size_t points() const { return q_.size() / joints_; }

private:
    void line(std::string_view l);
    void keep();

    const Kinematics& kin_;
    std::size_t joints_;
    std::vector<double> q_now_;
    std::vector<double> q_;        // kept moves: joints, row by row
    std::vector<char> prints_;     // kept moves: 1 when the move extrudes (it has an E word)
    bool printing_ = false;        // the line being read extrudes
    std::vector<double> low_, high_;  // every move's joints, not only the kept ones
    std::uint64_t moves_ = 0, every_ = 1;
    std::string pending_;          // a line cut by the block boundary
};

}  // namespace xlate5::cli
