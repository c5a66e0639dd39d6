// SPDX-License-Identifier: GPL-3.0-or-later
// [[bodies]] and [collision] of a machine file -> MachineGeometry; meshes through assimp.
#include "translators/machine/geometry.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <filesystem>
#include <sstream>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/inputs/expr.hpp"
#include "translators/machine/geometry_loader.hpp"
#include "translators/suggest.hpp"

namespace xlate5 {

namespace {

class Fields {
public:
    Fields(const std::string& path, const std::map<std::string, double>& params) : path_(path), params_(params) {}

    [[noreturn]] void fail(const toml::node* node, const std::string& key, const std::string& message) const {
        std::ostringstream os;
        os << path_;
        if (node && node->source().begin.line) os << ":" << node->source().begin.line;
        os << ": " << key << ": " << message;
        throw MachineError(os.str());
    }
    void only_keys(const toml::table& t, const std::string& where, const std::vector<std::string>& allowed) const {
        for (auto&& [k, v] : t) {
            const std::string key(k.str());
            if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
            const std::string guess = nearest_name(key, allowed);
            fail(&v, where + "." + key, guess.empty() ? "unknown key" : "unknown key; did you mean '" + guess + "'?");
        }
    }
    double number(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        if (auto v = node->value<double>()) {
            if (!std::isfinite(*v)) fail(node, key, "not a finite number");
            return *v;
        }
        if (auto s = node->value<std::string>()) {
            try {
                return evaluate_expression(*s, params_);
            } catch (const std::invalid_argument& e) {
                fail(node, key, e.what());
            }
        }
        fail(node, key, "expected a number or a parameter expression");
    }
    double positive(const toml::node* node, const std::string& key) const {
        const double v = number(node, key);
        if (!(v > 0)) fail(node, key, "must be positive");
        if (v > kMaxSize) fail(node, key, "larger than " + std::to_string(int(kMaxSize)) + " mm: not a machine part");
        return v;
    }
    Eigen::Vector3d vec3(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        const auto* arr = node->as_array();
        if (!arr || arr->size() != 3) fail(node, key, "expected an array of 3 numbers");
        Eigen::Vector3d v;
        for (int i = 0; i < 3; ++i) v[i] = number(arr->get(std::size_t(i)), key + "[" + std::to_string(i) + "]");
        return v;
    }
    std::string string(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        auto s = node->value<std::string>();
        if (!s) fail(node, key, "expected a string");
        return *s;
    }
    static constexpr double kMaxSize = 10000;  // mm

private:
    const std::string& path_;
    const std::map<std::string, double>& params_;
};

// The radius of the sphere about the shape frame's origin holding the shape, after `place`.
double bounding_radius(const BodyShape& s, const Eigen::Isometry3d& place) {
    const Eigen::Vector3d o = place.translation();
    switch (s.kind) {
        case BodyShape::Kind::Box: return o.norm() + 0.5 * s.size.norm();
        case BodyShape::Kind::Sphere: return o.norm() + s.radius;
        case BodyShape::Kind::Capsule: return o.norm() + 0.5 * s.length + s.radius;
        case BodyShape::Kind::Cylinder:
        case BodyShape::Kind::Cone: return o.norm() + std::hypot(0.5 * s.length, s.radius);
        case BodyShape::Kind::Mesh: {
            double r = 0;
            for (const auto& v : s.vertices) r = std::max(r, (place * v).norm());
            return r;
        }
    }
    return 0;
}

// The lowest point of the placed shape along `axis` (a unit vector), from its vertices or its
// extent: for the tip_clearance check.
double lowest_along(const BodyShape& s, const Eigen::Isometry3d& place, const Eigen::Vector3d& axis) {
    const Eigen::Vector3d a = place.linear().transpose() * axis;  // the axis in the shape's frame
    const double o = place.translation().dot(axis);
    switch (s.kind) {
        case BodyShape::Kind::Box: return o - 0.5 * (std::abs(a.x()) * s.size.x() + std::abs(a.y()) * s.size.y() + std::abs(a.z()) * s.size.z());
        case BodyShape::Kind::Sphere: return o - s.radius;
        case BodyShape::Kind::Capsule: return o - 0.5 * s.length * std::abs(a.z()) - s.radius;
        case BodyShape::Kind::Cylinder:
        case BodyShape::Kind::Cone: {
            // Cylinder: either cap's rim; cone (FCL's: base at -length/2, apex at +length/2):
            // its base rim or its apex.
            const double rim = s.radius * std::sqrt(std::max(0.0, 1 - a.z() * a.z()));
            const double base = o - 0.5 * s.length * a.z() - rim;
            const double top = s.kind == BodyShape::Kind::Cone ? o + 0.5 * s.length * a.z() : o + 0.5 * s.length * a.z() - rim;
            return std::min(base, top);
        }
        case BodyShape::Kind::Mesh: {
            double low = 1e300;
            for (const auto& v : s.vertices) low = std::min(low, (place * v).dot(axis));
            return low;
        }
    }
    return 0;
}

// Keeps the part of a mesh at or above `level` along `axis` (in the placed frame): every triangle
// clipped by that plane (Sutherland-Hodgman against one plane: a triangle becomes none, one or two).
void clip_mesh(BodyShape& s, const Eigen::Isometry3d& place, const Eigen::Vector3d& axis, double level) {
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    const Eigen::Vector3d a = place.linear().transpose() * axis;
    const double o = level - place.translation().dot(axis);  // the plane in the shape's frame: a.v >= o
    for (const auto& t : s.triangles) {
        std::vector<Eigen::Vector3d> poly;
        for (int k = 0; k < 3; ++k) {
            const Eigen::Vector3d& p = s.vertices[std::size_t(t[k])];
            const Eigen::Vector3d& q = s.vertices[std::size_t(t[(k + 1) % 3])];
            const double dp = a.dot(p) - o, dq = a.dot(q) - o;
            if (dp >= 0) poly.push_back(p);
            if ((dp >= 0) != (dq >= 0)) poly.push_back(p + (q - p) * (dp / (dp - dq)));
        }
        if (poly.size() < 3) continue;
        const int base = int(vertices.size());
        vertices.insert(vertices.end(), poly.begin(), poly.end());
        for (std::size_t k = 1; k + 1 < poly.size(); ++k) triangles.push_back({base, base + int(k), base + int(k) + 1});
    }
    s.vertices = std::move(vertices);
    s.triangles = std::move(triangles);
}

}  // namespace

void load_mesh(const std::string& file, double scale, BodyShape& shape, const std::string& where) {
    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(file, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
    if (!scene || !scene->mRootNode) {
        const std::string why = importer.GetErrorString();
        throw MachineError(where + ": cannot read the mesh '" + file + "'" + (why.empty() ? "" : ": " + why));
    }
    shape.vertices.clear();
    shape.triangles.clear();
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh* mesh = scene->mMeshes[mi];
        const int base = int(shape.vertices.size());
        for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
            const aiVector3D& p = mesh->mVertices[v];
            const Eigen::Vector3d x(p.x * scale, p.y * scale, p.z * scale);
            if (!x.allFinite()) throw MachineError(where + ": the mesh '" + file + "' has a vertex that is not a finite number");
            shape.vertices.push_back(x);
        }
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace& face = mesh->mFaces[f];
            if (face.mNumIndices != 3) continue;  // points and lines left by the triangulation
            shape.triangles.push_back({base + int(face.mIndices[0]), base + int(face.mIndices[1]), base + int(face.mIndices[2])});
            if (shape.triangles.size() > kMaxMeshTriangles)
                throw MachineError(where + ": the mesh '" + file + "' has more than " + std::to_string(kMaxMeshTriangles) +
                                   " triangles (docs/limits.md): simplify it");
        }
    }
    if (shape.triangles.empty()) throw MachineError(where + ": the mesh '" + file + "' has no triangles");
}

