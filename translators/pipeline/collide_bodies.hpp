// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage's bodies (collide.hpp): the machine's bodies as FCL objects, the frames
// they ride on, and every body's pose at given joints (a Snapshot); FCL's distance and contact
// queries between placed bodies. The base of the stage's parts: collide_bounds.hpp builds on it.
#pragma once
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/collision_object.h>
#include <fcl/narrowphase/distance.h>

#include <array>
#include <memory>
#include <utility>
#include <vector>

#include "translators/constants.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5::collision_parts {

using Iso = Eigen::Isometry3d;
// Closer than this is a contact (mm): the advance toward a grazing contact stops there.
constexpr double kContact = 1e-3;
// GJK stops once its distance is within this fraction of the truth (it approaches from above):
// every distance is scaled down by it, so the advance stays conservative.
constexpr double kGjkTolerance = 1e-2;

std::shared_ptr<fcl::CollisionGeometryd> make_geometry(const BodyShape& s);

// An FCL object whose box is the tight one of its shape: FCL's own, once the object is turned,
// is the box of the shape's bounding sphere (the nozzle's cone reached 2.4 mm below its tip
// that way, onto the bed).
struct Placed : fcl::CollisionObjectd {
    using fcl::CollisionObjectd::CollisionObjectd;
    void tight_box() { aabb = box_at(t); }
    // The box the shape would have at `pose`, without placing it there.
    fcl::AABBd box_at(const Eigen::Isometry3d& pose) const {
        const fcl::CollisionGeometryd& g = *collisionGeometry();
        const Eigen::Vector3d e = 0.5 * (g.aabb_local.max_ - g.aabb_local.min_);
        const Eigen::Vector3d c = pose * g.aabb_local.center();
        // The local box turned: its extent along each axis. A sphere's does not turn.
        const Eigen::Vector3d E = g.getNodeType() == fcl::GEOM_SPHERE ? e : Eigen::Vector3d(pose.linear().cwiseAbs() * e);
        return fcl::AABBd(c - E, c + E);
    }
};

struct Solid {
    const Body* body = nullptr;
    std::unique_ptr<Placed> object;
    int frame = -1;  // index into the frames bodies ride on (CollideBodies::frame_keys)
    bool moves = true;  // in the part frame (false: on the plate, fixed there)
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // its chain frame's origin, in the shape's frame (rate())
};

// A sub-step's end: every solid's pose in the part frame, and what the bound needs.
struct Snapshot {
    std::vector<Iso> pose;                   // per solid, part frame
    std::vector<Eigen::Vector3d> centre;     // per solid, base frame
    std::vector<Eigen::Vector3d> line_point, line_dir;  // per rotary chain element, base frame
    std::vector<fcl::AABBd> box;             // per solid, part frame, as placed (with boxes)
    Iso tip = Iso::Identity();               // the tip's frame, part frame
    Eigen::Vector3d tip_base = Eigen::Vector3d::Zero();
    Eigen::Vector3d axis_base = Eigen::Vector3d::UnitZ();  // the tool axis, base frame
    std::vector<double> q;                   // the joints it was taken at
};

// FCL's AABB::overlap, inline (it is not, in the library).
inline bool overlaps(const fcl::AABBd& a, const fcl::AABBd& b) {
    return a.min_.x() <= b.max_.x() && b.min_.x() <= a.max_.x() && a.min_.y() <= b.max_.y() && b.min_.y() <= a.max_.y() &&
           a.min_.z() <= b.max_.z() && b.min_.z() <= a.max_.z();
}

inline void walk(const std::vector<ChainElement>& chain, const double* q, std::vector<Iso>& out) {
    out.resize(chain.size());
    Iso T = Iso::Identity();
    for (std::size_t k = 0; k < chain.size(); ++k) {
        const ChainElement& e = chain[k];
        switch (e.kind) {
            case ChainElement::Kind::Fixed:
                if (!e.fixed.isApprox(Iso::Identity(), 0)) T = T * e.fixed;  // a calibration offset left at 0: nothing
                break;
            case ChainElement::Kind::Linear: T.translate(e.axis * q[e.joint]); break;
            case ChainElement::Kind::Rotary:
                if (e.point.isZero()) {
                    T.rotate(Eigen::AngleAxisd(q[e.joint] * kPi / 180.0, e.axis));
                    break;
                }
                T.translate(e.point);
                T.rotate(Eigen::AngleAxisd(q[e.joint] * kPi / 180.0, e.axis));
                T.translate(-e.point);
                break;
        }
        out[k] = T;
    }
}

// A step's joint motion as the bow needs it: the linear joints' travel, each rotary's turn
// (at most 16 rotary chain elements: the constructor refuses more).
struct Turns {
    double L = 0, T = 0;
    std::array<double, 16> th{};
};

