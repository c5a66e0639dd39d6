// SPDX-License-Identifier: GPL-3.0-or-later
// The machine's solid parts as data, for the collision stage (pipeline/collide.hpp): bodies
// attached to a frame of a kinematic chain, their shapes, and the collision settings. Read from
// the machine file's [[bodies]] and [collision] (docs/machines.md, "Bodies"). Data only here;
// the loader is geometry.cpp, called by machine_file.cpp. May call: expr, assimp (meshes).
#pragma once
#include <Eigen/Geometry>

#include <array>
#include <map>
#include <string>
#include <vector>

namespace xlate5 {

struct BodyShape {
    enum class Kind { Box, Cylinder, Cone, Capsule, Sphere, Mesh } kind = Kind::Box;
    Eigen::Vector3d size = Eigen::Vector3d::Zero();  // box: full edge lengths
    double radius = 0;   // cylinder, cone (its base), capsule, sphere
    double length = 0;   // cylinder, cone: height; capsule: between its two sphere centres
    // Mesh: triangles (vertex indices) over vertices, in the body's frame (scale applied).
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    std::string mesh_path;
};

struct Body {
    std::string name;
    bool tool_side = true;  // carried by the tool chain (else by the part chain)
    // The frame it rides on: the chain's frame after element `after` (0-based index into the
    // side's chain); -1: the machine's base (nothing moves it); the chain's size - 1: its end
    // (the tip's frame, or the build plate's).
    int after = -1;
    Eigen::Isometry3d place = Eigen::Isometry3d::Identity();  // the shape's frame in that frame
    BodyShape shape;
    double radius = 0;  // of the sphere about the shape frame's origin that holds the shape
    int line = 0;       // in the machine file, for messages
    // A tool body on the tip's frame: its lowest point along the tool axis from the tip (mm,
    // at least tip_clearance); what lies wholly below that cannot meet it.
    double low = -1e300;
};

struct CollisionSettings {
    // mm above the tip (along the tool axis) below which the nozzle may touch what it prints:
    // tool bodies rigid with the tip must lie above it (the loader checks).
    double tip_clearance = 0.5;
    // Bead of the printed part when E does not give its width: width and layer height, mm.
    double bead_width = 0.45;
    double bead_height = 0.2;
    double filament_diameter = 1.75;  // mm: E (mm of filament) -> bead width
    // A travel (a piece without E) that would collide is re-routed: lifted `lift` mm along the
    // tool axis (then twice and four times that, if need be), travelled, lowered (docs/machines.md).
    bool reroute = true;
    double lift = 10;
};

struct MachineGeometry {
    std::vector<Body> bodies;
    CollisionSettings settings;
    bool has_tool_bodies() const {
        for (const auto& b : bodies)
            if (b.tool_side) return true;
        return false;
    }
};

// The largest mesh read (docs/limits.md): triangles per mesh file.
inline constexpr std::size_t kMaxMeshTriangles = 1u << 20;

// Reads a triangle mesh (STL, OBJ: whatever assimp reads) into `shape`, scaled. Throws
// MachineError naming `where`.
void load_mesh(const std::string& file, double scale, BodyShape& shape, const std::string& where);

}  // namespace xlate5
