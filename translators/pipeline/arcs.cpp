// SPDX-License-Identifier: GPL-3.0-or-later
// The interpreter's arc function (pure): G2/G3 geometry -> chord end points. What it may call: see arcs.hpp.
#include "translators/pipeline/arcs.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "translators/constants.hpp"

namespace xlate5 {

ArcPlane arc_plane(int plane) {
    if (plane == 18) return {2, 0, 1, 'K', 'I'};
    if (plane == 19) return {1, 2, 0, 'J', 'K'};
    return {0, 1, 2, 'I', 'J'};
}

std::string arc_chords(const Arc& arc, double chord_tol, std::vector<Eigen::Vector3d>& ends, int max_chords) {
    ends.clear();
    if (arc.turns < 1 || arc.turns > kMaxArcTurns)
        return "arc turns P must be 1 to " + std::to_string(kMaxArcTurns);
    const ArcPlane pl = arc_plane(arc.plane);
    const int a = pl.a, b = pl.b, n = pl.n;
    const Eigen::Vector3d& start = arc.start;
    const Eigen::Vector3d& end = arc.end;
    const bool clockwise = arc.clockwise;
    const double radius = arc.radius;
    const Eigen::Vector2d s2(start[a], start[b]), e2(end[a], end[b]);
    Eigen::Vector2d c2;
    if (!arc.by_radius) {
        c2 = s2 + Eigen::Vector2d(arc.offset_a, arc.offset_b);
    } else {
        // R > 0: the shorter arc, R < 0: the longer; the centre lies on the chord's bisector.
        const Eigen::Vector2d chord = e2 - s2;
        const double d = chord.norm();
        if (d == 0 || std::abs(radius) < d / 2 - 1e-9) return "arc radius R is too small for the distance to the end point";
        const double h = std::sqrt(std::max(0.0, radius * radius - d * d / 4));
        const Eigen::Vector2d mid = 0.5 * (s2 + e2), left(-chord.y() / d, chord.x() / d);
        // For G2 (clockwise) with R > 0 the centre is on the right of the chord.
        const double side = ((clockwise ? -1.0 : 1.0) * (radius > 0 ? 1.0 : -1.0));
        c2 = mid + side * h * left;
    }
    const double r0 = (s2 - c2).norm(), r1 = (e2 - c2).norm();
    if (!(r0 > 1e-9)) return "arc radius is 0";
    if (std::abs(r0 - r1) > 0.01 + 1e-3 * r0)
        return "the arc's end point is not on its circle (radius " + std::to_string(r0) + " at the start, " + std::to_string(r1) +
               " at the end)";
    const double t0 = std::atan2(s2.y() - c2.y(), s2.x() - c2.x()), t1 = std::atan2(e2.y() - c2.y(), e2.x() - c2.x());
    double sweep = clockwise ? t0 - t1 : t1 - t0;
    while (sweep <= 1e-12) sweep += kTwoPi;  // equal ends: a full circle
    sweep += kTwoPi * (arc.turns - 1);
    const double step = chord_tol < r0 ? 2 * std::acos(1 - chord_tol / r0) : kTwoPi / 4;
    // Counted in double before the cast: many turns of a small tolerance overflow an int.
    const double need = std::ceil(sweep / step);
    const int cap = pieces_bound(max_chords);
    if (!(need <= cap))
        return "the arc needs " + (need < 1e15 ? std::to_string(std::int64_t(need)) : std::string("too many")) +
               " chords to stay within the tolerance, more than " + std::to_string(cap) +
               " (the bound on pieces per input line)";
    const int chords = std::max(1, int(need));
    for (int k = 1; k <= chords; ++k) {
        const double f = double(k) / chords;
        const double th = t0 + (clockwise ? -1.0 : 1.0) * sweep * f;
        Eigen::Vector3d p;
        p[a] = c2.x() + r0 * std::cos(th);
        p[b] = c2.y() + r0 * std::sin(th);
        p[n] = start[n] + (end[n] - start[n]) * f;
        if (k == chords) p[a] = end[a], p[b] = end[b];
        ends.push_back(p);
    }
    return {};
}

}  // namespace xlate5
