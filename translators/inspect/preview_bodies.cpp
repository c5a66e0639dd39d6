// SPDX-License-Identifier: GPL-3.0-or-later
// The machine drawn on the preview page: its own collision bodies, else a default from the
// chains, and its build volume. What it may call: see preview.hpp.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "translators/inspect/preview.hpp"

namespace xlate5 {

namespace {

// A pose whose z axis is `dir` (unit), placed at `at`.
std::array<double, 12> pose_along(const Eigen::Vector3d& dir, const Eigen::Vector3d& at) {
    const Eigen::Matrix3d r = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), dir.normalized()).toRotationMatrix();
    return {r(0, 0), r(0, 1), r(0, 2), at.x(), r(1, 0), r(1, 1), r(1, 2), at.y(), r(2, 0), r(2, 1), r(2, 2), at.z()};
}

std::array<double, 12> pose_of(const Eigen::Isometry3d& m) {
    std::array<double, 12> p{};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) p[std::size_t(4 * r + c)] = m(r, c);
    return p;
}

// Vertex clustering (Rossignac and Borrel's): the vertices in one cell of a grid over the mesh's
// box become their mean, and a triangle whose corners fall in fewer than three cells, or repeats
// one kept, goes. The grid is made coarser until the triangles fit `cap`: the outline stays, to
// within a cell, and the page's size is bounded whatever the mesh.
void thin_mesh(PreviewBody& b, std::size_t cap) {
    const std::size_t nv = b.vertices.size() / 3;
    if (b.triangles.size() / 3 <= cap || nv == 0) return;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (std::size_t v = 0; v < nv; ++v)
        for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], b.vertices[3 * v + k]), hi[k] = std::max(hi[k], b.vertices[3 * v + k]);
    const double extent = std::max(1e-9, (hi - lo).maxCoeff());
    for (double cells = std::ceil(std::sqrt(double(cap))); cells >= 1; cells = std::floor(cells * 0.8)) {
        const double cell = extent / cells;
        const auto index = [&](double x, int k) { return std::uint64_t(std::min(cells, std::floor((x - lo[k]) / cell))); };
        std::map<std::uint64_t, std::uint32_t> id;
        std::vector<double> sum;
        std::vector<int> count;
        std::vector<std::uint32_t> of(nv);
        const auto side = std::uint64_t(cells) + 1;
        for (std::size_t v = 0; v < nv; ++v) {
            const double* x = &b.vertices[3 * v];
            const std::uint64_t key = (index(x[0], 0) * side + index(x[1], 1)) * side + index(x[2], 2);
            const auto [it, added] = id.try_emplace(key, std::uint32_t(count.size()));
            if (added) sum.insert(sum.end(), {0.0, 0.0, 0.0}), count.push_back(0);
            of[v] = it->second;
            for (std::size_t k = 0; k < 3; ++k) sum[3 * it->second + k] += x[k];
            ++count[it->second];
        }
        std::set<std::array<std::uint32_t, 3>> seen;
        std::vector<std::uint32_t> triangles;
        for (std::size_t t = 0; t + 2 < b.triangles.size(); t += 3) {
            const std::uint32_t a = of[b.triangles[t]], c = of[b.triangles[t + 1]], d = of[b.triangles[t + 2]];
            if (a == c || c == d || a == d) continue;
            std::array<std::uint32_t, 3> key{a, c, d};
            std::sort(key.begin(), key.end());
            if (!seen.insert(key).second) continue;
            triangles.insert(triangles.end(), {a, c, d});
        }
        if (triangles.size() / 3 > cap && cells > 1) continue;
        for (std::size_t i = 0; i < count.size(); ++i)
            for (std::size_t k = 0; k < 3; ++k) sum[3 * i + k] /= count[i];
        b.vertices = std::move(sum);
        b.triangles = std::move(triangles);
        return;
    }
}

}  // namespace

BuildVolume build_volume(const Machine& m) {
    BuildVolume v;
    const auto scan = [&](const std::vector<ChainElement>& chain, double sign) {
        for (const auto& e : chain) {
            if (e.kind != ChainElement::Kind::Linear) continue;
            const Joint& j = m.joints[std::size_t(e.joint)];
            if (!j.bounded() || j.absent) continue;
            for (int k = 0; k < 3; ++k)
                if (std::abs(std::abs(e.axis[k]) - 1) < 1e-9) {
                    const double s = sign * e.axis[k];
                    v.lo[k] = std::min(s * j.min, s * j.max), v.hi[k] = std::max(s * j.min, s * j.max);
                }
        }
    };
    scan(m.tool_chain, 1);
    scan(m.part_chain, -1);
    return v;
}

