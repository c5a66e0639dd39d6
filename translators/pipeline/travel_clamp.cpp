// SPDX-License-Identifier: GPL-3.0-or-later
// Retargeting's travel clamp: see travel_clamp.hpp.
#include "translators/pipeline/travel_clamp.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "translators/constants.hpp"
#include "translators/kinematics/great_arc.hpp"

#include "translators/pipeline/joint_limits.hpp"

namespace xlate5 {

namespace {

// How far inside a limit a held joint stops: the planner solves the pose again from the tip,
// and its rounding must not put the joint past the limit (far below any printer's step).
constexpr double kInside = 1e-6;

}  // namespace

TravelClamp::TravelClamp(const Kinematics& target, std::string input_name, std::function<void(const std::string&)> notice,
                         const Eigen::Vector3d& offset)
    : target_(target), input_name_(std::move(input_name)), notice_(std::move(notice)), offset_(offset), q_(target.machine().home_joints()) {}

int TravelClamp::source_pieces(const Kinematics& source, const std::vector<double>& q0, const std::vector<double>& q1, bool travel) const {
    const MotionSettings& motion = target_.machine().motion;
    if (!motion.segment || q0.size() != q1.size() || (travel && !target_.is_polar())) return 1;
    bool turns = false;
    for (const int j : source.rotary_joints()) turns = turns || q0[std::size_t(j)] != q1[std::size_t(j)];
    if (!turns) return 1;  // the rotaries still: the source draws a straight line
    const double tol = 0.25 * motion.tolerance, angle = 0.25 * motion.angle_tolerance * kRadPerDeg;
    std::vector<double>& q = lerp_;
    q = q0;
    const auto at = [&](double s) {
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = q0[j] + s * (q1[j] - q0[j]);
        return source.forward(q);
    };
    // Doubled until every part passes on three points each (the middle and its quarters).
    for (int n = 1;; n *= 2) {
        bool within = true;
        Pose a = at(0);
        for (int k = 1; k <= n && within; ++k) {
            const Pose b = at(double(k) / n);
            const GreatArc arc(a.axis, b.axis);
            for (const double t : {0.25, 0.5, 0.75}) {
                const Pose p = at((k - 1 + t) / n);
                const Eigen::Vector3d chord = a.tip + t * (b.tip - a.tip);
                const double axis_off = std::acos(std::clamp(p.axis.dot(arc.at(t)), -1.0, 1.0));
                if ((p.tip - chord).norm() > tol || axis_off > angle) within = false;
            }
            a = b;
        }
        if (within || n >= kMaxSourcePieces) return n;
    }
}

Pose TravelClamp::place(const Pose& source_pose, bool travel, std::uint64_t line) {
    Pose pose = source_pose;
    pose.tip += offset_;
    // The same solve as the planner's end (Kinematics::inverse: the orientation nearest the
    // joints before, then the position), from the joints this stage placed last.
    const IkResult r = target_.inverse(pose, q_, solved_);
    if (r.ok()) {
        q_.swap(solved_);
        return pose;
    }
    // A rotary past its limit is named first (check_limits), so `linear` says the rotaries are inside.
    if (!travel || r.status != IkStatus::OutOfLimits || !r.linear) return pose;
    const Machine& m = target_.machine();
    std::string held;
    for (std::size_t j = 0; j < m.joints.size(); ++j) {
        const Joint& J = m.joints[j];
        if (J.rotary) continue;
        const double at = std::clamp(solved_[j], J.min + kInside, J.max - kInside);
        if (at != solved_[j]) held += std::string(held.empty() ? "" : ", ") + J.name + " at " + joint_value_text(at) + " (asked " + joint_value_text(solved_[j]) + ")";
        solved_[j] = at;
    }
    Pose placed = pose;
    placed.tip = target_.forward(solved_).tip;
    // Only a lift made shorter: the held tip lies back along the tool axis from the asked one (a
    // park or safe height above the target's travel). A tip held sideways would put the move
    // somewhere the file never meant (a part placed outside the travel): refused as before.
    const Eigen::Vector3d back = pose.tip - placed.tip;
    const double along = back.dot(pose.axis);
    if (!(along > 0) || (back - along * pose.axis).norm() > 1e-6 * std::max(1.0, along)) return pose;
    q_.swap(solved_);
    // One note a line (a move cut into parts along the source's path is held part by part).
    if (line == held_line_) return placed;
    held_line_ = line;
    ++held_;
    if (notice_ && held_ <= kMaxNotices)
        notice_(input_name_ + ":" + std::to_string(line) + ": note: a travel move past " + m.name + "'s travel is held at its limits: " +
                held + (held_ == kMaxNotices ? " (further ones are not listed)" : ""));
    return placed;
}

}  // namespace xlate5
