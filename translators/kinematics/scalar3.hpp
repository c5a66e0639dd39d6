// SPDX-License-Identifier: GPL-3.0-or-later
// Internal to translators/kinematics/*.cpp (no header includes it): the chain walk's 3-vectors
// and 3x3 matrices in scalars, and the tolerances the orientation paths share. The interface
// speaks Eigen; these write out Eigen's fixed-size products in the same operations and order, so
// to the last bit (a 3x3 matrix times a column sums rows 0 and 1 as (a0 + a1) + a2 and row 2 as
// a0 + (a1 + a2); test_kinematics holds the two against each other), with every value in its own
// variable so that it stays in a register (Eigen's 3-vectors went through memory in
// part-overlapping loads and stores, which stall).
#pragma once
#include <Eigen/Core>
#include <cmath>

#include "translators/constants.hpp"
#include "translators/kinematics/kinematics_types.hpp"

namespace xlate5::kin {

inline constexpr double kDeg = kRadPerDeg;
// A projected vector shorter than this leaves subproblem 1 without an answer: the joint is on
// its singular pole and keeps its previous angle.
inline constexpr double kFreeEps = 1e-7;
// Orientations this close (radians, squared for gamma) to the reachable set count as reachable.
inline constexpr double kReachEps = 1e-6;

struct V3 {
    double x, y, z;
};
struct M3 {
    double xx, xy, xz, yx, yy, yz, zx, zy, zz;  // row, column
};

inline V3 v3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(const V3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }

inline V3 operator*(const M3& m, const V3& v) {
    return {(m.xx * v.x + m.xy * v.y) + m.xz * v.z, (m.yx * v.x + m.yy * v.y) + m.yz * v.z, m.zx * v.x + (m.zy * v.y + m.zz * v.z)};
}

inline M3 operator*(const M3& a, const M3& b) {
    const V3 c0 = a * V3{b.xx, b.yx, b.zx}, c1 = a * V3{b.xy, b.yy, b.zy}, c2 = a * V3{b.xz, b.yz, b.zz};
    return {c0.x, c1.x, c2.x, c0.y, c1.y, c2.y, c0.z, c1.z, c2.z};
}

// A row-by-row array of nine as a matrix.
inline M3 m3(const double* m) { return {m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]}; }

// R^T v, as Eigen sums a transposed product: every row (a0 + a1) + a2.
inline V3 transposed_times(const M3& m, const V3& v) {
    return {(m.xx * v.x + m.yx * v.y) + m.zx * v.z, (m.xy * v.x + m.yy * v.y) + m.zy * v.z, (m.xz * v.x + m.yz * v.y) + m.zz * v.z};
}

// Eigen's normalized(): v / |v|, the squares summed (a0 + a1) + a2; a zero vector is returned as is.
inline V3 normalized(const V3& v) {
    const double n = (v.x * v.x + v.y * v.y) + v.z * v.z;
    if (!(n > 0)) return v;
    const double r = std::sqrt(n);
    return {v.x / r, v.y / r, v.z / r};
}

// atan2(-y, -x) from phi = atan2(y, x), y non-zero: the opposite direction, half a turn away, in
// (-pi, pi] as atan2 gives it (to an ulp of it, not atan2's own bits). Both orientation paths use
// it where a second solution's terms are the first's negated, so they stay the same to the bit.
inline double opposite_angle(double phi) { return phi > 0 ? phi - kPi : phi + kPi; }

// A rotary joint's axis in the base frame (dir unit); only the bound's lever arms use it, so it
// need not match Eigen's rounding (the bound keeps a slack).
struct AxisLine {
    V3 point, dir;
};

// The distance of x from an axis line (measured in the base frame, as forward() and the
// position solve's end measure the lever arms).
inline double distance_from(const V3& x, const AxisLine& line) {
    const V3 d = x - line.point, u = line.dir;
    const V3 off = d - u * (u.x * d.x + u.y * d.y + u.z * d.z);
    return std::sqrt(off.x * off.x + off.y * off.y + off.z * off.z);
}

// The error of a singular Jacobian, out of the solve's way.
[[gnu::noinline, gnu::cold]] inline IkResult singular_jacobian() {
    return {IkStatus::Singular, "the linear axes cannot move the tip in every direction here"};
}

}  // namespace xlate5::kin