namespace {

void read_collision_settings(const Fields& f, const toml::node* node, CollisionSettings& s) {
    const auto* t = node->as_table();
    if (!t) f.fail(node, "collision", "expected a table");
    f.only_keys(*t, "collision", {"tip_clearance", "bead_width", "bead_height", "filament_diameter", "reroute", "lift"});
    if (t->contains("tip_clearance")) {
        s.tip_clearance = f.number(t->get("tip_clearance"), "collision.tip_clearance");
        if (!(s.tip_clearance >= 0) || s.tip_clearance > 50)
            f.fail(t->get("tip_clearance"), "collision.tip_clearance", "expected 0 to 50 mm");
    }
    if (t->contains("bead_width")) s.bead_width = f.positive(t->get("bead_width"), "collision.bead_width");
    if (t->contains("bead_height")) s.bead_height = f.positive(t->get("bead_height"), "collision.bead_height");
    if (t->contains("filament_diameter")) s.filament_diameter = f.positive(t->get("filament_diameter"), "collision.filament_diameter");
    if (const auto* r = t->get("reroute")) {
        const auto v = r->value<bool>();
        if (!v) f.fail(r, "collision.reroute", "expected true or false");
        s.reroute = *v;
    }
    if (t->contains("lift")) {
        s.lift = f.positive(t->get("lift"), "collision.lift");
        if (s.lift > 500) f.fail(t->get("lift"), "collision.lift", "expected at most 500 mm");
    }
}

// One [[bodies]] table being read: the checks of each part name the table and its keys.
struct BodyTable {
    const Fields& f;
    const toml::table& t;
    const std::string& where;
};

// Its side and the chain frame it rides on (`after`): a joint letter of that chain, or "base".
void read_frame(const BodyTable& in, const Machine& m, Body& b) {
    const Fields& f = in.f;
    const std::string& where = in.where;
    const std::string side = f.string(in.t.get("side"), where + ".side");
    if (side == "part") b.tool_side = false;
    else if (side != "tool") f.fail(in.t.get("side"), where + ".side", "expected \"tool\" (carried by the tool chain) or \"part\"");
    const auto& chain = b.tool_side ? m.tool_chain : m.part_chain;
    b.after = int(chain.size()) - 1;  // the chain's end
    const auto* a = in.t.get("after");
    if (!a) return;
    const std::string name = f.string(a, where + ".after");
    if (name == "base") {
        b.after = -1;
        return;
    }
    const int joint = name.size() == 1 ? m.joint_index(char(std::toupper(static_cast<unsigned char>(name[0])))) : -1;
    int at = -1;
    for (std::size_t k = 0; k < chain.size(); ++k)
        if (joint >= 0 && chain[k].joint == joint) at = int(k);
    if (at < 0)
        f.fail(a, where + ".after", "expected \"base\" or a joint letter of the " + side + "_chain (no joint '" + name + "' there)");
    b.after = at;
}

// The shape's keys: those `keys` names are required (scale optional), the other shapes' refused.
void need_keys(const BodyTable& in, const std::string& shape, std::initializer_list<const char*> keys) {
    for (const char* k : {"size", "radius", "length", "mesh", "scale"}) {
        bool wanted = false;
        for (const char* w : keys) wanted = wanted || std::string(w) == k;
        if (!wanted && in.t.contains(k)) in.f.fail(in.t.get(k), in.where + "." + k, "a " + shape + " has no " + k);
        if (wanted && std::string(k) != "scale" && !in.t.contains(k)) in.f.fail(&in.t, in.where, "a " + shape + " needs " + k);
    }
}

void read_box(const BodyTable& in, BodyShape& s) {
    need_keys(in, "box", {"size"});
    s.kind = BodyShape::Kind::Box;
    s.size = in.f.vec3(in.t.get("size"), in.where + ".size");
    for (int k = 0; k < 3; ++k)
        if (!(s.size[k] > 0) || s.size[k] > Fields::kMaxSize)
            in.f.fail(in.t.get("size"), in.where + ".size", "edges must be positive and at most 10000 mm");
}

// A cylinder, cone or capsule: a radius and a length.
void read_round(const BodyTable& in, const std::string& shape, BodyShape& s) {
    need_keys(in, shape, {"radius", "length"});
    s.kind = shape == "cylinder" ? BodyShape::Kind::Cylinder : shape == "cone" ? BodyShape::Kind::Cone : BodyShape::Kind::Capsule;
    s.radius = in.f.positive(in.t.get("radius"), in.where + ".radius");
    s.length = in.f.positive(in.t.get("length"), in.where + ".length");
}

// A mesh file, relative to the machine file's directory, scaled.
void read_mesh(const BodyTable& in, const std::string& path, BodyShape& s) {
    need_keys(in, "mesh", {"mesh", "scale"});
    s.kind = BodyShape::Kind::Mesh;
    const double scale = in.t.contains("scale") ? in.f.positive(in.t.get("scale"), in.where + ".scale") : 1.0;
    std::filesystem::path file = in.f.string(in.t.get("mesh"), in.where + ".mesh");
    if (file.is_relative()) file = std::filesystem::path(path).parent_path() / file;
    s.mesh_path = file.lexically_normal().string();
    std::ostringstream at;
    at << path << ":" << in.t.get("mesh")->source().begin.line << ": " << in.where << ".mesh";
    load_mesh(s.mesh_path, scale, s, at.str());
}

void read_shape(const BodyTable& in, const std::string& path, BodyShape& s) {
    const std::string shape = in.f.string(in.t.get("shape"), in.where + ".shape");
    if (shape == "box") {
        read_box(in, s);
    } else if (shape == "sphere") {
        need_keys(in, shape, {"radius"});
        s.kind = BodyShape::Kind::Sphere;
        s.radius = in.f.positive(in.t.get("radius"), in.where + ".radius");
    } else if (shape == "cylinder" || shape == "cone" || shape == "capsule") {
        read_round(in, shape, s);
    } else if (shape == "mesh") {
        read_mesh(in, path, s);
    } else {
        const std::string guess = nearest_name(shape, {"box", "cylinder", "cone", "capsule", "sphere", "mesh"});
        in.f.fail(in.t.get("shape"), in.where + ".shape",
                  "expected box, cylinder, cone, capsule, sphere or mesh" + (guess.empty() ? "" : "; did you mean '" + guess + "'?"));
    }
}

// The shape's place in its frame: rotate = { axis, angle }, then translate.
void read_place(const BodyTable& in, Eigen::Isometry3d& place) {
    const Fields& f = in.f;
    const std::string& where = in.where;
    if (const auto* rot = in.t.get("rotate")) {
        const auto* rt = rot->as_table();
        if (!rt) f.fail(rot, where + ".rotate", "expected { axis = [x, y, z], angle = degrees }");
        f.only_keys(*rt, where + ".rotate", {"axis", "angle"});
        const Eigen::Vector3d axis = f.vec3(rt->get("axis"), where + ".rotate.axis");
        if (axis.norm() < 1e-9) f.fail(rt->get("axis"), where + ".rotate.axis", "direction has length 0");
        const double angle = f.number(rt->get("angle"), where + ".rotate.angle");
        place.linear() = Eigen::AngleAxisd(angle * kPi / 180.0, axis.normalized()).toRotationMatrix();
    }
    if (in.t.contains("translate")) place.translation() = f.vec3(in.t.get("translate"), where + ".translate");
}

// A tool body on the tip's own frame must stay above tip_clearance: below it the nozzle touches
// what it prints, on purpose. A mesh (a nozzle as drawn) is cut there; a shape has to be placed
// above it. Sets the body's radius and, for such a body, its lowest point.
void bound_body(const BodyTable& in, const Machine& m, const CollisionSettings& settings, Body& b) {
    const auto& chain = b.tool_side ? m.tool_chain : m.part_chain;
    const bool on_tip = b.tool_side && b.after == int(chain.size()) - 1;
    BodyShape& s = b.shape;
    if (on_tip && s.kind == BodyShape::Kind::Mesh) {
        clip_mesh(s, b.place, m.tool_axis, settings.tip_clearance);
        if (s.triangles.empty()) in.f.fail(&in.t, in.where, "the mesh lies wholly below collision.tip_clearance");
    }
    b.radius = bounding_radius(s, b.place);
    if (!on_tip) return;
    const double low = lowest_along(s, b.place, m.tool_axis);
    b.low = low;
    if (low < settings.tip_clearance - 1e-9) {
        std::ostringstream os;
        os << "reaches " << low << " mm along the tool axis from the tip, below collision.tip_clearance (" << settings.tip_clearance
           << " mm): start it at tip_clearance or above";
        in.f.fail(&in.t, in.where, os.str());
    }
}

Body read_body(const BodyTable& in, const std::string& path, const Machine& m, const MachineGeometry& geometry) {
    const Fields& f = in.f;
    const std::string& where = in.where;
    f.only_keys(in.t, where, {"name", "side", "after", "shape", "size", "radius", "length", "mesh", "scale", "translate", "rotate"});
    Body b;
    b.line = int(in.t.source().begin.line);
    b.name = f.string(in.t.get("name"), where + ".name");
    if (b.name.empty() || b.name.size() > 40) f.fail(in.t.get("name"), where + ".name", "expected a name of 1 to 40 characters");
    for (const auto& other : geometry.bodies)
        if (other.name == b.name) f.fail(in.t.get("name"), where + ".name", "body '" + b.name + "' is defined twice");
    read_frame(in, m, b);
    read_shape(in, path, b.shape);
    read_place(in, b.place);
    bound_body(in, m, geometry.settings, b);
    return b;
}

}  // namespace

void load_geometry(const toml::table& root, const std::string& path, const std::map<std::string, double>& params, Machine& m) {
    Fields f(path, params);
    auto geometry = std::make_shared<MachineGeometry>();
    if (const auto* node = root.get("collision")) read_collision_settings(f, node, geometry->settings);
    const auto* node = root.get("bodies");
    if (!node) {
        if (root.contains("collision")) f.fail(root.get("collision"), "collision", "there are no [[bodies]] to check");
        return;
    }
    const auto* arr = node->as_array();
    if (!arr) f.fail(node, "bodies", "expected an array of tables ([[bodies]])");
    for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "bodies[" + std::to_string(i) + "]";
        const auto* t = arr->get(i)->as_table();
        if (!t) f.fail(arr->get(i), where, "expected a table");
        geometry->bodies.push_back(read_body({f, *t, where}, path, m, *geometry));
    }
    if (geometry->bodies.empty()) return;
    m.geometry = std::move(geometry);
}

}  // namespace xlate5
