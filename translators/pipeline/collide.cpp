// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage on FCL: bodies, the printed part's beads, the swept check.
// What it may call: see collide.hpp.
#include "translators/pipeline/collide.hpp"

#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/cone.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>

#include <cmath>
#include <iomanip>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"

namespace xlate5 {

std::string CollisionEvent::message() const {
    std::ostringstream os;
    os << std::fixed << std::setprecision(3) << "collision: " << tool_body << " meets ";
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

struct Solid {
    const Body* body = nullptr;
    std::unique_ptr<fcl::CollisionObjectd> object;
    bool moves = true;  // in the part frame (false: on the plate, fixed there)
};

// A sub-step's end: every solid's pose in the part frame, and what the bound needs.
struct Snapshot {
    std::vector<Iso> pose;                   // per solid, part frame
    std::vector<Eigen::Vector3d> centre;     // per solid, base frame
    std::vector<Eigen::Vector3d> line_point, line_dir;  // per rotary chain element, base frame
    std::vector<fcl::AABBd> box;             // per solid, part frame
    Iso tip = Iso::Identity();               // the tip's frame, part frame
    Eigen::Vector3d tip_base = Eigen::Vector3d::Zero();
};

void walk(const std::vector<ChainElement>& chain, const double* q, std::vector<Iso>& out) {
    out.resize(chain.size());
    Iso T = Iso::Identity();
    for (std::size_t k = 0; k < chain.size(); ++k) {
        const ChainElement& e = chain[k];
        switch (e.kind) {
            case ChainElement::Kind::Fixed: T = T * e.fixed; break;
            case ChainElement::Kind::Linear: T.translate(e.axis * q[e.joint]); break;
            case ChainElement::Kind::Rotary:
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
    struct Bead {
        std::unique_ptr<fcl::CollisionObjectd> object;
        std::uint64_t line = 0;
        Eigen::Vector3d centre, half[3];  // the box: centre and half axes, part frame
    };
    std::vector<Bead> beads;
    fcl::DynamicAABBTreeCollisionManagerd part;
    std::vector<Iso> part_frames, tool_frames;
    std::vector<double> q;
    std::uint64_t queries = 0;

    Impl(const Machine& m) : machine(m), settings(m.geometry->settings) {
        for (const Body& b : m.geometry->bodies) {
            Solid s;
            s.body = &b;
            s.object = std::make_unique<fcl::CollisionObjectd>(make_geometry(b.shape));
            s.moves = !(!b.tool_side && b.after == int(m.part_chain.size()) - 1);
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
        for (std::size_t j = 0; j < m.joints.size(); ++j)
            if (!m.joints[j].rotary) linear_joints.push_back(int(j));
        q.resize(m.joints.size());
        // The fixed obstacles' poses never change: set once, at home.
        Snapshot at;
        const auto home = m.home_joints();
        snap(home.data(), at);
        for (const int i : fixed_obstacles) place(i, at.pose[std::size_t(i)]);
    }

    void place(int i, const Iso& pose) {
        auto& o = *solids[std::size_t(i)].object;
        o.setTransform(pose);
        o.computeAABB();
    }

    // Every solid at joints `qq`: poses (part frame), centres (base frame), rotary axis lines.
    void snap(const double* qq, Snapshot& s) {
        walk(machine.part_chain, qq, part_frames);
        walk(machine.tool_chain, qq, tool_frames);
        const Iso part_end = part_frames.empty() ? Iso::Identity() : part_frames.back();
        const Iso to_part = part_end.inverse();
        s.pose.resize(solids.size());
        s.centre.resize(solids.size());
        s.box.resize(solids.size());
        for (std::size_t i = 0; i < solids.size(); ++i) {
            const Body& b = *solids[i].body;
            const auto& frames = b.tool_side ? tool_frames : part_frames;
            const Iso base = (b.after < 0 ? Iso::Identity() : frames[std::size_t(b.after)]) * b.place;
            s.centre[i] = base.translation();
            s.pose[i] = to_part * base;
        }
        const Iso tip_base = tool_frames.empty() ? Iso::Identity() : tool_frames.back();
        s.tip = to_part * tip_base;
        s.tip_base = tip_base.translation();
        s.line_point.resize(rotaries.size());
        s.line_dir.resize(rotaries.size());
        for (std::size_t r = 0; r < rotaries.size(); ++r) {
            const auto& chain = rotaries[r].tool ? machine.tool_chain : machine.part_chain;
            const auto& frames = rotaries[r].tool ? tool_frames : part_frames;
            const ChainElement& e = chain[std::size_t(rotaries[r].element)];
            const Iso before = rotaries[r].element == 0 ? Iso::Identity() : frames[std::size_t(rotaries[r].element - 1)];
            s.line_point[r] = before * e.point;
            s.line_dir[r] = before.linear() * e.axis;
        }
    }

    // How far any point of solid i may move in the part frame over the joint change dq, from
    // snapshot s on (docs/machines.md, "Bodies": the sweep's bound). Loose (the linear joints'
    // travel and the rotaries' arms add up although the kinematics makes them cancel at the
    // tip): it only bounds the arms' growth within a sub-step for rate() below.
    double bound(int i, const Snapshot& s, const double* dq) const {
        if (!solids[std::size_t(i)].moves) return 0;
        return bound_at(s.centre[std::size_t(i)], solids[std::size_t(i)].body->radius, s, dq);
    }
    // The same for a sphere of radius R about `centre` (base frame) carried by the tool.
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
    // (joint change dq over it): a Lipschitz bound, tight where bound() is loose. A point's
    // path p(u) has |p'(u) - (p(1) - p(0))| <= M / 2 with M >= |p''|; p(1) - p(0) is at most
    // the body frame's chord plus its turn times the body's radius; and with the joints moving
    // at constant rates, M <= 4 T^2 r + 3 T L (T: the rotaries' turn, L: the linear joints'
    // travel, r: the farthest a point or axis gets from a rotary axis). Derivation:
    // docs/machines.md, "Bodies".
    double rate(int i, const Snapshot& a, const Snapshot& b, const double* dq) const {
        if (!solids[std::size_t(i)].moves) return 0;
        const Body& body = *solids[std::size_t(i)].body;
        const Iso& pa = a.pose[std::size_t(i)];
        const Iso& pb = b.pose[std::size_t(i)];
        // The bounding sphere's centre: the body's chain frame origin.
        const Eigen::Vector3d o = body.place.inverse().translation();
        const Eigen::Vector3d oa = pa * o, ob = pb * o;
        const double turned = Eigen::AngleAxisd(pa.linear().transpose() * pb.linear()).angle();
        const double chord = (ob - oa).norm() + std::abs(turned) * body.radius;
        return chord + curve(a.centre[std::size_t(i)], body.radius, a, dq);
    }
    // Half the bound on |p''| of rate() for a sphere of radius R about `centre` (base frame).
    double curve(const Eigen::Vector3d& centre, double R, const Snapshot& a, const double* dq) const {
        double T = 0, L = 0, r = 0;
        for (const int j : linear_joints) L += std::abs(dq[j]);
        for (std::size_t k = 0; k < rotaries.size(); ++k) {
            const double th = std::abs(dq[rotaries[k].joint]) * kPi / 180.0;
            if (th == 0) continue;
            T += th;
            // Every point of the body lies within its radius of the shape's centre.
            const Eigen::Vector3d v = centre - a.line_point[k];
            r = std::max(r, (v - v.dot(a.line_dir[k]) * a.line_dir[k]).norm() + R);
        }
        if (T == 0) return 0;
        r += 2 * bound_at(centre, R, a, dq);  // how far points and axes get within the step
        return 0.5 * (4 * T * T * r + 3 * T * L);
    }

    // Whether the box (centre c, half axes h, part frame, fixed there) lies wholly below tool
    // body t's lowest point along the tool axis over the whole sub-step a -> b: then they
    // cannot meet. A point x's height over the tip, z = n . (x - tip), changes at most by
    // T (|x - tip| + Dtip) + Dtip (T: the turn, Dtip: the tip's rate) over the step.
    bool below(int t, const Eigen::Vector3d& c, const Eigen::Vector3d* h, const Snapshot& a, double T, double Dtip) const {
        const double low = solids[std::size_t(t)].body->low;
        if (low < -1e299) return false;
        const Eigen::Vector3d n = a.tip.linear() * machine.tool_axis;
        const Eigen::Vector3d tip = a.tip.translation();
        for (int k = 0; k < 8; ++k) {
            const Eigen::Vector3d x = c + ((k & 1) ? h[0] : -h[0]) + ((k & 2) ? h[1] : -h[1]) + ((k & 4) ? h[2] : -h[2]);
            const double z = n.dot(x - tip) + T * ((x - tip).norm() + Dtip) + Dtip;
            if (z >= low - kContact) return false;
        }
        return true;
    }

    void pose_at(const double* q0, const double* q1, double s, Snapshot& out) {
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = q0[j] + (q1[j] - q0[j]) * s;
        snap(q.data(), out);
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

    std::shared_ptr<fcl::Boxd> probe_box;

    std::vector<std::size_t> candidates;
    static constexpr std::intptr_t kProbe = -1;
    static bool collect(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
        auto* self = static_cast<Impl*>(data);
        // One is the probe; the bead carries its index.
        const auto* bead = reinterpret_cast<std::intptr_t>(a->getUserData()) == kProbe ? b : a;
        self->candidates.push_back(std::size_t(reinterpret_cast<std::intptr_t>(bead->getUserData())));
        return false;  // every one
    }
    // The beads whose boxes meet `box`, into `candidates`.
    void collect_part(const fcl::AABBd& box) {
        const Eigen::Vector3d size = (box.max_ - box.min_).cwiseMax(1e-9);
        if (!probe_box) probe_box = std::make_shared<fcl::Boxd>(size);
        probe_box->side = size;
        probe_box->computeLocalAABB();
        fcl::CollisionObjectd probe(probe_box, Iso(Eigen::Translation3d(box.center())));
        probe.computeAABB();
        probe.setUserData(reinterpret_cast<void*>(kProbe));
        part.collide(&probe, this, &collect);
    }

    // The first contact over the sweep q0 -> q1, or none.
    std::optional<CollisionEvent> sweep(const double* q0, const double* q1) {
        const std::size_t n = q.size();
        std::vector<double> dq(n);
        double turn = 0;
        for (std::size_t j = 0; j < n; ++j) {
            dq[j] = q1[j] - q0[j];
            if (machine.joints[j].rotary) turn += std::abs(dq[j]) * kPi / 180.0;
        }
        const int steps = std::max(1, int(std::ceil(turn / kSubStepTurn)));
        Snapshot a, b, mid;
        snap(q0, a);
        std::vector<double> dstep(n);
        for (std::size_t j = 0; j < n; ++j) dstep[j] = dq[j] / steps;
        const bool step_turns = turn > 0;
        for (int k = 0; k < steps; ++k) {
            const double sa = double(k) / steps, sb = double(k + 1) / steps;
            pose_at(q0, q1, sb, b);
            // Each moving solid's sweep over the step, boxed: both ends' boxes joined and grown by
            // half its bound (a point that moves at most D stays within D/2 of one end).
            std::vector<fcl::AABBd> swept(solids.size());
            std::vector<double> D(solids.size(), 0.0);
            for (std::size_t i = 0; i < solids.size(); ++i) {
                if (!solids[i].moves) {
                    swept[i] = solids[i].object->getAABB();
                    continue;
                }
                place(int(i), a.pose[i]);
                fcl::AABBd box = solids[i].object->getAABB();
                place(int(i), b.pose[i]);
                box += solids[i].object->getAABB();
                D[i] = rate(int(i), a, b, dstep.data());
                // Without rotation every solid only translates, along a straight line in the part
                // frame: the join of its end boxes holds its whole sweep, no growth needed.
                grow(box, (step_turns ? 0.5 * D[i] : 0.0) + kContact);
                swept[i] = box;
            }
            // The turn and the tip's rate over the step, for below().
            double T = 0;
            for (const auto& r : rotaries) T += std::abs(dstep[std::size_t(r.joint)]) * kPi / 180.0;
            const double Dtip = (b.tip.translation() - a.tip.translation()).norm() + curve(a.tip_base, 0, a, dstep.data());
            std::optional<CollisionEvent> first;
            double first_s = 2;
            for (const int t : tools) {
                // Candidates: the bodies whose swept boxes meet the tool body's.
                std::vector<std::pair<int, const fcl::CollisionObjectd*>> cands;  // (solid, object)
                for (const auto* list : {&fixed_obstacles, &moving_obstacles})
                    for (const int o : *list)
                        if (swept[std::size_t(t)].overlap(swept[std::size_t(o)])) cands.push_back({o, solids[std::size_t(o)].object.get()});
                for (const auto& [who, obj] : cands) {
                    if (!solids[std::size_t(who)].moves) {
                        const fcl::AABBd& box = obj->getAABB();
                        const Eigen::Vector3d e = 0.5 * (box.max_ - box.min_);
                        const Eigen::Vector3d half[3] = {Eigen::Vector3d(e.x(), 0, 0), Eigen::Vector3d(0, e.y(), 0), Eigen::Vector3d(0, 0, e.z())};
                        if (below(t, box.center(), half, a, T, Dtip)) continue;
                    }
                    const double Do = D[std::size_t(who)];
                    const double rate = (D[std::size_t(t)] + Do) / (sb - sa);
                    double s = sa;
                    for (int it = 0;; ++it) {
                        pose_at(q0, q1, s, mid);
                        place(t, mid.pose[std::size_t(t)]);
                        if (solids[std::size_t(who)].moves) place(who, mid.pose[std::size_t(who)]);
                        const double d = distance(*solids[std::size_t(t)].object, *obj);
                        if (d <= kContact || it >= kMaxAdvances) {
                            if (s < first_s) {
                                first_s = s;
                                CollisionEvent ev;
                                ev.tool_body = solids[std::size_t(t)].body->name;
                                ev.other = solids[std::size_t(who)].body->name;
                                ev.at = contact_point(*solids[std::size_t(t)].object, *obj);
                                first = ev;
                            }
                            break;
                        }
                        // The pair cannot meet before s + d / rate: past the step's end, done.
                        if (rate <= 0 || s + d / rate >= sb) break;
                        s += d / rate;
                    }
                }
                // The printed part: the beads whose boxes meet the tool body's swept box (one
                // walk of the tree, no GJK), less those wholly below the body's lowest point
                // over the step (the layers it prints on); each one left advanced against.
                if (beads.empty()) continue;
                candidates.clear();
                collect_part(swept[std::size_t(t)]);
                const double rate = D[std::size_t(t)] / (sb - sa);
                for (const std::size_t c : candidates) {
                    const Bead& bead = beads[c];
                    if (below(t, bead.centre, bead.half, a, T, Dtip)) continue;
                    double s = sa;
                    for (int it = 0;; ++it) {
                        pose_at(q0, q1, s, mid);
                        place(t, mid.pose[std::size_t(t)]);
                        const double d = distance(*solids[std::size_t(t)].object, *bead.object);
                        if (d <= kContact || it >= kMaxAdvances) {
                            if (s < first_s) {
                                first_s = s;
                                CollisionEvent ev;
                                ev.tool_body = solids[std::size_t(t)].body->name;
                                ev.bead_line = bead.line;
                                ev.at = contact_point(*solids[std::size_t(t)].object, *bead.object);
                                first = ev;
                            }
                            break;
                        }
                        if (rate <= 0 || s + d / rate >= sb) break;
                        s += d / rate;
                    }
                }
            }
            if (first) return first;
            std::swap(a, b);
        }
        return std::nullopt;
    }

    void add_bead(const double* q0, const double* q1, double e, std::uint64_t line) {
        walk(machine.part_chain, q0, part_frames);
        walk(machine.tool_chain, q0, tool_frames);
        const Iso to_part0 = (part_frames.empty() ? Iso::Identity() : part_frames.back()).inverse();
        const Iso tip0 = to_part0 * (tool_frames.empty() ? Iso::Identity() : tool_frames.back());
        walk(machine.part_chain, q1, part_frames);
        walk(machine.tool_chain, q1, tool_frames);
        const Iso to_part1 = (part_frames.empty() ? Iso::Identity() : part_frames.back()).inverse();
        const Iso tip1 = to_part1 * (tool_frames.empty() ? Iso::Identity() : tool_frames.back());
        const Eigen::Vector3d p0 = tip0.translation(), p1 = tip1.translation();
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
        Eigen::Vector3d up = tip1.linear() * machine.tool_axis;
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
        auto object = std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Boxd>(length, w, h), pose);
        object->computeAABB();
        object->setUserData(reinterpret_cast<void*>(std::intptr_t(beads.size())));
        part.registerObject(object.get());
        beads.push_back({std::move(object), line, pose.translation(),
                         {0.5 * length * pose.linear().col(0), 0.5 * w * pose.linear().col(1), 0.5 * h * pose.linear().col(2)}});
    }

    void truncate(std::size_t count) {
        while (beads.size() > count) {
            part.unregisterObject(beads.back().object.get());
            beads.pop_back();
        }
    }
};

CollisionStage::CollisionStage(const Machine& machine, CollisionPolicy policy, CollideCursor& cursor, const Modes& modes)
    : impl_(std::make_unique<Impl>(machine)), cursor_(cursor), modes_(modes), policy_(policy) {}

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
        for (const auto& b : impl_->beads) least = std::min(least, impl_->distance(a, *b.object));
    }
    return std::max(least, 0.0);
}

void CollisionStage::piece(std::span<const double> from, std::span<const double> to, const std::optional<PassedNumber>& e) {
    double de = 0;
    if (e) {
        if (modes_.e_relative) de = e->value;
        else de = e->value - cursor_.e, cursor_.e = e->value;
    }
    if (auto ev = sweep(from, to)) {
        if (on_collision) on_collision(*ev);
        if (policy_ == CollisionPolicy::Refuse) throw LineError(1, ev->message());
    }
    if (de > 0) add_bead(from, to, de, cursor_.line);
}

}  // namespace xlate5
