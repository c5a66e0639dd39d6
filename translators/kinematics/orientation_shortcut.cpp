// SPDX-License-Identifier: GPL-3.0-or-later
// See orientation_shortcut.hpp.
#include "translators/kinematics/orientation_shortcut.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "translators/kinematics/scalar3.hpp"

namespace xlate5 {

using namespace kin;

void OrientationShortcut::load(const Eigen::Vector3d& w1, const Eigen::Vector3d& w2, const Eigen::Vector3d& p_,
                               const Eigen::Matrix3d& g0_, double s1, double s2) {
    OrientationShortcut& f = *this;
    auto coordinate_axis = [](const Eigen::Vector3d& w) {
        for (int k = 0; k < 3; ++k)
            if (std::abs(w[k]) == 1 && w[(k + 1) % 3] == 0 && w[(k + 2) % 3] == 0) return k;
        return -1;
    };
    f.i = coordinate_axis(w1);
    f.j = coordinate_axis(w2);
    f.on_ = f.i >= 0 && f.j >= 0 && f.i != f.j;
    if (!f.on_) return;
    // The general path's constants, computed as it computes them.
    const Eigen::Vector3d n = w1.cross(w2);
    const Eigen::Vector3d pp2 = p_ - w2 * w2.dot(p_);
    const int k = 3 - f.i - f.j;
    f.pattern = f.i * 2 + (f.j > f.i ? f.j - 1 : f.j);  // (0,1) (0,2) (1,0) (1,2) (2,0) (2,1)
    f.w1i = w1[f.i], f.w2j = w2[f.j], f.nk = n[k];
    f.sign1 = s1, f.sign2 = s2;
    f.a = w1.dot(w2);
    f.den = f.a * f.a - 1.0;
    f.w2p = w2.dot(p_);
    f.aw2p = f.a * f.w2p;
    f.psq = p_.squaredNorm();
    f.nn = n.squaredNorm();
    // x / 2^m and x * 2^-m round the same real number (2^-m exact), so they agree to the bit.
    auto power_of_two = [](double v) {
        int e = 0;
        return std::isfinite(v) && std::abs(std::frexp(v, &e)) == 0.5;
    };
    f.den_inv = 1.0 / f.den, f.nn_inv = 1.0 / f.nn;
    f.exact_inv = power_of_two(f.den) && power_of_two(f.nn) && power_of_two(f.den_inv) && power_of_two(f.nn_inv);
    for (int m = 0; m < 3; ++m) f.pp2[m] = pp2[m];
    f.free2 = pp2.norm() < kFreeEps;
    f.g0_identity = g0_ == Eigen::Matrix3d::Identity();
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) f.g0[r * 3 + c] = g0_(r, c);
    // |v| < kFreeEps as |v|^2 < free_sq: the square root is correctly rounded and so
    // never decreasing, and free_sq is the least double whose root reaches kFreeEps.
    double t = kFreeEps * kFreeEps;
    while (std::sqrt(t) >= kFreeEps) t = std::nextafter(t, 0.0);
    while (std::sqrt(t) < kFreeEps) t = std::nextafter(t, 1.0);
    f.free_sq = t;
    // What the shortcut takes for granted, as the general path computes it: n along k
    // alone, pp2 zero along j.
    f.on_ = n[f.i] == 0 && n[f.j] == 0 && pp2[f.j] == 0;
}

namespace {

// The shortcut's two solutions from their atan2 terms t (y, x of phi1 and phi2, branch 1 then
// branch 2) and the joints' signs.
void both_branches(const double* t, double sign1, double sign2, OrientationSolutions& out) {
    // The second tilt from the first when its terms are the first's with y negated (as in the
    // general path, chain.cpp).
    const double phi1 = std::atan2(t[0], t[1]), phi2 = std::atan2(t[2], t[3]);
    // (t[0] is not zero here.)
    const double phi1b = t[4] == -t[0] && t[5] == -t[1] ? opposite_angle(phi1) : std::atan2(t[4], t[5]);
    const bool odd = t[7] == t[3] && std::signbit(t[7]) == std::signbit(t[3]) && -t[6] == t[2] && std::signbit(t[6]) != std::signbit(t[2]);
    const double phi2b = odd ? -phi2 : std::atan2(t[6], t[7]);
    out.angle[0][0] = sign1 * phi1 / kDeg;
    out.angle[0][1] = sign2 * phi2 / kDeg;
    out.angle[1][0] = sign1 * phi1b / kDeg;
    out.angle[1][1] = sign2 * phi2b / kDeg;
    out.count = 2;
    out.has_terms = true;
    // (The angle is sign * atan2(y, x), so atan2(sign * y, x): the sign is +-1.)
    for (int b = 0; b < 2; ++b)
        for (int r = 0; r < 2; ++r) out.terms[b][r][0] = (r == 0 ? sign1 : sign2) * t[4 * b + 2 * r], out.terms[b][r][1] = t[4 * b + 2 * r + 1];
}

}  // namespace

