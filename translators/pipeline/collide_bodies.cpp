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

void ChainFrames::walk(const std::vector<ChainElement>& chain, const double* q) {
    const std::size_t n = chain.size();
    std::size_t k0 = 0;
    // Whether the rotation so far differs from the last walk's: while it does not, each
    // frame keeps its rotation and only its translation is made again.
    bool turned = true;
    if (!valid) {
        frames.assign(n, Rigid{});
        turn.assign(n, Eigen::Matrix3d::Identity());
        shift.assign(n, Eigen::Vector3d::Zero());
        at.assign(n, 0.0);
        plain.resize(n);
        for (std::size_t k = 0; k < n; ++k) plain[k] = chain[k].fixed.isApprox(Iso::Identity(), 0);
        valid = true;
    } else {
        k0 = n;
        for (std::size_t k = 0; k < n; ++k)
            if (chain[k].kind != ChainElement::Kind::Fixed && !(q[chain[k].joint] == at[k])) {
                k0 = k;
                break;
            }
        turned = false;
    }
    Rigid T = k0 == 0 ? Rigid{} : frames[k0 - 1];
    for (std::size_t k = k0; k < n; ++k) {
        const ChainElement& e = chain[k];
        switch (e.kind) {
            case ChainElement::Kind::Fixed:
                if (plain[k]) break;
                T.t += T.R * e.fixed.translation();
                T.R = turned ? Eigen::Matrix3d(T.R * e.fixed.linear()) : frames[k].R;
                break;
            case ChainElement::Kind::Linear:
                at[k] = q[e.joint];
                T.t += T.R * (e.axis * at[k]);
                break;
            case ChainElement::Kind::Rotary:
                if (!(q[e.joint] == at[k])) {  // at 0 on the first walk: turn is the identity
                    at[k] = q[e.joint];
                    turn[k] = Eigen::AngleAxisd(at[k] * kPi / 180.0, e.axis).toRotationMatrix();
                    shift[k] = e.point - turn[k] * e.point;
                    turned = true;
                }
                // About the axis through e.point: translate(p) rotate translate(-p).
                T.t += T.R * shift[k];
                T.R = turned ? Eigen::Matrix3d(T.R * turn[k]) : frames[k].R;
                break;
        }
        frames[k] = T;
    }
}

void CollideBodies::snap(const double* qq, Snapshot& s, bool boxes) {
    s.q.assign(qq, qq + q.size());
    const bool same = same_turn(qq);
    part_walk.walk(machine.part_chain, qq);
    tool_walk.walk(machine.tool_chain, qq);
    const std::size_t n = solids.size();
    if (s.pose.size() != n) {
        s.pose.assign(n, Iso::Identity());
        s.centre.resize(n);
        s.box.resize(n);
    }
    s.line_point.resize(rotaries.size());
    s.line_dir.resize(rotaries.size());
    if (same) snap_moved(s);
    else snap_turned(qq, s);
    if (!boxes) return;
    for (std::size_t i = 0; i < n; ++i) {
        if (!solids[i].moves) {
            s.box[i] = solids[i].object->getAABB();
            continue;
        }
        const Eigen::Vector3d c = turned.Rc[i] + s.pose[i].translation();
        s.box[i].min_ = c - turned.E[i];  // set in place: FCL's constructor is out of line
        s.box[i].max_ = c + turned.E[i];
    }
}

void CollideBodies::snap_moved(Snapshot& s) {
    const auto& pf = part_walk.frames;
    const auto& tf = tool_walk.frames;
    const Eigen::Vector3d to_part_t = pf.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(-(turned.to_part_R * pf.back().t));
    for (std::size_t f = 0; f < frame_keys.size(); ++f) {
        const auto& [tool_side, after] = frame_keys[f];
        const auto& frames = tool_side ? tf : pf;
        frame_part[f].t = after < 0 ? to_part_t : Eigen::Vector3d(turned.to_part_R * frames[std::size_t(after)].t + to_part_t);
    }
    for (std::size_t i = 0; i < solids.size(); ++i) {
        const Solid& so = solids[i];
        if (!so.moves) {
            s.pose[i] = so.object->getTransform();
            s.centre[i] = s.pose[i].translation();
            continue;
        }
        const Body& b = *so.body;
        const auto& frames = b.tool_side ? tf : pf;
        s.centre[i] = b.after < 0 ? so.place.t : Eigen::Vector3d(turned.Cp[i] + frames[std::size_t(b.after)].t);
        s.pose[i].linear() = turned.R[i];
        s.pose[i].translation() = turned.Fp[i] + frame_part[std::size_t(so.frame)].t;
    }
    const Eigen::Vector3d tip_base_t = tf.empty() ? Eigen::Vector3d::Zero() : tf.back().t;
    s.tip.linear() = turned.tip_R;
    s.tip.translation() = tip_frame >= 0 ? frame_part[std::size_t(tip_frame)].t : Eigen::Vector3d(turned.to_part_R * tip_base_t + to_part_t);
    s.tip_base = tip_base_t;
    s.axis_base = turned.axis_base;
    for (std::size_t r = 0; r < rotaries.size(); ++r) {
        const auto& frames = rotaries[r].tool ? tf : pf;
        const int k = rotaries[r].element;
        s.line_point[r] = k == 0 ? turned.line_Rp[r] : Eigen::Vector3d(turned.line_Rp[r] + frames[std::size_t(k - 1)].t);
        s.line_dir[r] = turned.line_dir[r];
    }
}