std::vector<PreviewBody> default_bodies(const Machine& m) {
    std::vector<PreviewBody> bodies;
    const auto add = [&](std::string name, std::string frame, PreviewBody::Shape shape, std::array<double, 3> size, std::array<double, 12> pose) {
        PreviewBody b;
        b.name = std::move(name), b.frame = std::move(frame), b.shape = shape, b.size = size, b.pose = pose;
        bodies.push_back(std::move(b));
    };
    const BuildVolume v = build_volume(m);
    double bx = v.hi[0] > v.lo[0] ? v.hi[0] - v.lo[0] : 200, by = v.hi[1] > v.lo[1] ? v.hi[1] - v.lo[1] : 200;
    const double cx = v.hi[0] > v.lo[0] ? (v.hi[0] + v.lo[0]) / 2 : 0, cy = v.hi[1] > v.lo[1] ? (v.hi[1] + v.lo[1]) / 2 : 0;
    bool table = false;
    for (const auto& e : m.part_chain) table = table || e.kind == ChainElement::Kind::Rotary;
    if (table) {  // the part on a turning table: a disc under the plate, turning with it
        const double r = std::clamp(0.3 * std::min(bx, by), 30.0, 150.0);
        add("table", "part", PreviewBody::Shape::Cylinder, {r, r, 6}, pose_along(Eigen::Vector3d::UnitZ(), {0, 0, -3}));
    } else {
        add("bed", "part", PreviewBody::Shape::Box, {bx, by, 4}, pose_along(Eigen::Vector3d::UnitZ(), {cx, cy, -2}));
    }
    // Each rotary joint: its axis as a short cylinder through its point, in the frame it turns in.
    const auto axes = [&](const std::vector<ChainElement>& chain, const std::string& side) {
        for (std::size_t i = 0; i < chain.size(); ++i) {
            const auto& e = chain[i];
            if (e.kind != ChainElement::Kind::Rotary) continue;
            const double r = side == "part" ? 12 : 8, len = side == "part" ? 20 : 40;
            add(std::string("joint ") + m.joints[std::size_t(e.joint)].output, side + ":" + std::to_string(i),
                PreviewBody::Shape::Cylinder, {r, r, len}, pose_along(e.axis, e.point));
        }
    };
    axes(m.part_chain, "part");
    axes(m.tool_chain, "tool");
    // The nozzle (its tip at the tool frame's origin) and a holder above it, along the tool axis.
    const Eigen::Vector3d u = m.tool_axis.normalized();
    add("nozzle", "tool", PreviewBody::Shape::Cylinder, {1.5, 1.5, 10}, pose_along(u, 5 * u));
    add("holder", "tool", PreviewBody::Shape::Box, {22, 22, 30}, pose_along(u, 25 * u));
    return bodies;
}

std::vector<PreviewBody> machine_bodies(const Machine& m) {
    std::vector<PreviewBody> out;
    if (!m.geometry) return out;
    std::size_t triangles = 0;
    for (const Body& b : m.geometry->bodies) triangles += b.shape.kind == BodyShape::Kind::Mesh ? b.shape.triangles.size() : 0;
    for (const Body& b : m.geometry->bodies) {
        PreviewBody p;
        p.name = b.name;
        const std::string side = b.tool_side ? "tool" : "part";
        const auto& chain = b.tool_side ? m.tool_chain : m.part_chain;
        // Body::after indexes the chain's elements; the page's frames count them (0: the base).
        p.frame = b.after < 0 ? "tool:0" : b.after == int(chain.size()) - 1 ? side : side + ":" + std::to_string(b.after + 1);
        p.pose = pose_of(b.place);
        const BodyShape& s = b.shape;
        switch (s.kind) {
            case BodyShape::Kind::Box: p.shape = PreviewBody::Shape::Box, p.size = {s.size.x(), s.size.y(), s.size.z()}; break;
            case BodyShape::Kind::Cylinder: p.shape = PreviewBody::Shape::Cylinder, p.size = {s.radius, s.radius, s.length}; break;
            case BodyShape::Kind::Cone: p.shape = PreviewBody::Shape::Cone, p.size = {s.radius, s.radius, s.length}; break;
            case BodyShape::Kind::Capsule: p.shape = PreviewBody::Shape::Capsule, p.size = {s.radius, s.radius, s.length}; break;
            case BodyShape::Kind::Sphere: p.shape = PreviewBody::Shape::Sphere, p.size = {s.radius, s.radius, s.radius}; break;
            case BodyShape::Kind::Mesh: {
                p.shape = PreviewBody::Shape::Mesh;
                Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
                for (const auto& v : s.vertices) {
                    lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
                    p.vertices.insert(p.vertices.end(), {v.x(), v.y(), v.z()});
                }
                p.size = {hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z()};
                for (const auto& t : s.triangles)
                    p.triangles.insert(p.triangles.end(), {std::uint32_t(t[0]), std::uint32_t(t[1]), std::uint32_t(t[2])});
                p.source_triangles = s.triangles.size();
                // Each mesh its share of the cap, by its triangles.
                thin_mesh(p, std::max<std::size_t>(1, kMaxPreviewTriangles * s.triangles.size() / std::max<std::size_t>(1, triangles)));
                break;
            }
        }
        out.push_back(std::move(p));
    }
    return out;
}

}  // namespace xlate5