bool OrientationShortcut::solve(const Eigen::Vector3d& axis, OrientationSolutions& out) const {
    if (!on_) return false;
    // The general path (chain.cpp) with the rotary axes +-1 times coordinate axes i and j (see
    // the class): every product with one of their zero entries is left out, and with it every
    // term that is zero for any finite input (a projection's component along the axis it is
    // projected off). A sum that keeps one non-zero term is then that term to the last bit; only
    // a sum of zeros could differ, in the sign of its zero, and a zero's sign changes nothing but
    // other zeros' signs here (no division by a value that can be zero) until an atan2 takes it
    // as y (x's sign matters only when y is zero). So where an atan2's y comes out zero, a joint
    // is free, the input is not a finite non-zero vector or the axis is on a pole (one solution),
    // all rare, the general path answers instead.
    const OrientationShortcut& f = *this;
    const double x = axis.x(), y = axis.y(), z = axis.z();
    const double sq = (x * x + y * y) + z * z;  // axis.normalized()
    if (!(sq > 0 && sq <= std::numeric_limits<double>::max())) return false;
    const double r = std::sqrt(sq);
    double u[3] = {x / r, y / r, z / r};
    if (!f.g0_identity) {  // u = g0^T v; with g0 the identity, each row's one term 1 * v
        const V3 t = transposed_times(M3{f.g0[0], f.g0[1], f.g0[2], f.g0[3], f.g0[4], f.g0[5], f.g0[6], f.g0[7], f.g0[8]}, V3{u[0], u[1], u[2]});
        u[0] = t.x, u[1] = t.y, u[2] = t.z;
    }
    // The atan2 terms (y, x) of each branch's phi1 and phi2: t[0..3] branch 1, t[4..7] branch 2;
    // false where the general path must answer.
    double t[8] = {};  // (set before every use: the zeros only tell the compiler so)
    int status = 0;  // 0: both branches, 1: unreachable, 2: the general path
    auto terms = [&](auto ci, auto cj) {
        constexpr int i = decltype(ci)::value, j = decltype(cj)::value, k = 3 - i - j;
        constexpr int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
        const double w1u = f.w1i * u[i];  // w1 . u
        const double na = f.aw2p - w1u, nb = f.a * w1u - f.w2p;
        double alpha, beta, gamma2;
        if (f.exact_inv) {  // the quotients below as products, to the bit (see OrientShortcut)
            alpha = na * f.den_inv, beta = nb * f.den_inv;
            gamma2 = (f.psq - alpha * alpha - beta * beta - 2.0 * alpha * beta * f.a) * f.nn_inv;
        } else {
            alpha = na / f.den, beta = nb / f.den;
            gamma2 = (f.psq - alpha * alpha - beta * beta - 2.0 * alpha * beta * f.a) / f.nn;
        }
        if (gamma2 < -kReachEps * kReachEps) return void(status = 1);
        const double gamma = std::sqrt(std::max(gamma2, 0.0));
        if (gamma == 0.0) return void(status = 2);
        // c = alpha w1 + beta w2 + s gamma n: one term per component.
        const double ci_ = alpha * f.w1i, cj_ = beta * f.w2j, ck = gamma * f.nk, ck2 = (-1.0 * gamma) * f.nk;
        // Subproblem 1 about w2 takes p to c: p projected off w2 is the constant pp2 (zero along
        // j), c's projection is c less its j component. About w1, c to u: c and u less their i
        // components.
        const double q2 = ci_ * ci_ + ck * ck, q2b = ci_ * ci_ + ck2 * ck2;
        const double p1 = cj_ * cj_ + ck * ck, p1b = cj_ * cj_ + ck2 * ck2;
        const double q1 = u[j] * u[j] + u[k] * u[k];
        if (f.free2 || !(std::min(std::min(q2, q2b), std::min(std::min(p1, p1b), q1)) >= f.free_sq)) return void(status = 2);
        for (int b = 0; b < 2; ++b) {
            double c[3];
            c[i] = ci_, c[j] = cj_, c[k] = b == 0 ? ck : ck2;
            t[4 * b + 0] = f.w1i * (c[i1] * u[i2] - c[i2] * u[i1]);
            t[4 * b + 1] = c[i1] * u[i1] + c[i2] * u[i2];
            t[4 * b + 2] = f.w2j * (f.pp2[j1] * c[j2] - f.pp2[j2] * c[j1]);
            t[4 * b + 3] = f.pp2[j1] * c[j1] + f.pp2[j2] * c[j2];
        }
        if (t[0] == 0 || t[2] == 0 || t[4] == 0 || t[6] == 0) status = 2;
    };
    using std::integral_constant;
    switch (f.pattern) {
        case 0: terms(integral_constant<int, 0>{}, integral_constant<int, 1>{}); break;
        case 1: terms(integral_constant<int, 0>{}, integral_constant<int, 2>{}); break;
        case 2: terms(integral_constant<int, 1>{}, integral_constant<int, 0>{}); break;
        case 3: terms(integral_constant<int, 1>{}, integral_constant<int, 2>{}); break;
        case 4: terms(integral_constant<int, 2>{}, integral_constant<int, 0>{}); break;
        default: terms(integral_constant<int, 2>{}, integral_constant<int, 1>{}); break;
    }
    if (status == 2) return false;
    out.axis = axis;
    out.count = 0;
    if (status == 1) return true;  // out of reach
    both_branches(t, f.sign1, f.sign2, out);
    return true;
}

}  // namespace xlate5
