// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage on FCL: bodies, the printed part's beads, the swept check.
// What it may call: see collide.hpp.
#include "translators/pipeline/collide.hpp"

#include <fcl/broadphase/detail/hierarchy_tree.h>
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/OBB.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>

#include <cmath>
#include <deque>
#include <iomanip>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"

namespace xlate5 {

std::string CollisionEvent::message() const {
    std::ostringstream os;
    os << std::fixed << std::setprecision(3);
    if (rerouted) os << "travel re-routed, lifted " << lift << " mm: " << tool_body << " would meet ";
    else os << "collision: " << tool_body << " meets ";
    if (other.empty()) os << "printed part at line " << bead_line;
    else os << other;
    os << " at X" << at.x() << " Y" << at.y() << " Z" << at.z();
    return os.str();
}

namespace {

using Iso = Eigen::Isometry3d;
// Closer than this is a contact (mm): the advance toward a grazing contact stops there.
constexpr double kContact = 1e-3;
// Rotation (radians, all rotaries together) of one sub-step of the sweep: keeps the bound's
// second-order term (the arms changing within a step) small; see docs/machines.md.
constexpr double kSubStepTurn = 2.0 * kPi / 180.0;
// Advances per body pair and sub-step before the pair is taken as touching (a contact closer
// than the advance can resolve at a reasonable cost).
constexpr int kMaxAdvances = 20000;
// GJK stops once its distance is within this fraction of the truth (it approaches from above):
// every distance is scaled down by it, so the advance stays conservative.
constexpr double kGjkTolerance = 1e-2;
// A span turning less than this (radians, all rotaries together) is tested whole before it is
// halved: the bounds need under half a radian (bound_at).
constexpr double kWholeTurn = 0.25;

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
    int frame = -1;  // index into the frames bodies ride on (Impl::frame_keys)
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

void walk(const std::vector<ChainElement>& chain, const double* q, std::vector<Iso>& out) {
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

}  // namespace

struct CollisionStage::Impl {
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
    std::vector<Iso> part_frames, tool_frames;
    std::vector<std::pair<bool, int>> frame_keys;  // (tool side, after) of the frames bodies ride on
    std::vector<Iso> frame_part;                   // those frames in the part frame, per snapshot
    int tip_frame = -1;                            // the tip's among them, if a body rides on it
    const Iso identity = Iso::Identity();
    std::vector<double> q;
    std::uint64_t queries = 0;

