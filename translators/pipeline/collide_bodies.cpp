// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's bodies: made from the machine file's, the fixed ones placed once.
#include "translators/pipeline/collide_bodies.hpp"

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/OBBRSS.h>

#include <algorithm>
#include <string>

#include "translators/error.hpp"

namespace xlate5::collision_parts {

std::shared_ptr<fcl::CollisionGeometryd> make_geometry(const BodyShape& s) {
    switch (s.kind) {
        case BodyShape::Kind::Box: return std::make_shared<fcl::Boxd>(s.size.x(), s.size.y(), s.size.z());
        case BodyShape::Kind::Sphere: return std::make_shared<fcl::Sphered>(s.radius);
        case BodyShape::Kind::Cylinder: return std::make_shared<fcl::Cylinderd>(s.radius, s.length);
        case BodyShape::Kind::Cone: return std::make_shared<fcl::Coned>(s.radius, s.length);
        case BodyShape::Kind::Capsule: return std::make_shared<fcl::Capsuled>(s.radius, s.length);
        case BodyShape::Kind::Mesh: {
            auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
            std::vector<fcl::Triangle> tris;
            tris.reserve(s.triangles.size());
            for (const auto& t : s.triangles) tris.emplace_back(std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2]));
            model->beginModel(int(tris.size()), int(s.vertices.size()));
            model->addSubModel(s.vertices, tris);
            model->endModel();
            model->computeLocalAABB();
            return model;
        }
    }
    return nullptr;
}

CollideBodies::CollideBodies(const Machine& m) : machine(m), settings(m.geometry->settings) {
    for (const Body& b : m.geometry->bodies) {
        Solid s;
        s.body = &b;
        s.object = std::make_unique<Placed>(make_geometry(b.shape));
        s.moves = !(!b.tool_side && b.after == int(m.part_chain.size()) - 1);
        s.origin = b.place.inverse().translation();
        s.place = rigid(b.place);
        {
            const fcl::CollisionGeometryd& g = *s.object->collisionGeometry();
            s.box_centre = g.aabb_local.center();
            s.box_half = 0.5 * (g.aabb_local.max_ - g.aabb_local.min_);
            s.round = g.getNodeType() == fcl::GEOM_SPHERE;
        }
        const std::pair<bool, int> key(b.tool_side, b.after);
        const auto at = std::find(frame_keys.begin(), frame_keys.end(), key);
        s.frame = int(at - frame_keys.begin());
        if (at == frame_keys.end()) frame_keys.push_back(key);
        if (b.tool_side && b.after == int(m.tool_chain.size()) - 1 && b.after >= 0) tip_frame = s.frame;
        const int i = int(solids.size());
        if (b.tool_side && b.after >= 0) tools.push_back(i);
        else if (s.moves) moving_obstacles.push_back(i);
        else fixed_obstacles.push_back(i);
        solids.push_back(std::move(s));
    }
    for (int side = 0; side < 2; ++side) {
        const auto& chain = side ? m.tool_chain : m.part_chain;
        for (std::size_t k = 0; k < chain.size(); ++k)
            if (chain[k].kind == ChainElement::Kind::Rotary) rotaries.push_back({side == 1, int(k), chain[k].joint});
    }
    if (rotaries.size() > Turns{}.th.size())
        throw MachineError("the collision check handles at most " + std::to_string(Turns{}.th.size()) + " rotary chain elements");
    for (std::size_t j = 0; j < m.joints.size(); ++j)
        if (!m.joints[j].rotary) linear_joints.push_back(int(j));
    q.resize(m.joints.size());
    // The fixed obstacles' poses never change: set once, at home.
    const auto home = m.home_joints();
    walk(m.part_chain, home.data(), part_frames);
    walk(m.tool_chain, home.data(), tool_frames);
    const Iso to_part = (part_frames.empty() ? Iso::Identity() : part_frames.back()).inverse();
    for (const int i : fixed_obstacles) {
        const Body& b = *solids[std::size_t(i)].body;
        const auto& frames = b.tool_side ? tool_frames : part_frames;
        place(i, to_part * (b.after < 0 ? Iso::Identity() : frames[std::size_t(b.after)]) * b.place);
    }
}

}  // namespace xlate5::collision_parts
