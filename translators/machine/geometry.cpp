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

void load_geometry(const toml::table& root, const std::string& path, const std::map<std::string, double>& params, Machine& m) {
    Fields f(path, params);
    auto geometry = std::make_shared<MachineGeometry>();
    if (const auto* node = root.get("collision")) {
        const auto* t = node->as_table();
        if (!t) f.fail(node, "collision", "expected a table");
        f.only_keys(*t, "collision", {"tip_clearance", "bead_width", "bead_height", "filament_diameter", "reroute", "lift"});
        CollisionSettings& s = geometry->settings;
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
    const auto* node = root.get("bodies");
    if (!node) {
        if (root.contains("collision")) f.fail(root.get("collision"), "collision", "there are no [[bodies]] to check");
        return;
    }
    const auto* arr = node->as_array();
    if (!arr) f.fail(node, "bodies", "expected an array of tables ([[bodies]])");
    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "bodies[" + std::to_string(i) + "]";
        const auto* t = arr->get(i)->as_table();
        if (!t) f.fail(arr->get(i), where, "expected a table");
        f.only_keys(*t, where, {"name", "side", "after", "shape", "size", "radius", "length", "mesh", "scale", "translate", "rotate"});
        Body b;
        b.line = int(t->source().begin.line);
        b.name = f.string(t->get("name"), where + ".name");
        if (b.name.empty() || b.name.size() > 40) f.fail(t->get("name"), where + ".name", "expected a name of 1 to 40 characters");
        for (const auto& other : geometry->bodies)
            if (other.name == b.name) f.fail(t->get("name"), where + ".name", "body '" + b.name + "' is defined twice");
        const std::string side = f.string(t->get("side"), where + ".side");
        if (side == "part") b.tool_side = false;
        else if (side != "tool") f.fail(t->get("side"), where + ".side", "expected \"tool\" (carried by the tool chain) or \"part\"");
        const auto& chain = b.tool_side ? m.tool_chain : m.part_chain;
        b.after = int(chain.size()) - 1;  // the chain's end
        if (const auto* a = t->get("after")) {
            const std::string name = f.string(a, where + ".after");
            if (name == "base") {
                b.after = -1;
            } else {
                const int joint = name.size() == 1 ? m.joint_index(char(std::toupper(static_cast<unsigned char>(name[0])))) : -1;
                int at = -1;
                for (std::size_t k = 0; k < chain.size(); ++k)
                    if (joint >= 0 && chain[k].joint == joint) at = int(k);
                if (at < 0)
                    f.fail(a, where + ".after", "expected \"base\" or a joint letter of the " + side + "_chain (no joint '" + name +
                                                    "' there)");
                b.after = at;
            }
        }
        const std::string shape = f.string(t->get("shape"), where + ".shape");
        BodyShape& s = b.shape;
        auto need = [&](std::initializer_list<const char*> keys) {
            for (const char* k : {"size", "radius", "length", "mesh", "scale"}) {
                bool wanted = false;
                for (const char* w : keys) wanted = wanted || std::string(w) == k;
                if (!wanted && t->contains(k))
                    f.fail(t->get(k), where + "." + k, "a " + shape + " has no " + k);
                if (wanted && std::string(k) != "scale" && !t->contains(k))
                    f.fail(t, where, "a " + shape + " needs " + k);
            }
        };
        if (shape == "box") {
            need({"size"});
            s.kind = BodyShape::Kind::Box;
            s.size = f.vec3(t->get("size"), where + ".size");
            for (int k = 0; k < 3; ++k)
                if (!(s.size[k] > 0) || s.size[k] > Fields::kMaxSize) f.fail(t->get("size"), where + ".size", "edges must be positive and at most 10000 mm");
        } else if (shape == "sphere") {
            need({"radius"});
            s.kind = BodyShape::Kind::Sphere;
            s.radius = f.positive(t->get("radius"), where + ".radius");
        } else if (shape == "cylinder" || shape == "cone" || shape == "capsule") {
            need({"radius", "length"});
            s.kind = shape == "cylinder" ? BodyShape::Kind::Cylinder : shape == "cone" ? BodyShape::Kind::Cone : BodyShape::Kind::Capsule;
            s.radius = f.positive(t->get("radius"), where + ".radius");
            s.length = f.positive(t->get("length"), where + ".length");
        } else if (shape == "mesh") {
            need({"mesh", "scale"});
            s.kind = BodyShape::Kind::Mesh;
            const double scale = t->contains("scale") ? f.positive(t->get("scale"), where + ".scale") : 1.0;
            std::filesystem::path file = f.string(t->get("mesh"), where + ".mesh");
            if (file.is_relative()) file = dir / file;
            s.mesh_path = file.lexically_normal().string();
            std::ostringstream at;
            at << path << ":" << t->get("mesh")->source().begin.line << ": " << where << ".mesh";
            load_mesh(s.mesh_path, scale, s, at.str());
        } else {
            const std::string guess = nearest_name(shape, {"box", "cylinder", "cone", "capsule", "sphere", "mesh"});
            f.fail(t->get("shape"), where + ".shape",
                   "expected box, cylinder, cone, capsule, sphere or mesh" + (guess.empty() ? "" : "; did you mean '" + guess + "'?"));
        }
        if (const auto* rot = t->get("rotate")) {
            const auto* rt = rot->as_table();
            if (!rt) f.fail(rot, where + ".rotate", "expected { axis = [x, y, z], angle = degrees }");
            f.only_keys(*rt, where + ".rotate", {"axis", "angle"});
            const Eigen::Vector3d axis = f.vec3(rt->get("axis"), where + ".rotate.axis");
            if (axis.norm() < 1e-9) f.fail(rt->get("axis"), where + ".rotate.axis", "direction has length 0");
            const double angle = f.number(rt->get("angle"), where + ".rotate.angle");
            b.place.linear() = Eigen::AngleAxisd(angle * kPi / 180.0, axis.normalized()).toRotationMatrix();
        }
        if (t->contains("translate")) b.place.translation() = f.vec3(t->get("translate"), where + ".translate");
        // A tool body on the tip's own frame must stay above tip_clearance: below it the nozzle
        // touches what it prints, on purpose. A mesh (a nozzle as drawn) is cut there; a shape
        // has to be placed above it.
        if (b.tool_side && b.after == int(chain.size()) - 1 && s.kind == BodyShape::Kind::Mesh) {
            clip_mesh(s, b.place, m.tool_axis, geometry->settings.tip_clearance);
            if (s.triangles.empty()) f.fail(t, where, "the mesh lies wholly below collision.tip_clearance");
        }
        b.radius = bounding_radius(s, b.place);
        if (b.tool_side && b.after == int(chain.size()) - 1) {
            const double low = lowest_along(s, b.place, m.tool_axis);
            b.low = low;
            if (low < geometry->settings.tip_clearance - 1e-9) {
                std::ostringstream os;
                os << "reaches " << low << " mm along the tool axis from the tip, below collision.tip_clearance ("
                   << geometry->settings.tip_clearance << " mm): start it at tip_clearance or above";
                f.fail(t, where, os.str());
            }
        }
        geometry->bodies.push_back(std::move(b));
    }
    if (geometry->bodies.empty()) return;
    m.geometry = std::move(geometry);
}

}  // namespace xlate5
