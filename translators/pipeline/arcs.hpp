// SPDX-License-Identifier: GPL-3.0-or-later
// G2/G3 -> chords: a pure function of the arc's geometry, called by the resolver, which then
// sends each chord through the planner like any move. May call: nothing but Eigen.
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

namespace xlate5 {

// Full turns an arc's P word may ask for (docs/limits.md); the chords are bounded as well, by
// kMaxPiecesPerLine (constants.hpp).
inline constexpr int kMaxArcTurns = 1000;

// The plane of an arc (RS274): G17 XY, G18 ZX, G19 YZ. Axes a, b span it, n is its normal; ca and
// cb are the centre-offset letters along a and b.
struct ArcPlane {
    int a, b, n;
    char ca, cb;
};
ArcPlane arc_plane(int plane);  // 17, 18 or 19

struct Arc {
    bool clockwise = false;
    int plane = 17;
    Eigen::Vector3d start = Eigen::Vector3d::Zero(), end = Eigen::Vector3d::Zero();  // mm, one frame
    bool by_radius = false;
    double offset_a = 0, offset_b = 0;  // centre from the start, along the plane's axes (I J K)
    double radius = 0;                  // R > 0: the shorter arc, R < 0: the longer
    int turns = 1;                      // P: full turns (1: less than one)
};

// The chord end points of `arc`, each chord within `chord_tolerance` of it, helical along the
// plane's normal; the last point is exactly `arc.end`. Returns an empty string, or why the arc
// cannot be cut (a radius too small, an end point off the circle, turns outside 1..kMaxArcTurns,
// more than kMaxPiecesPerLine chords).
// `max_chords` (0: kMaxPiecesPerLine, never above it) lowers the bound.
std::string arc_chords(const Arc& arc, double chord_tolerance, std::vector<Eigen::Vector3d>& ends, int max_chords = 0);

}  // namespace xlate5
