// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's printed part: a bead laid, the part cut back.
#include "translators/pipeline/collide_part.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace xlate5::collision_parts {

void CollidePart::add_bead(const double* q0, const double* q1, double e, std::uint64_t line) {
    const std::size_t n = q.size();
    // The piece just swept: its tips are known.
    if (!(tips_q0.size() == n && std::equal(q0, q0 + n, tips_q0.begin()) && std::equal(q1, q1 + n, tips_q1.begin()))) {
        Snapshot s;
        snap(q0, s);
        tip0_part = s.tip.translation();
        snap(q1, s);
        tip1_part = s.tip.translation();
        axis1_part = s.tip.linear() * machine.tool_axis;
    }
    const Eigen::Vector3d p0 = tip0_part, p1 = tip1_part;
    const Eigen::Vector3d d = p1 - p0;
    const double length = d.norm();
    if (length < 1e-6) return;  // extrusion in place: no bead to speak of
    const double h = settings.bead_height;
    double w = settings.bead_width;
    if (e > 0) {
        const double area = kPi * 0.25 * settings.filament_diameter * settings.filament_diameter;
        w = std::clamp(e * area / (length * h), 0.1, 3 * settings.bead_width);
    }
    const Eigen::Vector3d x = d / length;
    Eigen::Vector3d up = axis1_part;
    // A piece that rises or plunges along the tool axis by more than a layer (a priming move
    // coming down onto the layer) leaves its material where it ends, not along its path.
    if (std::abs(d.dot(up)) > settings.bead_height) return;
    up -= up.dot(x) * x;
    if (up.norm() < 1e-6) up = x.unitOrthogonal();
    up.normalize();
    Iso pose = Iso::Identity();
    pose.linear().col(0) = x;
    pose.linear().col(1) = up.cross(x);
    pose.linear().col(2) = up;
    // The bead lies under the tip's path: its top along it.
    pose.translation() = 0.5 * (p0 + p1) - 0.5 * h * up;
    Bead& b = beads.emplace_back();
    bead_clear.resize(beads.size() * tools.size());
    b.line = line;
    b.pose = pose;
    b.size = Eigen::Vector3d(length, w, h);
    b.centre = pose.translation();
    b.half[0] = 0.5 * length * pose.linear().col(0);
    b.half[1] = 0.5 * w * pose.linear().col(1);
    b.half[2] = 0.5 * h * pose.linear().col(2);
    b.reach = 0.5 * b.size.norm();
    // Its box: the extent of the turned box along each axis.
    const Eigen::Vector3d E = b.half[0].cwiseAbs() + b.half[1].cwiseAbs() + b.half[2].cwiseAbs();
    b.box = fcl::AABBd(b.centre - E, b.centre + E);
    if (beads.size() - 1 == open_first) {
        open_box = b.box;
    } else {
        open_box.min_ = open_box.min_.cwiseMin(b.box.min_);
        open_box.max_ = open_box.max_.cwiseMax(b.box.max_);
    }
    if (beads.size() - open_first == kChunk) seal_chunk();
}

// The open chunk's beads, now kChunk of them, into the tree as one leaf.
void CollidePart::seal_chunk() {
    Chunk& ch = chunks.emplace_back();
    ch.first = open_first;
    ch.node = part.insert(open_box, reinterpret_cast<void*>(std::intptr_t(chunks.size() - 1)));
    const Eigen::Matrix3d axes = beads[open_first].pose.linear();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (std::size_t i = open_first; i < beads.size(); ++i) {
        const Bead& bd = beads[i];
        const Eigen::Vector3d c = axes.transpose() * bd.centre;
        Eigen::Vector3d ext = Eigen::Vector3d::Zero();
        for (const auto& h : bd.half) ext += (axes.transpose() * h).cwiseAbs();
        lo = lo.cwiseMin(c - ext);
        hi = hi.cwiseMax(c + ext);
    }
    const Eigen::Vector3d ext = 0.5 * (hi - lo);
    ch.centre = axes * (0.5 * (hi + lo));
    for (int k = 0; k < 3; ++k) ch.half[k] = ext[k] * axes.col(k);
    ch.reach = ext.norm();
    ch.obb.axis = axes;
    ch.obb.To = ch.centre;
    ch.obb.extent = ext;
    open_first = beads.size();
    // Inserted in printing order, the tree's boxes come to overlap much (a layer's chunks
    // under one node with the last layer's): rebuilt by FCL's top-down split each time the
    // chunks reach a power of four (a rebuild costs about a hundred walks; at every power of two
    // the rebuilds cost more than the walks gained: bench/README.md).
    if (const std::size_t n = chunks.size(); n >= 64 && (n & (n - 1)) == 0 && (std::countr_zero(n) % 2 == 0)) part.balanceTopdown();
}

void CollidePart::truncate(std::size_t count) {
    if (beads.size() <= count) return;
    while (!chunks.empty() && chunks.back().first + kChunk > count) {
        part.remove(chunks.back().node);
        chunks.pop_back();
    }
    open_first = chunks.empty() ? 0 : chunks.back().first + kChunk;
    beads.erase(beads.begin() + std::ptrdiff_t(count), beads.end());
    for (std::size_t i = open_first; i < beads.size(); ++i) {
        if (i == open_first) open_box = beads[i].box;
        open_box.min_ = open_box.min_.cwiseMin(beads[i].box.min_);
        open_box.max_ = open_box.max_.cwiseMax(beads[i].box.max_);
    }
    bead_clear.resize(count * tools.size());
}

}  // namespace xlate5::collision_parts