void CollideBodies::snap_turned(const double* qq, Snapshot& s) {
    const auto& pf = part_walk.frames;
    const auto& tf = tool_walk.frames;
    Turned& c = turned;
    const std::size_t n = solids.size();
    c.at.resize(rotaries.size());
    for (std::size_t r = 0; r < rotaries.size(); ++r) c.at[r] = qq[rotaries[r].joint];
    c.R.resize(n);
    c.Fp.resize(n);
    c.Cp.resize(n);
    c.Rc.resize(n);
    c.E.resize(n);
    c.line_Rp.resize(rotaries.size());
    c.line_dir.resize(rotaries.size());
    const Rigid to_part = pf.empty() ? Rigid{} : inverse(pf.back());
    c.to_part_R = to_part.R;
    // Each chain frame a body rides on, in the part frame: once, for all its bodies.
    frame_part.resize(frame_keys.size());
    for (std::size_t f = 0; f < frame_keys.size(); ++f) {
        const auto& [tool_side, after] = frame_keys[f];
        const auto& frames = tool_side ? tf : pf;
        frame_part[f] = after < 0 ? to_part : compose(to_part, frames[std::size_t(after)]);
    }
    for (std::size_t i = 0; i < n; ++i) {
        const Solid& so = solids[i];
        if (!so.moves) {  // on the plate: where the constructor placed it
            s.pose[i] = so.object->getTransform();
            s.centre[i] = s.pose[i].translation();
            continue;
        }
        const Body& b = *so.body;
        const auto& frames = b.tool_side ? tf : pf;
        if (b.after < 0) {
            s.centre[i] = so.place.t;
        } else {
            c.Cp[i] = frames[std::size_t(b.after)].R * so.place.t;
            s.centre[i] = c.Cp[i] + frames[std::size_t(b.after)].t;
        }
        const Rigid& F = frame_part[std::size_t(so.frame)];
        c.R[i] = F.R * so.place.R;
        c.Fp[i] = F.R * so.place.t;
        c.Rc[i] = c.R[i] * so.box_centre;  // Placed::box_at's, inline
        c.E[i] = so.round ? so.box_half : Eigen::Vector3d(c.R[i].cwiseAbs() * so.box_half);
        s.pose[i].linear() = c.R[i];
        s.pose[i].translation() = c.Fp[i] + F.t;
    }
    const Rigid tip_base = tf.empty() ? Rigid{} : tf.back();
    const Rigid tip = tip_frame >= 0 ? frame_part[std::size_t(tip_frame)] : compose(to_part, tip_base);
    c.tip_R = tip.R;
    c.axis_base = tip_base.R * machine.tool_axis;
    s.tip.linear() = tip.R;
    s.tip.translation() = tip.t;
    s.tip_base = tip_base.t;
    s.axis_base = c.axis_base;
    for (std::size_t r = 0; r < rotaries.size(); ++r) {
        const auto& chain = rotaries[r].tool ? machine.tool_chain : machine.part_chain;
        const auto& frames = rotaries[r].tool ? tf : pf;
        const ChainElement& e = chain[std::size_t(rotaries[r].element)];
        if (rotaries[r].element == 0) {
            c.line_Rp[r] = e.point;
            c.line_dir[r] = e.axis;
        } else {
            const Rigid& before = frames[std::size_t(rotaries[r].element - 1)];
            c.line_Rp[r] = before.R * e.point;
            c.line_dir[r] = before.R * e.axis;
        }
        s.line_point[r] = rotaries[r].element == 0 ? c.line_Rp[r] : Eigen::Vector3d(c.line_Rp[r] + frames[std::size_t(rotaries[r].element - 1)].t);
        s.line_dir[r] = c.line_dir[r];
    }
    c.valid = true;
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
    obstacles = fixed_obstacles;
    obstacles.insert(obstacles.end(), moving_obstacles.begin(), moving_obstacles.end());
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
    ChainFrames part_home, tool_home;
    part_home.walk(m.part_chain, home.data());
    tool_home.walk(m.tool_chain, home.data());
    const Rigid to_part = part_home.frames.empty() ? Rigid{} : inverse(part_home.frames.back());
    for (const int i : fixed_obstacles) {
        const Solid& s = solids[std::size_t(i)];
        const auto& frames = s.body->tool_side ? tool_home.frames : part_home.frames;
        const Rigid P = compose(s.body->after < 0 ? to_part : compose(to_part, frames[std::size_t(s.body->after)]), s.place);
        Iso pose = Iso::Identity();
        pose.linear() = P.R;
        pose.translation() = P.t;
        place(i, pose);
    }
}

}  // namespace xlate5::collision_parts
