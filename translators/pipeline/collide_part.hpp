// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's printed part: its beads, in chunks in FCL's dynamic AABB tree (rebuilt
// as the part grows), and the tips of the last piece swept, for its bead. Builds on
// collide_clearance.hpp (a bead gets its row of cleared distances).
#pragma once
#include <fcl/broadphase/detail/hierarchy_tree.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/math/bv/OBB.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "translators/pipeline/collide_clearance.hpp"

namespace xlate5::collision_parts {

struct CollidePart : CollideClearance {
    using CollideClearance::CollideClearance;

    // A bead: a box in the part frame. Its FCL object is made only when the narrow phase needs
    // it (the tests before rule out nearly all), in `bead_object`.
    using Node = fcl::detail::NodeBase<fcl::AABBd>;
    struct Bead {
        std::uint64_t line = 0;
        Iso pose;
        Eigen::Vector3d size;             // length, width, height
        Eigen::Vector3d centre, half[3];  // the box: centre and half axes, part frame
        double reach = 0;                 // its half diagonal
        fcl::AABBd box;
    };
    std::vector<Bead> beads;
    // The tree holds the beads in chunks of kChunk in printing order (neighbours, mostly): a
    // leaf's insertion costs more than the check of a few boxes. The last beads, fewer than
    // kChunk, are the open chunk, checked one by one.
    static constexpr std::size_t kChunk = 8;
    struct Chunk {
        std::size_t first = 0;
        Node* node = nullptr;
        // Its beads' oriented box, on the first bead's axes: tighter than the tree's
        // axis-aligned one across a tilted layer (the below-the-tool test at the chunk).
        Eigen::Vector3d centre, half[3];
        double reach = 0;
        fcl::OBBd obb;
    };
    std::vector<Chunk> chunks;
    std::size_t open_first = 0;
    fcl::AABBd open_box;  // the open chunk's beads' boxes joined (when it has any)
    fcl::detail::HierarchyTree<fcl::AABBd> part;  // FCL's dynamic AABB tree of the chunks
    std::shared_ptr<fcl::Boxd> bead_box = std::make_shared<fcl::Boxd>(1, 1, 1);
    Placed bead_object{bead_box};
    const fcl::CollisionObjectd& object_of(const Bead& b) {
        bead_box->side = b.size;
        bead_box->computeLocalAABB();
        bead_object.setTransform(b.pose);
        return bead_object;
    }
    // The tips of the last piece swept (part frame), for its bead.
    std::vector<double> tips_q0, tips_q1;
    Eigen::Vector3d tip0_part = Eigen::Vector3d::Zero(), tip1_part = Eigen::Vector3d::Zero(), axis1_part = Eigen::Vector3d::UnitZ();

    // The bead as FCL's oriented box.
    static fcl::OBBd bead_obb(const Bead& b) {
        fcl::OBBd o;
        o.axis = b.pose.linear();
        o.To = b.centre;
        o.extent = 0.5 * b.size;
        return o;
    }

    // Adds the bead from the tip at q0 to the tip at q1 (CollisionStage::add_bead).
    void add_bead(const double* q0, const double* q1, double e, std::uint64_t line);
    void seal_chunk();
    // Drops the beads from `count` on (the look-back's replay).
    void truncate(std::size_t count);
};

}  // namespace xlate5::collision_parts
