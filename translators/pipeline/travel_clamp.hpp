// SPDX-License-Identifier: GPL-3.0-or-later
// Retargeting's travel clamp (--from): a joint-space file written for another machine may park
// or lift where that machine reaches and this one does not (the S3-DeformFDM ring starts at its
// machine's Z 250, past every other bundled machine's travel). A travel move whose only fault
// on this machine is a linear joint past its limit, and which holding that joint at its limit
// only shortens along the tool axis (a lift or park), is held there instead of refused: the
// tool still turns to the move's orientation, and the next move goes on from there. A printing
// move is never changed (refused as before), nor a travel move that fails for another reason
// (a rotary past its limit, an orientation out of reach) or that the limit would move sideways
// (a part placed outside the travel: the user places it).
// Stage: between the source machine's forward kinematics (InverseTranslator) and this machine's
// translation. May call: kinematics (inverse, forward) and the machine's limits.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "translators/kinematics/kinematics.hpp"

namespace xlate5 {

class TravelClamp {
public:
    // Notices (one line each, at most kMaxNotices, then one saying the rest are not listed) go to
    // `notice` when set.
    static constexpr std::uint64_t kMaxNotices = 10;
    // `offset`: the source's part frame placed on the target's (--place), added to every tip.
    TravelClamp(const Kinematics& target, std::string input_name, std::function<void(const std::string&)> notice,
                const Eigen::Vector3d& offset = Eigen::Vector3d::Zero());

    // Where a move of input line `line` goes on the target: `pose` moved by the offset, or for a
    // travel move past a linear joint's limit, that pose with the tip where the joint stops at its limit.
    Pose place(const Pose& source_pose, bool travel, std::uint64_t line);
    // Into how many equal parts of the source's joint-linear move q0 -> q1 (the source's forward
    // kinematics `source`) the move is cut so that each part's chord and great arc stay within a
    // quarter of the target's tolerances of the path the source machine takes (the target then
    // follows each chord within its tolerances): 1 for a move the source draws straight, or when
    // the target does not split (--no-segment), at most kMaxSourcePieces.
    static constexpr int kMaxSourcePieces = 256;
    // A travel move (not printed) keeps the straight line, as any tool-space travel, except on a
    // polar target (Kinematics::is_polar), which reaches a tool axis only in the tip's plane
    // through C's axis: there the straight line between two poses is mostly out of its reach.
    int source_pieces(const Kinematics& source, const std::vector<double>& q0, const std::vector<double>& q1, bool travel) const;
    // The target homed (G28): its joints are at home again.
    void homed() { q_ = target_.machine().home_joints(); }
    std::uint64_t held() const { return held_; }  // input lines with a travel move held at a limit so far

private:
    const Kinematics& target_;
    std::string input_name_;
    std::function<void(const std::string&)> notice_;
    Eigen::Vector3d offset_;
    std::vector<double> q_, solved_;  // the target's joints as last placed; scratch
    mutable std::vector<double> lerp_;  // scratch of source_pieces
    std::uint64_t held_ = 0, held_line_ = 0;
};

}  // namespace xlate5
