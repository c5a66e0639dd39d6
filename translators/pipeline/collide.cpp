// SPDX-License-Identifier: GPL-3.0-or-later
// The collision stage on FCL: bodies, the printed part's beads, the swept check.
// What it may call: see collide.hpp.
#include "translators/pipeline/collide.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <iomanip>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/pipeline/collide_part.hpp"

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

using namespace collision_parts;

namespace {

// Rotation (radians, all rotaries together) of one sub-step of the sweep: keeps the bound's
// second-order term (the arms changing within a step) small; see docs/machines.md.
constexpr double kSubStepTurn = 2.0 * kPi / 180.0;
// Advances per body pair and sub-step before the pair is taken as touching (a contact closer
// than the advance can resolve at a reasonable cost).
constexpr int kMaxAdvances = 20000;
// A span turning less than this (radians, all rotaries together) is tested whole before it is
// halved: the bounds need under half a radian (bound_at).
constexpr double kWholeTurn = 0.25;

}  // namespace

// The sweep itself, on the parts below it (collide_part.hpp and what it builds on).
struct CollisionStage::Impl : CollidePart {
    using CollidePart::CollidePart;

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
        // The open chunk's beads, when its box meets a tool body's swept box.
        if (open_first < beads.size())
            for (const int t : tools)
                if (overlaps(open_box, swept[std::size_t(t)])) {
                    sift(open_first, beads.size(), bound, ~0u);
                    break;
                }
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

    Snapshot mid;
    std::vector<fcl::AABBd> swept;
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
        step_turns = turns;
        // Each moving solid's sweep over the step, boxed: every point stays within M / 8 of the
        // straight line between its two ends (|p''| <= M), and those lines lie in the join of the
        // end boxes (docs/machines.md, "Bodies").
        swept.resize(solids.size());
        bow.assign(solids.size(), 0.0);
        for (std::size_t i = 0; i < solids.size(); ++i) {
            swept[i] = a.box[i];
            if (!solids[i].moves) continue;
            swept[i].min_ = swept[i].min_.cwiseMin(b.box[i].min_);  // FCL's += is out of line
            swept[i].max_ = swept[i].max_.cwiseMax(b.box[i].max_);
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
            for (const int o : obstacles) {
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
            if ((!root || !overlaps(root->bv, box)) && (open_first == beads.size() || !overlaps(open_box, box))) continue;
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
        for (const int o : impl_->obstacles) {
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
        for (const int o : impl_->obstacles) least = std::min(least, impl_->distance(a, *impl_->solids[std::size_t(o)].object));
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
    // Filament drawn back (a retraction) is pushed out again before any leaves the nozzle: the
    // prime after a travel refills the nozzle and lays no bead.
    if (de < 0) {
        cursor_.retracted -= de;
        de = 0;
    } else {
        const double refill = std::min(de, cursor_.retracted);
        cursor_.retracted -= refill;
        de -= refill;
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