    Impl(const Machine& m) : machine(m), settings(m.geometry->settings) {
        for (const Body& b : m.geometry->bodies) {
            Solid s;
            s.body = &b;
            s.object = std::make_unique<Placed>(make_geometry(b.shape));
            s.moves = !(!b.tool_side && b.after == int(m.part_chain.size()) - 1);
            s.origin = b.place.inverse().translation();
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
        solid_clear.resize(tools.size() * solids.size());
        new_epoch();
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

    // How far any point of a sphere of radius R about `centre` (base frame) carried by the tool
    // may move in the part frame over the joint change dq, from snapshot s on (docs/machines.md,
    // "Bodies"). Loose (the linear joints' travel and the rotaries' arms add up although the
    // kinematics makes them cancel at the tip): it only bounds the arms' growth within a step.
    double bound_at(const Eigen::Vector3d& centre, double R, const Snapshot& s, const double* dq) const {
        double a = 0, turn = 0;
        for (const int j : linear_joints) a += std::abs(dq[j]);
        for (std::size_t r = 0; r < rotaries.size(); ++r) {
            const double th = std::abs(dq[rotaries[r].joint]) * kPi / 180.0;
            if (th == 0) continue;
            const Eigen::Vector3d v = centre - s.line_point[r];
            const double arm = (v - v.dot(s.line_dir[r]) * s.line_dir[r]).norm() + R;
            a += th * arm;
            turn += th;
        }
        // The arms grow by at most what every point and axis moves within the step (each at
        // most the bound itself): D <= a + 2 turn D.
        return a / (1 - 2 * turn);
    }

    // The most any point of solid i moves in the part frame per unit of the sub-step from a to b
    // (`bow`: curve() over it): a Lipschitz bound, tight where bound() is loose. A point's
    // path p(u) has |p'(u) - (p(1) - p(0))| <= M / 2 with M >= |p''|; p(1) - p(0) is at most
    // the body frame's chord plus its turn times the body's radius; and with the joints moving
    // at constant rates, M <= 4 T^2 r + 3 T L (T: the rotaries' turn, L: the linear joints'
    // travel, r: the farthest a point or axis gets from a rotary axis). Derivation:
    // docs/machines.md, "Bodies".
    double rate(int i, const Snapshot& a, const Snapshot& b, double bow) const {
        if (!solids[std::size_t(i)].moves) return 0;
        const Body& body = *solids[std::size_t(i)].body;
        const Iso& pa = a.pose[std::size_t(i)];
        const Iso& pb = b.pose[std::size_t(i)];
        // The bounding sphere's centre: the body's chain frame origin.
        const Eigen::Vector3d& o = solids[std::size_t(i)].origin;
        const Eigen::Vector3d oa = pa * o, ob = pb * o;
        // A point at R from the origin moves by at most |Rb - Ra| R = 2 sin(turn / 2) R =
        // sqrt(3 - trace(Ra^T Rb)) R: no angle needed.
        const double tr = pa.linear().cwiseProduct(pb.linear()).sum();
        const double chord = (ob - oa).norm() + std::sqrt(std::max(0.0, 3 - tr)) * body.radius;
        return chord + bow;
    }
    // A step's joint motion as the bow needs it: the linear joints' travel, each rotary's turn.
    struct Turns {
        double L = 0, T = 0;
        std::array<double, 16> th{};
    };
    Turns turns_of(const double* dq) const {
        Turns tt;
        for (const int j : linear_joints) tt.L += std::abs(dq[j]);
        for (std::size_t k = 0; k < rotaries.size() && k < tt.th.size(); ++k) {
            tt.th[k] = std::abs(dq[rotaries[k].joint]) * kPi / 180.0;
            tt.T += tt.th[k];
        }
        return tt;
    }
    // Half the bound on |p''| of rate() for a sphere of radius R about `centre` (base frame).
    double curve(const Eigen::Vector3d& centre, double R, const Snapshot& a, const Turns& tt) const {
        if (tt.T == 0) return 0;
        double r = 0, A = 0;
        for (std::size_t k = 0; k < rotaries.size(); ++k) {
            const double th = tt.th[k];
            if (th == 0) continue;
            // Every point of the body lies within its radius of the shape's centre.
            const Eigen::Vector3d v = centre - a.line_point[k];
            const double arm = (v - v.dot(a.line_dir[k]) * a.line_dir[k]).norm() + R;
            r = std::max(r, arm);
            A += th * arm;
        }
        r += 2 * (tt.L + A) / (1 - 2 * tt.T);  // how far points and axes get within the step (bound_at)
        return 0.5 * (4 * tt.T * tt.T * r + 3 * tt.T * tt.L);
    }



    // What the tests of one step (sa..sb of the piece) share: the tool axis' and the tip's
    // motion over it (part frame), for below().
    struct StepBound {
        Eigen::Vector3d n, tip;  // the tool axis and the tip at the step's start
        double Tn = 0;           // how far the tool axis turns over the step, at most (rad)
        double Dtip = 0;         // the tip's path length, at most
        double along = 0;        // the tip's motion along n, at most: |n . (tip1 - tip0)| + its bow
    };
    StepBound step_bound(const Snapshot& a, const Snapshot& b, const Turns& tt) const {
        StepBound sb;
        sb.n = a.tip.linear() * machine.tool_axis;
        sb.tip = a.tip.translation();
        // The tool axis turns at |n'| <= sum_k theta_k |w_k x n|; the angle between w_k and n
        // changes only by the other rotaries' turns (docs/machines.md, "Bodies").
        for (std::size_t k = 0; k < rotaries.size(); ++k) {
            const double th = tt.th[k];
            if (th == 0) continue;
            sb.Tn += th * std::min(1.0, a.line_dir[k].cross(a.axis_base).norm() + (tt.T - th));
        }
        const Eigen::Vector3d chord = b.tip.translation() - a.tip.translation();
        const double c = curve(a.tip_base, 0, a, tt);  // M / 2 for the tip
        sb.Dtip = chord.norm() + c;
        sb.along = std::abs(sb.n.dot(chord)) + 0.25 * c;
        return sb;
    }

    // Whether the box (centre c, half axes h, half diagonal `reach`; part frame, fixed there)
    // lies wholly below tool body t's lowest point along the tool axis over the whole step:
    // then they cannot meet. A point x's height over the tip, z = n . (x - tip), rises over
    // the step by at most Tn (|x - tip| + 2 Dtip) + along (docs/machines.md, "Bodies").
    bool below(int t, const Eigen::Vector3d& c, const Eigen::Vector3d* h, double reach, const StepBound& sb) const {
        return under(t, rise(c, h, reach, sb));
    }
    // The highest the box reaches along the tool axis over the tip, over the step: what below()
    // compares with each body's lowest point (the same for every tool body: computed once).
    static double rise(const Eigen::Vector3d& c, const Eigen::Vector3d* h, double reach, const StepBound& sb) {
        const Eigen::Vector3d d = c - sb.tip;
        const double top = sb.n.dot(d) + std::abs(sb.n.dot(h[0])) + std::abs(sb.n.dot(h[1])) + std::abs(sb.n.dot(h[2]));
        return top + sb.Tn * (d.norm() + reach + 2 * sb.Dtip) + sb.along;
    }
    bool under(int t, double rise) const {
        const double low = solids[std::size_t(t)].body->low;
        return low > -1e299 && rise < low - kContact;
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

    static void grow(fcl::AABBd& box, double by) {
        box.min_ -= Eigen::Vector3d::Constant(by);
        box.max_ += Eigen::Vector3d::Constant(by);
    }

    // The beads each tool body may meet over the step: one walk of the printed part's tree
    // (FCL's dynamic AABB tree) with the tool bodies' swept boxes together, into
    // `candidates[k]` for tools[k]. A chunk, then a bead, drops out for a body when its box
    // misses the body's swept box, lies wholly below the body over the step (below(): its rise
    // is the same for every body), or its oriented box stays apart from the body's (apart()).
    std::vector<std::vector<std::size_t>> candidates;
    std::vector<const Node*> stack;
    std::vector<const fcl::AABBd*> active;
    // `mask`: the tools (bit k: tools[k]; from the 33rd on, all) the beads' chunk did not rule out.
    void sift(std::size_t first, std::size_t last, const StepBound& bound, unsigned mask) {
        for (std::size_t i = first; i < last; ++i) {
            const Bead& b = beads[i];
            double r = 0;
            bool risen = false;
            for (std::size_t k = 0; k < tools.size(); ++k) {
                const int t = tools[k];
                if ((k < 32 && !(mask >> k & 1u)) || !overlaps(b.box, swept[std::size_t(t)])) continue;
                if (!risen) r = rise(b.centre, b.half, b.reach, bound), risen = true;
                if (under(t, r) || known_clear(bead_clear[i * tools.size() + k], odo[std::size_t(t)], step_rate(t)) ||
                    apart(t, bead_obb(b)))
                    continue;
                candidates[k].push_back(i);
            }
        }
    }
    void collect_part(const StepBound& bound) {
        candidates.resize(tools.size());
        for (auto& c : candidates) c.clear();
        sift(open_first, beads.size(), bound, ~0u);
        const Node* root = part.getRoot();
        if (!root) return;
        // Only the tool bodies whose swept boxes meet the root's can meet a node's below it.
        active.clear();
        for (const int t : tools)
            if (overlaps(root->bv, swept[std::size_t(t)])) active.push_back(&swept[std::size_t(t)]);
        if (active.empty()) return;
        stack.clear();
        stack.push_back(root);
        while (!stack.empty()) {
            const auto* node = stack.back();
            stack.pop_back();
            bool meets = false;
            for (const fcl::AABBd* box : active)
                if (overlaps(node->bv, *box)) {
                    meets = true;
                    break;
                }
            if (!meets) continue;
            if (!node->isLeaf()) {
                stack.push_back(node->children[1]);
                stack.push_back(node->children[0]);
                continue;
            }
            const Chunk& ch = chunks[std::size_t(reinterpret_cast<std::intptr_t>(node->data))];
            const double r = rise(ch.centre, ch.half, ch.reach, bound);
            unsigned mask = 0;
            for (std::size_t k = 0; k < tools.size(); ++k) {
                const int t = tools[k];
                // Past 32 bodies the mask cannot tell: their beads are all sifted.
                if (k >= 32 || (overlaps(node->bv, swept[std::size_t(t)]) && !under(t, r) && !apart(t, ch.obb))) mask |= 1u << (k % 32);
            }
            if (mask) sift(ch.first, ch.first + kChunk, bound, mask);
        }
    }

    // The bead as FCL's oriented box.
    static fcl::OBBd bead_obb(const Bead& b) {
        fcl::OBBd o;
        o.axis = b.pose.linear();
        o.To = b.centre;
        o.extent = 0.5 * b.size;
        return o;
    }
    // Whether tool body t, over the whole step from `step_a` (each of its points moving at most
    // step_rate, set by test_step), stays apart from the box `other`: its own box (in its
    // frame) grown by that much holds it all along; FCL's separating-axis test of two boxes.
    const Snapshot *step_a = nullptr, *step_b = nullptr;
    double step_rate(int i) {
        if (D[std::size_t(i)] < 0) D[std::size_t(i)] = rate(i, *step_a, *step_b, bow[std::size_t(i)]);
        return D[std::size_t(i)];
    }
    // Tool body t's own box grown by step_rate(t) + kContact, in the part frame at the step's
    // start: made once a step (`held_ok`, cleared by test_step), for apart().
    struct Held {
        Eigen::Matrix3d axes;  // the body's axes, columns
        Eigen::Vector3d centre, extent;
    };
    std::vector<Held> held;
    std::vector<char> held_ok;
    const Held& held_box(int t) {
        Held& h = held[std::size_t(t)];
        if (held_ok[std::size_t(t)]) return h;
        const fcl::CollisionGeometryd& g = *solids[std::size_t(t)].object->collisionGeometry();
        const Iso& pose = step_a->pose[std::size_t(t)];
        h.axes = pose.linear();
        h.centre = pose * (0.5 * (g.aabb_local.min_ + g.aabb_local.max_));
        h.extent = 0.5 * (g.aabb_local.max_ - g.aabb_local.min_) + Eigen::Vector3d::Constant(step_rate(t) + kContact);
        held_ok[std::size_t(t)] = 1;
        return h;
    }
    bool apart(int t, const fcl::OBBd& other) {
        const Held& h = held_box(t);
        const Eigen::Vector3d w = other.To - h.centre;
        // The separating-axis test on the two boxes' own six face normals (of the fifteen: fewer
        // axes find fewer gaps, never a false one), the body's first, each row of R (the body's
        // axes against the other's) made only when its axis is tried: most gaps show on one.
        Eigen::Matrix3d R;
        for (int i = 0; i < 3; ++i) {
            const Eigen::Vector3d a = h.axes.col(i);
            R.row(i) = a.transpose() * other.axis;
            if (std::abs(a.dot(w)) > h.extent[i] + R.row(i).cwiseAbs().dot(other.extent)) return true;
        }
        for (int j = 0; j < 3; ++j)
            if (std::abs(other.axis.col(j).dot(w)) > other.extent[j] + R.col(j).cwiseAbs().dot(h.extent)) return true;
        return false;
    }

    // The outcome of one step's test.
    enum class Step { Clear, Unsure, Hit };
    // Conservative advancement of tool t against `other` over sa..sb: the contact, if any.
    // Clear: `until` is how far the pair may move (on the odometer, from the step's start) before
    // they can meet: the last distance measured plus the motion bound up to where it was measured.
    bool advance(int t, const fcl::CollisionObjectd& other, int who, double rate, const double* q0, const double* q1, double sa,
                 double sb, double& s_hit, double& until) {
        double s = sa;
        for (int it = 0;; ++it) {
            // At the step's start the poses are its snapshot's: most pairs clear there at once.
            const Snapshot* at = step_a;
            if (it > 0) pose_at(q0, q1, s, mid), at = &mid;
            place(t, at->pose[std::size_t(t)]);
            if (who >= 0 && solids[std::size_t(who)].moves) place(who, at->pose[std::size_t(who)]);
            const double d = distance(*solids[std::size_t(t)].object, other);
            if (d <= kContact || it >= kMaxAdvances) {
                s_hit = s;
                return true;
            }
            // The pair cannot meet before s + d / rate: past the step's end, done.
            if (rate <= 0 || s + d / rate >= sb) {
                until = (s - sa) * rate + d;
                return false;
            }
            s += d / rate;
        }
    }

    // Cached clearance (conservative advancement carried across steps and pieces): a distance d
    // measured between a tool body and a bead (or obstacle) stays a lower bound until the pair
    // has moved d towards each other. Each solid's odometer sums its motion bound (step_rate)
    // over the steps swept clear in a row; a pair is skipped while its odometers at the step's
    // end are below what they were when measured plus d. A sweep that does not start where the
    // last one ended clear (a contact, a detour's retry, the look-back's replay) starts a new
    // epoch: every cached value lapses.
    struct Clear {
        double until = 0;          // the pair's odometer sum up to which it cannot meet
        std::uint32_t epoch = 0;   // 0: never measured
    };
    std::vector<Clear> bead_clear;      // per bead and tool (beads.size() x tools.size())
    std::vector<Clear> solid_clear;     // per tool and solid (tools.size() x solids.size())
    std::vector<double> odo;            // per solid: motion bound summed, this epoch
    std::uint32_t epoch = 1;
    void new_epoch() {
        ++epoch;
        odo.assign(solids.size(), 0.0);
    }
    // Whether the pair (tool k, with odometer sum `at_start` at the step's start and `moving`
    // over it) is known apart over the whole step.
    bool known_clear(const Clear& c, double at_start, double moving) const {
        return c.epoch == epoch && at_start + moving < c.until;
    }

    Snapshot mid;
    std::vector<fcl::AABBd> swept;
    std::vector<double> bow, D;  // per solid, this step: curve() and step_rate()
    std::vector<double> dstep;

    // One step sa..sb of the piece q0 -> q1, its ends' snapshots a and b (with boxes). `leaf`:
    // the step is small enough for the advancement; otherwise anything the cheap tests cannot
    // rule out makes it Unsure (the caller halves the step).
    Step test_step(const double* q0, const double* q1, double sa, double sb, const Snapshot& a, const Snapshot& b, bool leaf,
                   std::optional<CollisionEvent>& first) {
        const std::size_t n = q.size();
        dstep.resize(n);
        for (std::size_t j = 0; j < n; ++j) dstep[j] = b.q[j] - a.q[j];
        const Turns tt = turns_of(dstep.data());
        const bool turns = tt.T > 0;
        // Each moving solid's sweep over the step, boxed: every point stays within M / 8 of the
        // straight line between its two ends (|p''| <= M), and those lines lie in the join of the
        // end boxes (docs/machines.md, "Bodies").
        swept.resize(solids.size());
        bow.assign(solids.size(), 0.0);
        for (std::size_t i = 0; i < solids.size(); ++i) {
            swept[i] = a.box[i];
            if (!solids[i].moves) continue;
            swept[i] += b.box[i];
            if (turns) bow[i] = curve(a.centre[i], solids[i].body->radius, a, tt);
            grow(swept[i], 0.25 * bow[i] + kContact);
        }
        const StepBound bound = step_bound(a, b, tt);
        D.assign(solids.size(), -1.0);
        held.resize(solids.size());
        held_ok.assign(solids.size(), 0);
        step_a = &a;
        step_b = &b;
        auto rate_of = [&](int i) { return step_rate(i); };
        double first_s = 2;
        auto hit = [&](int t, int who, const Bead* bead, double s) {
            if (s >= first_s) return;
            first_s = s;
            CollisionEvent ev;
            ev.tool_body = solids[std::size_t(t)].body->name;
            const fcl::CollisionObjectd& other = bead ? object_of(*bead) : *solids[std::size_t(who)].object;
            if (bead) ev.bead_line = bead->line;
            else ev.other = solids[std::size_t(who)].body->name;
            pose_at(q0, q1, s, mid);
            place(t, mid.pose[std::size_t(t)]);
            if (!bead && solids[std::size_t(who)].moves) place(who, mid.pose[std::size_t(who)]);
            ev.at = contact_point(*solids[std::size_t(t)].object, other);
            first = ev;
        };
        const Node* root = part.getRoot();
        bool collected = false;
        for (std::size_t k = 0; k < tools.size(); ++k) {
            const int t = tools[k];
            const fcl::AABBd& box = swept[std::size_t(t)];
            for (const auto* list : {&fixed_obstacles, &moving_obstacles})
                for (const int o : *list) {
                    if (!overlaps(box, swept[std::size_t(o)])) continue;
                    const Solid& obstacle = solids[std::size_t(o)];
                    if (!obstacle.moves) {
                        const fcl::AABBd& ob = obstacle.object->getAABB();
                        const Eigen::Vector3d e = 0.5 * (ob.max_ - ob.min_);
                        const Eigen::Vector3d half[3] = {Eigen::Vector3d(e.x(), 0, 0), Eigen::Vector3d(0, e.y(), 0), Eigen::Vector3d(0, 0, e.z())};
                        if (below(t, ob.center(), half, e.norm(), bound)) continue;
                    }
                    Clear& c = solid_clear[std::size_t(k) * solids.size() + std::size_t(o)];
                    const double at_start = odo[std::size_t(t)] + odo[std::size_t(o)], moving = rate_of(t) + rate_of(o);
                    if (known_clear(c, at_start, moving)) continue;
                    if (!leaf) return Step::Unsure;
                    double s = 0, until = 0;
                    if (advance(t, *obstacle.object, o, moving / (sb - sa), q0, q1, sa, sb, s, until)) hit(t, o, nullptr, s);
                    else c = {at_start + until, epoch};
                }
            // The printed part: the beads whose boxes meet the tool body's swept box, less those
            // wholly below the body's lowest point over the step (the layers it prints on).
            if ((!root || !overlaps(root->bv, box)) && open_first == beads.size()) continue;
            if (!collected) collect_part(bound), collected = true;
            for (const std::size_t c : candidates[std::size_t(k)]) {
                const Bead& bead = beads[c];
                if (!leaf) return Step::Unsure;
                double s = 0, until = 0;
                if (advance(t, object_of(bead), -1, rate_of(t) / (sb - sa), q0, q1, sa, sb, s, until)) hit(t, -1, &bead, s);
                else bead_clear[c * tools.size() + std::size_t(k)] = {odo[std::size_t(t)] + until, epoch};
            }
        }
        return first ? Step::Hit : Step::Clear;
    }

    // The middles by depth of the halving, reused (a deque: growing keeps the others in place).
    std::deque<Snapshot> pool;
    Snapshot start;      // at the last piece's end: the next piece's start, usually
    bool start_valid = false;

    // Tests sa..sb (ends a, b), halving it while the cheap tests are unsure; the first contact.
    bool test_span(const double* q0, const double* q1, double sa, double sb, const Snapshot& a, const Snapshot& b, int depth,
                   std::optional<CollisionEvent>& first) {
        double turn = 0;
        for (const auto& r : rotaries) turn += std::abs(b.q[std::size_t(r.joint)] - a.q[std::size_t(r.joint)]) * kPi / 180.0;
        const bool leaf = turn <= kSubStepTurn;
        // The bounds hold for a turn under half a radian (bound_at); test larger spans halved.
        if (turn < kWholeTurn) {
            const Step r = test_step(q0, q1, sa, sb, a, b, leaf, first);
            if (r == Step::Clear)  // the odometers run on past the step
                for (std::size_t i = 0; i < solids.size(); ++i)
                    if (solids[i].moves) odo[i] += step_rate(int(i));
            if (r != Step::Unsure) return r == Step::Hit;
        }
        if (std::size_t(depth) >= pool.size()) pool.resize(std::size_t(depth) + 1);
        const double sm = 0.5 * (sa + sb);
        Snapshot& m = pool[std::size_t(depth)];  // deeper halvings use deeper ones
        pose_at(q0, q1, sm, m, true);
        if (test_span(q0, q1, sa, sm, a, m, depth + 1, first)) return true;
        return test_span(q0, q1, sm, sb, m, b, depth + 1, first);
    }

    // The first contact over the sweep q0 -> q1, or none.
    std::optional<CollisionEvent> sweep(const double* q0, const double* q1) {
        const std::size_t n = q.size();
        if (!start_valid || !std::equal(q0, q0 + n, start.q.begin())) {
            snap(q0, start, true);
            new_epoch();
        }
        if (end.q.size() != n) end.q.resize(n);
        snap(q1, end, true);
        std::optional<CollisionEvent> first;
        start_valid = false;
        test_span(q0, q1, 0, 1, start, end, 0, first);
        if (first) return first;
        tips_q0 = start.q;
        tips_q1 = end.q;
        tip0_part = start.tip.translation();
        tip1_part = end.tip.translation();
        axis1_part = end.tip.linear() * machine.tool_axis;
        std::swap(start, end);
        start_valid = true;
        return std::nullopt;
    }
    Snapshot end;

    void add_bead(const double* q0, const double* q1, double e, std::uint64_t line) {
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
        if (beads.size() - open_first < kChunk) return;
        fcl::AABBd box = beads[open_first].box;
        for (std::size_t i = open_first + 1; i < beads.size(); ++i) box += beads[i].box;
        Chunk& ch = chunks.emplace_back();
        ch.first = open_first;
        ch.node = part.insert(box, reinterpret_cast<void*>(std::intptr_t(chunks.size() - 1)));
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
        // part doubles (a rebuild costs about a hundred walks).
        if (const std::size_t n = chunks.size(); n >= 64 && (n & (n - 1)) == 0) part.balanceTopdown();
    }

    void truncate(std::size_t count) {
        if (beads.size() <= count) return;
        while (!chunks.empty() && chunks.back().first + kChunk > count) {
            part.remove(chunks.back().node);
            chunks.pop_back();
        }
        open_first = chunks.empty() ? 0 : chunks.back().first + kChunk;
        beads.erase(beads.begin() + std::ptrdiff_t(count), beads.end());
        bead_clear.resize(count * tools.size());
    }
};

CollisionStage::CollisionStage(const Kinematics& kinematics, CollisionPolicy policy, CollideCursor& cursor, const Modes& modes,
                               std::optional<bool> reroute, std::optional<double> lift)
    : impl_(std::make_unique<Impl>(kinematics.machine())),
      cursor_(cursor),
      modes_(modes),
      policy_(policy),
      kinematics_(kinematics),
      // The detour is written uncompensated: a machine with compensation is not re-routed.
      reroute_(reroute.value_or(kinematics.machine().geometry->settings.reroute) && kinematics.machine().compensation.empty()),
      lift_(lift.value_or(kinematics.machine().geometry->settings.lift)) {}

CollisionStage::~CollisionStage() = default;

std::size_t CollisionStage::beads() const { return impl_->beads.size(); }
std::uint64_t CollisionStage::distance_queries() const { return impl_->queries; }

std::optional<CollisionEvent> CollisionStage::sweep(std::span<const double> q0, std::span<const double> q1) {
    impl_->truncate(cursor_.beads);
    auto ev = impl_->sweep(q0.data(), q1.data());
    if (ev) ev->line = cursor_.line;
    return ev;
}

void CollisionStage::add_bead(std::span<const double> q0, std::span<const double> q1, double e, std::uint64_t line) {
    impl_->truncate(cursor_.beads);
    if (impl_->beads.size() >= kMaxBeads)
        throw LineError(1, "the printed part has more than " + std::to_string(kMaxBeads) +
                               " beads, the collision check's bound (docs/limits.md): translate with --collision off, or split the print");
    impl_->add_bead(q0.data(), q1.data(), e, line);
    cursor_.beads = impl_->beads.size();
}

std::vector<CollisionEvent> CollisionStage::touching(std::span<const double> q) {
    std::vector<CollisionEvent> out;
    Snapshot s;
    impl_->snap(q.data(), s);
    for (std::size_t i = 0; i < impl_->solids.size(); ++i) impl_->place(int(i), s.pose[i]);
    for (const int t : impl_->tools)
        for (const auto* list : {&impl_->fixed_obstacles, &impl_->moving_obstacles})
            for (const int o : *list) {
                auto& a = *impl_->solids[std::size_t(t)].object;
                auto& b = *impl_->solids[std::size_t(o)].object;
                if (impl_->distance(a, b) > kContact) continue;
                CollisionEvent ev;
                ev.tool_body = impl_->solids[std::size_t(t)].body->name;
                ev.other = impl_->solids[std::size_t(o)].body->name;
                ev.at = impl_->contact_point(a, b);
                out.push_back(ev);
            }
    return out;
}

double CollisionStage::clearance(std::span<const double> q) {
    impl_->truncate(cursor_.beads);
    Snapshot s;
    impl_->snap(q.data(), s);
    for (std::size_t i = 0; i < impl_->solids.size(); ++i) impl_->place(int(i), s.pose[i]);
    double least = 1e300;
    for (const int t : impl_->tools) {
        auto& a = *impl_->solids[std::size_t(t)].object;
        for (const auto* list : {&impl_->fixed_obstacles, &impl_->moving_obstacles})
            for (const int o : *list) least = std::min(least, impl_->distance(a, *impl_->solids[std::size_t(o)].object));
        for (const auto& b : impl_->beads) least = std::min(least, impl_->distance(a, impl_->object_of(b)));
    }
    return std::max(least, 0.0);
}

const std::vector<std::vector<double>>* CollisionStage::piece(std::span<const double> from, std::span<const double> to,
                                                              const std::optional<PassedNumber>& e) {
    double de = 0;
    if (e) {
        if (modes_.e_relative) de = e->value;
        else de = e->value - cursor_.e, cursor_.e = e->value;
    }
    const std::vector<std::vector<double>>* detour = nullptr;
    if (auto ev = sweep(from, to)) {
        // A travel goes round instead, when it can.
        double lift = 0;
        std::optional<std::vector<std::vector<double>>> round;
        if (!e && reroute_) round = reroute(from, to, lift);
        if (round) {
            detour_ = std::move(*round);
            detour = &detour_;
            ev->rerouted = true;
            ev->lift = lift;
            if (on_collision) on_collision(*ev);
        } else {
            if (on_collision) on_collision(*ev);
            if (policy_ == CollisionPolicy::Refuse) throw LineError(1, ev->message());
        }
    }
    if (de > 0) add_bead(from, to, de, cursor_.line);
    return detour;
}

std::optional<std::vector<std::vector<double>>> CollisionStage::reroute(std::span<const double> q0, std::span<const double> q1, double& lift) {
    const std::vector<double> a(q0.begin(), q0.end()), b(q1.begin(), q1.end());
    const Pose p0 = kinematics_.forward(a), p1 = kinematics_.forward(b);
    // Lifted along each end's own tool axis (its orientation kept); higher if the first is not enough.
    for (const double h : {lift_, 2 * lift_, 4 * lift_}) {
        std::vector<double> up0 = a, up1 = b;
        if (!kinematics_.solve_position(p0.tip + h * p0.axis, up0).ok() || !kinematics_.solve_position(p1.tip + h * p1.axis, up1).ok())
            return std::nullopt;  // past a joint's limit: no room to lift
        if (sweep(a, up0) || sweep(up0, up1) || sweep(up1, b)) continue;
        lift = h;
        return std::vector<std::vector<double>>{up0, up1};
    }
    return std::nullopt;
}

}  // namespace xlate5