struct CollideBodies {
    const Machine& machine;
    const CollisionSettings& settings;
    std::vector<Solid> solids;      // every body: the tool's (after >= 0) and the obstacles
    std::vector<int> tools, moving_obstacles, fixed_obstacles;
    struct RotaryRef {
        bool tool = false;
        int element = 0;
        int joint = 0;
    };
    std::vector<RotaryRef> rotaries;  // every rotary chain element
    std::vector<int> linear_joints;
    std::vector<Iso> part_frames, tool_frames;
    std::vector<std::pair<bool, int>> frame_keys;  // (tool side, after) of the frames bodies ride on
    std::vector<Iso> frame_part;                   // those frames in the part frame, per snapshot
    int tip_frame = -1;                            // the tip's among them, if a body rides on it
    const Iso identity = Iso::Identity();
    std::vector<double> q;
    std::uint64_t queries = 0;

    explicit CollideBodies(const Machine& m);

    void place(int i, const Iso& pose) {
        auto& o = *solids[std::size_t(i)].object;
        o.setTransform(pose);
        o.tight_box();
    }

    // Every solid at joints `qq`: poses (part frame), centres (base frame), rotary axis lines.
    void snap(const double* qq, Snapshot& s, bool boxes = false) {
        s.q.assign(qq, qq + q.size());
        walk(machine.part_chain, qq, part_frames);
        walk(machine.tool_chain, qq, tool_frames);
        const Iso part_end = part_frames.empty() ? Iso::Identity() : part_frames.back();
        const Iso to_part = part_end.inverse();
        s.pose.resize(solids.size());
        s.centre.resize(solids.size());
        s.box.resize(solids.size());
        // Each chain frame a body rides on, in the part frame: once, for all its bodies.
        frame_part.resize(frame_keys.size());
        for (std::size_t f = 0; f < frame_keys.size(); ++f) {
            const auto& [tool_side, after] = frame_keys[f];
            const auto& frames = tool_side ? tool_frames : part_frames;
            frame_part[f] = after < 0 ? to_part : Iso(to_part * frames[std::size_t(after)]);
        }
        for (std::size_t i = 0; i < solids.size(); ++i) {
            if (!solids[i].moves) {  // on the plate: where the constructor placed it
                s.pose[i] = solids[i].object->getTransform();
                s.centre[i] = s.pose[i].translation();
                continue;
            }
            const Body& b = *solids[i].body;
            const auto& frames = b.tool_side ? tool_frames : part_frames;
            s.centre[i] = b.after < 0 ? b.place.translation() : Eigen::Vector3d(frames[std::size_t(b.after)] * b.place.translation());
            s.pose[i] = frame_part[std::size_t(solids[i].frame)] * b.place;
        }
        const Iso& tip_base = tool_frames.empty() ? identity : tool_frames.back();
        s.tip = tip_frame >= 0 ? frame_part[std::size_t(tip_frame)] : Iso(to_part * tip_base);
        s.tip_base = tip_base.translation();
        s.axis_base = tip_base.linear() * machine.tool_axis;
        if (boxes)
            for (std::size_t i = 0; i < solids.size(); ++i) {
                s.box[i] = solids[i].moves ? solids[i].object->box_at(s.pose[i]) : solids[i].object->getAABB();
            }
        s.line_point.resize(rotaries.size());
        s.line_dir.resize(rotaries.size());
        for (std::size_t r = 0; r < rotaries.size(); ++r) {
            const auto& chain = rotaries[r].tool ? machine.tool_chain : machine.part_chain;
            const auto& frames = rotaries[r].tool ? tool_frames : part_frames;
            const ChainElement& e = chain[std::size_t(rotaries[r].element)];
            if (rotaries[r].element == 0) {
                s.line_point[r] = e.point;
                s.line_dir[r] = e.axis;
                continue;
            }
            const Iso& before = frames[std::size_t(rotaries[r].element - 1)];
            s.line_point[r] = before * e.point;
            s.line_dir[r] = before.linear() * e.axis;
        }
    }

    void pose_at(const double* q0, const double* q1, double s, Snapshot& out, bool boxes = false) {
        if (s == 1) {
            snap(q1, out, boxes);
            return;
        }
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = q0[j] + (q1[j] - q0[j]) * s;
        snap(q.data(), out, boxes);
    }

    // Distance between solids a and b as placed (negative or 0: they touch).
    double distance(const fcl::CollisionObjectd& a, const fcl::CollisionObjectd& b) {
        ++queries;
        fcl::DistanceRequestd request;
        request.gjk_solver_type = fcl::GST_INDEP;  // FCL's own GJK: several times faster than libccd's here
        request.distance_tolerance = kGjkTolerance;
        fcl::DistanceResultd result;
        fcl::distance(&a, &b, request, result);
        return result.min_distance * (1 - kGjkTolerance);
    }

    Eigen::Vector3d contact_point(const fcl::CollisionObjectd& a, const fcl::CollisionObjectd& b) {
        fcl::CollisionRequestd request(1, true);
        request.gjk_solver_type = fcl::GST_INDEP;
        fcl::CollisionResultd result;
        fcl::collide(&a, &b, request, result);
        if (result.numContacts() > 0) return result.getContact(0).pos;
        fcl::DistanceRequestd dr(true);
        dr.gjk_solver_type = fcl::GST_INDEP;
        fcl::DistanceResultd dres;
        fcl::distance(&a, &b, dr, dres);
        return 0.5 * (dres.nearest_points[0] + dres.nearest_points[1]);
    }
};

}  // namespace xlate5::collision_parts
