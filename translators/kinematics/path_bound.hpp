// SPDX-License-Identifier: GPL-3.0-or-later
// The path bound (the face's fourth part, kinematics.hpp): how far, anywhere along the firmware's
// path between two joint vectors (every joint at a constant rate), the tip and the tool axis leave
// the chords between its ends; from the machine's chains alone, taken once at load. The
// derivation is in path_bound.cpp. May call: the machine data.
#pragma once
#include <cstddef>
#include <vector>

#include "translators/kinematics/kinematics_types.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

// Upper bounds on how far the tip (mm) and the tool axis (a unit vector) leave the chords.
struct PathBound {
    double tip = 0, axis = 0;
};

class JointPathBound {
public:
    JointPathBound() = default;
    explicit JointPathBound(const Machine& machine);

    // The bound from the path's start `a` (Kinematics::path_end, near_end or reach()).
    PathBound joint_path_bound(const PathEnd& a, const double* qa, const double* qb) const;
    // joint_path_bound for any order of the terms (it takes a shorter path for some orders; the
    // tests hold it against this one).
    PathBound joint_path_bound_general(const PathEnd& a, const double* qa, const double* qb) const;
    // joint_path_bound's bound for the tool axis alone, for a turn of any size.
    double axis_path_bound(const double* qa, const double* qb) const;

    // The machine's reach as a path end (lever arms only, no pose): the tip's largest distance
    // from each rotary axis anywhere inside the joint limits. joint_path_bound(reach(), qa, qb)
    // bounds a path between joints inside the limits without an FK; has_reach() is false when a
    // linear joint has no limits.
    bool has_reach() const { return has_reach_; }
    const PathEnd& reach() const { return reach_; }
    // How far the tip can move between joints qa and qb (each joint on its own, added): an upper
    // bound by the reach, for joints inside the limits.
    double reach_shift(const double* qa, const double* qb) const;

    // The PathEnd at joints q near a solved end (the end rounded to the printed decimals), with
    // no FK: the solved pose with the slack that moving its joints to q can add (each rotary
    // turns the tip by at most its angle times the tip's distance from its axis, a linear joint
    // moves it by its own travel) and the arms grown by how far the tip can move at all. False
    // when that cannot be bounded (a linear joint without limits: no reach).
    bool near_end(const SolvedEnd& solved, const double* q, PathEnd& out) const;
    // near_end's growth is reach_shift's sum: every joint that shifts the tip has a term in it
    // (a rotary in no chain shifts nothing). Otherwise the position solve gives no SolvedEnds.
    bool covers_every_shift() const { return covers_; }

private:
    // The loading's steps, in this order.
    void load_terms(const Machine& machine);
    void load_reach(const Machine& machine);
    void load_near_terms(const Machine& machine);
    PathBound joint_path_bound_split(const PathEnd& a, const double* qa, const double* qb) const;

    // The moving elements of the chain seen from the part (the part chain inverted, then the tool
    // chain), in that order; linear joints ahead of every rotary are left out.
    struct Term {
        int joint = 0;
        bool rotary = false;
        double scale = 1;  // the axis's length as written
        int arm = 0;       // rotary: its index in PathEnd::arm
    };
    std::vector<Term> terms_;
    // terms_ when it is its rotaries and then its linear joints alone (joint_path_bound_split).
    struct Split {
        bool on = false;
        int rotary = 0, count = 0;
        Term terms[kMaxJoints];
    } split_;
    PathEnd reach_;  // see reach()
    bool has_reach_ = false;
    std::vector<double> shift_per_unit_;  // per joint: mm of tip per unit of the joint, at most
    // near_end's terms, looked up once: each linear joint with its mm per unit, each rotary
    // element with its radians per unit and its arm.
    struct NearTerm {
        int joint = 0;
        double per_unit = 0;
        int arm = -1;               // rotary: its index in PathEnd::arm; -1 for a linear joint
        double reach_per_unit = 0;  // the joint's shift_per_unit_ (reach_shift's term), on its first term only
    };
    std::vector<NearTerm> near_terms_;
    std::size_t near_linear_ = 0;  // near_terms_' linear joints, all ahead of its rotary elements
    int arm_count_ = 0;            // rotary elements, the entries of PathEnd::arm in use
    bool covers_ = false;          // see covers_every_shift()
};

}  // namespace xlate5
