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

// A rigid motion as rotation and translation, composed inline: Eigen's Isometry product is an
// out-of-line call, and a snapshot makes about ten of them.
struct Rigid {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
};
inline Rigid compose(const Rigid& a, const Rigid& b) { return {a.R * b.R, a.R * b.t + a.t}; }
inline Rigid rigid(const Iso& x) { return {x.linear(), x.translation()}; }
inline Rigid inverse(const Rigid& x) { return {x.R.transpose(), -(x.R.transpose() * x.t)}; }

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
    Rigid place;                                        // the body's place on its frame
    Eigen::Vector3d box_centre, box_half;               // its shape's box, in the shape's frame
    bool round = false;                                 // a sphere: its box does not turn
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

// A chain's frames at given joints, as walk() makes them, but made again only from the first
// element whose joint changed since the last walk, and each rotation only when its angle changed:
// a planar print's tilt and turn stay put over thousands of pieces.
struct ChainFrames {
    std::vector<Rigid> frames;
    std::vector<double> at;              // per element: the joint value it was made with
    std::vector<Eigen::Matrix3d> turn;   // per rotary element: its rotation at `at`
    std::vector<Eigen::Vector3d> shift;  // per rotary element: point - turn point (its axis off the origin)
    std::vector<char> plain;             // per fixed element: the identity (a calibration left at 0)
    bool valid = false;
    void walk(const std::vector<ChainElement>& chain, const double* q);
};

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
    std::vector<int> obstacles;  // the fixed ones, then the moving ones
    struct RotaryRef {
        bool tool = false;
        int element = 0;
        int joint = 0;
    };
    std::vector<RotaryRef> rotaries;  // every rotary chain element
    std::vector<int> linear_joints;
    std::vector<std::pair<bool, int>> frame_keys;  // (tool side, after) of the frames bodies ride on
    std::vector<Rigid> frame_part;                 // those frames in the part frame, per snapshot
    ChainFrames part_walk, tool_walk;              // the chains' frames at the last snapshot's joints
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

    // What a snapshot's rotations give, kept while no rotary joint turns (a planar print's
    // pieces, a travel at a fixed tilt): then every frame only moves, and a snapshot is its
    // translations.
    struct Turned {
        bool valid = false;
        std::vector<double> at;                          // the rotary joints' values
        std::vector<Eigen::Matrix3d> R;                  // per solid: its pose's rotation
        std::vector<Eigen::Vector3d> Fp, Cp, Rc, E;      // per solid: F.R p, its frame's R p, R c, box extent
        std::vector<Eigen::Vector3d> line_Rp, line_dir;  // per rotary: before.R point, the axis
        Eigen::Matrix3d to_part_R, tip_R;
        Eigen::Vector3d axis_base;
    } turned;
    bool same_turn(const double* qq) const {
        if (!turned.valid) return false;
        for (std::size_t r = 0; r < rotaries.size(); ++r)
            if (!(qq[rotaries[r].joint] == turned.at[r])) return false;
        return true;
    }

    // Every solid at joints `qq`: poses (part frame), centres (base frame), rotary axis lines.
    void snap(const double* qq, Snapshot& s, bool boxes = false);
    // snap() with the rotations as they were: the translations alone.
    void snap_moved(Snapshot& s);
    // snap() in full, keeping what its rotations give in `turned`.
    void snap_turned(const double* qq, Snapshot& s);

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
