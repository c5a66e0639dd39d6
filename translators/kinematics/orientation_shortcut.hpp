// SPDX-License-Identifier: GPL-3.0-or-later
// The orientation solutions' fast path, for two rotaries along coordinate axes (rw2's A/B head,
// pentarod's A/C table): the general path (Kinematics::orientation_solutions_general, chain.cpp)
// with every product by a zero entry left out, so the same bits. Chosen once at load; the tests
// hold it equal to the general path. May call: nothing but the math library.
#pragma once
#include <Eigen/Core>

#include "translators/kinematics/kinematics_types.hpp"

namespace xlate5 {

class OrientationShortcut {
public:
    // For rotary axes w1, w2 and tool axis p in the frame u' = G0^T u, with the joints' signs
    // (+1 tool chain, -1 part chain); on() is false unless w1 = w1i e_i, w2 = w2j e_j (i != j,
    // w1i, w2j +-1) and the general path's constants have the zeros the shortcut takes for granted.
    void load(const Eigen::Vector3d& w1, const Eigen::Vector3d& w2, const Eigen::Vector3d& p, const Eigen::Matrix3d& g0,
              double sign1, double sign2);
    bool on() const { return on_; }
    // The orientation solutions of `axis` (as orientation_solutions_general gives them), or
    // false when the general path must answer (a free joint, a pole, a non-finite axis).
    bool solve(const Eigen::Vector3d& axis, OrientationSolutions& out) const;

private:
    bool on_ = false;
    // n = w1 x w2 = nk e_k (nk +-1), and the general path's constants.
    bool g0_identity = false, free2 = false;
    int i = 0, j = 1, pattern = 0;  // pattern: which of the six (i, j)
    double w1i = 1, w2j = 1, nk = 1;
    double sign1 = 1, sign2 = 1;
    double a = 0, den = -1, w2p = 0, aw2p = 0, psq = 1, nn = 1;
    // den and nn both powers of two (+-1 for coordinate axes at right angles, as pentarod's):
    // a quotient by either is then the product with its exact reciprocal, to the last bit.
    bool exact_inv = false;
    double den_inv = -1, nn_inv = 1;
    double pp2[3] = {};  // p projected off w2
    double g0[9] = {};   // row by row
    double free_sq = 0;  // |v|^2 below this: |v| < kFreeEps
};

}  // namespace xlate5
