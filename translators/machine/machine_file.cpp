// SPDX-License-Identifier: GPL-3.0-or-later
// Machine TOML file -> Machine. Every error names the file, the line and the key at fault.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <utility>
#include <sstream>
#include <toml++/toml.h>

#include "translators/constants.hpp"
#include "translators/error.hpp"
#include "translators/inputs/expr.hpp"
#include "translators/machine/geometry_loader.hpp"
#include "translators/machine/machine.hpp"
#include "translators/suggest.hpp"
#include "translators/inputs/small_file.hpp"

#ifndef XLATE5_INSTALLED_MACHINE_DIR
#define XLATE5_INSTALLED_MACHINE_DIR ""
#endif

namespace xlate5 {

namespace {


class Reader {
public:
    Reader(std::string path, const toml::table& root) : path_(std::move(path)), root_(root) {}

    [[noreturn]] void fail(const toml::node* node, const std::string& key, const std::string& message) const {
        std::ostringstream os;
        os << path_;
        if (node && node->source().begin.line) os << ":" << node->source().begin.line;
        os << ": " << key << ": " << message;
        throw MachineError(os.str());
    }
    [[noreturn]] void fail(const toml::node_view<const toml::node>& view, const std::string& key,
                           const std::string& message) const {
        fail(view.node(), key, message);
    }

    void only_keys(const toml::table& t, const std::string& where, std::initializer_list<const char*> allowed) const {
        for (auto&& [k, v] : t) {
            bool ok = false;
            for (const char* a : allowed) ok = ok || k.str() == a;
            if (ok) continue;
            const std::string guess = nearest_name(std::string(k.str()), std::vector<std::string>(allowed.begin(), allowed.end()));
            fail(&v, where.empty() ? std::string(k.str()) : where + "." + std::string(k.str()),
                 guess.empty() ? "unknown key" : "unknown key; did you mean '" + guess + "'?");
        }
    }

    // A number, or a string with an expression over [parameters].
    double number(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        if (auto v = node->value<double>()) {
            if (!std::isfinite(*v)) fail(node, key, "not a finite number");
            return *v;
        }
        if (auto s = node->value<std::string>()) {
            try {
                return evaluate_expression(*s, params);
            } catch (const std::invalid_argument& e) {
                fail(node, key, e.what());
            }
        }
        fail(node, key, "expected a number or a parameter expression");
    }

    Eigen::Vector3d vec3(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        const auto* arr = node->as_array();
        if (!arr || arr->size() != 3) fail(node, key, "expected an array of 3 numbers");
        Eigen::Vector3d v;
        for (int i = 0; i < 3; ++i) v[i] = number(arr->get(std::size_t(i)), key + "[" + std::to_string(i) + "]");
        return v;
    }

    Eigen::Vector3d unit(const toml::node* node, const std::string& key) const {
        Eigen::Vector3d v = vec3(node, key);
        if (v.norm() < 1e-9) fail(node, key, "direction has length 0");
        return v.normalized();
    }

    std::string string(const toml::node* node, const std::string& key) const {
        if (!node) fail(nullptr, key, "missing");
        auto s = node->value<std::string>();
        if (!s) fail(node, key, "expected a string");
        return *s;
    }

    char letter(const toml::node* node, const std::string& key) const {
        std::string s = string(node, key);
        if (s.size() != 1 || !std::isalpha(static_cast<unsigned char>(s[0])))
            fail(node, key, "expected one axis letter");
        char c = char(std::toupper(static_cast<unsigned char>(s[0])));
        // Letters that are never G-code words on a move (R is arc radius only on G2/G3).
        if (std::string("XYZABCDUVWR").find(c) == std::string::npos)
            fail(node, key, std::string("letter ") + c + " cannot name an axis (use X Y Z A B C D U V W R)");
        return c;
    }

    const std::string& path() const { return path_; }
    const toml::table& root() const { return root_; }
    std::map<std::string, double> params;

private:
    std::string path_;
    const toml::table& root_;
};

void load_parameters(Reader& r, const std::map<std::string, double>& overrides) {
    if (auto* t = r.root()["parameters"].as_table()) {
        for (auto&& [k, v] : *t) {
            const std::string key = "parameters." + std::string(k.str());
            auto d = v.value<double>();
            if (!d || !std::isfinite(*d)) r.fail(&v, key, "expected a number");
            r.params[std::string(k.str())] = *d;
        }
    }
    for (const auto& [name, value] : overrides) {
        if (!r.params.count(name)) {
            std::vector<std::string> names;
            for (const auto& [n, v] : r.params) names.push_back(n);
            std::string list;
            for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
            const std::string guess = nearest_name(name, names);
            throw MachineError(r.path() + ": --set " + name + ": the machine has no parameter '" + name + "'" +
                               (guess.empty() ? "" : "; did you mean '" + guess + "'?") +
                               (names.empty() ? " (it has no [parameters])" : " (its parameters: " + list + ")"));
        }
        r.params[name] = value;
    }
}

void load_joints(Reader& r, Machine& m) {
    const auto* arr = r.root()["joints"].as_array();
    if (!arr || arr->empty()) r.fail(r.root()["joints"], "joints", "missing: list the machine's joints as [[joints]]");
    for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "joints[" + std::to_string(i) + "]";
        const auto* t = arr->get(i)->as_table();
        if (!t) r.fail(arr->get(i), where, "expected a table");
        r.only_keys(*t, where, {"name", "output", "type", "min", "max", "home", "max_feed", "rezero_beyond", "manual_stepper", "absent"});
        Joint j;
        j.name = r.letter(t->get("name"), where + ".name");
        j.output = t->contains("output") ? r.letter(t->get("output"), where + ".output") : j.name;
        const std::string type = r.string(t->get("type"), where + ".type");
        if (type == "rotary") j.rotary = true;
        else if (type != "linear") r.fail(t->get("type"), where + ".type", "expected \"linear\" or \"rotary\"");
        if (!j.rotary && (j.name == 'A' || j.name == 'B' || j.name == 'C'))
            r.fail(t->get("name"), where + ".name", "A, B and C name rotary joints");
        if (t->contains("min")) j.min = r.number(t->get("min"), where + ".min");
        if (t->contains("max")) j.max = r.number(t->get("max"), where + ".max");
        if (t->contains("min") != t->contains("max")) r.fail(t, where, "give both min and max, or neither");
        if (!j.rotary && !t->contains("min")) r.fail(t, where, "a linear joint needs min and max");
        if (j.min > j.max) r.fail(t->get("min"), where + ".min", "min is greater than max");
        if (t->contains("home")) j.home = r.number(t->get("home"), where + ".home");
        if (j.home < j.min || j.home > j.max) r.fail(t->get("home"), where + ".home", "home is outside min..max");
        if (t->contains("rezero_beyond")) {
            j.rezero_beyond = r.number(t->get("rezero_beyond"), where + ".rezero_beyond");
            if (!j.rotary || j.bounded()) r.fail(t->get("rezero_beyond"), where + ".rezero_beyond", "only an unbounded rotary joint is re-zeroed");
            if (!(j.rezero_beyond >= 180)) r.fail(t->get("rezero_beyond"), where + ".rezero_beyond", "must be at least 180 degrees");
        }
        if (t->contains("max_feed")) {
            j.max_feed = r.number(t->get("max_feed"), where + ".max_feed");
            if (!(j.max_feed > 0)) r.fail(t->get("max_feed"), where + ".max_feed", "must be positive");
        }
        if (const auto* a = t->get("absent")) {
            const auto b = a->value<bool>();
            if (!b) r.fail(a, where + ".absent", "expected true or false");
            j.absent = *b;
            if (j.absent && j.rotary) r.fail(a, where + ".absent", "only a linear joint can be absent (held at its home)");
            if (j.absent && (j.min != j.home || j.max != j.home))
                r.fail(a, where + ".absent", "an absent joint has min = max = home (the value it is held at)");
            if (j.absent) j.min = j.home - kAbsentSlack, j.max = j.home + kAbsentSlack;
        }
        if (t->contains("manual_stepper")) {
            j.manual_stepper = r.string(t->get("manual_stepper"), where + ".manual_stepper");
            // Klipper reads it as a config section's name and a command's word: no blanks.
            bool ok = !j.manual_stepper.empty();
            for (const char c : j.manual_stepper) ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
            if (!ok) r.fail(t->get("manual_stepper"), where + ".manual_stepper", "expected a name of letters, digits and _");
        } else {
            j.manual_stepper = std::string("axis_") + char(std::tolower(static_cast<unsigned char>(j.output)));
        }
        for (const auto& other : m.joints) {
            if (other.name == j.name) r.fail(t->get("name"), where + ".name", std::string("joint ") + j.name + " is defined twice");
            if (other.output == j.output) r.fail(t, where + ".output", std::string("output letter ") + j.output + " is used twice");
        }
        m.joints.push_back(j);
    }
}

std::vector<ChainElement> load_chain(Reader& r, Machine& m, const char* key, std::vector<bool>& used) {
    std::vector<ChainElement> chain;
    const auto node = r.root()[key];
    if (!node) return chain;
    const auto* arr = node.as_array();
    if (!arr) r.fail(node, key, "expected an array of tables ([[" + std::string(key) + "]])");
    for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = std::string(key) + "[" + std::to_string(i) + "]";
        const auto* t = arr->get(i)->as_table();
        if (!t) r.fail(arr->get(i), where, "expected a table");
        ChainElement e;
        if (t->contains("joint")) {
            r.only_keys(*t, where, {"joint", "axis", "point"});
            const char name = r.letter(t->get("joint"), where + ".joint");
            e.joint = m.joint_index(name);
            if (e.joint < 0) r.fail(t->get("joint"), where + ".joint", std::string("no joint named ") + name + " in [[joints]]");
            if (used[std::size_t(e.joint)]) r.fail(t->get("joint"), where + ".joint", std::string("joint ") + name + " appears twice in the chains");
            used[std::size_t(e.joint)] = true;
            const Joint& j = m.joints[std::size_t(e.joint)];
            e.kind = j.rotary ? ChainElement::Kind::Rotary : ChainElement::Kind::Linear;
            e.axis = r.unit(t->get("axis"), where + ".axis");
            if (t->contains("point")) {
                if (!j.rotary) r.fail(t->get("point"), where + ".point", "only a rotary joint has a point");
                e.point = r.vec3(t->get("point"), where + ".point");
            }
        } else {
            r.only_keys(*t, where, {"translate", "rotate"});
            if (!t->contains("translate") && !t->contains("rotate"))
                r.fail(t, where, "a fixed element needs translate and/or rotate (or joint for a joint)");
            e.kind = ChainElement::Kind::Fixed;
            if (const auto* rot = t->get("rotate")) {
                const auto* rt = rot->as_table();
                if (!rt) r.fail(rot, where + ".rotate", "expected { axis = [x, y, z], angle = degrees }");
                r.only_keys(*rt, where + ".rotate", {"axis", "angle"});
                const Eigen::Vector3d axis = r.unit(rt->get("axis"), where + ".rotate.axis");
                const double angle = r.number(rt->get("angle"), where + ".rotate.angle");
                e.fixed.linear() = Eigen::AngleAxisd(angle * kPi / 180.0, axis).toRotationMatrix();
            }
            if (t->contains("translate")) e.fixed.translation() = r.vec3(t->get("translate"), where + ".translate");
        }
        chain.push_back(e);
    }
    return chain;
}

// [[compensation]] terms: joint, by, and either points (+ interpolation, outside) or fourier.
Compensation load_terms(Reader& r, const Machine& m, toml::node_view<const toml::node> node) {
    Compensation c;
    const auto* arr = node.as_array();
    if (!arr) r.fail(node, "compensation", "expected an array of tables ([[compensation]])");
    for (std::size_t i = 0; i < arr->size(); ++i) {
        const std::string where = "compensation[" + std::to_string(i) + "]";
        const auto* t = arr->get(i)->as_table();
        if (!t) r.fail(arr->get(i), where, "expected a table");
        r.only_keys(*t, where, {"joint", "by", "points", "interpolation", "outside", "fourier"});
        CompensationTerm term;
        term.joint = m.joint_index(r.letter(t->get("joint"), where + ".joint"));
        if (term.joint < 0) r.fail(t->get("joint"), where + ".joint", "no such joint");
        term.by = m.joint_index(r.letter(t->get("by"), where + ".by"));
        if (term.by < 0 || !m.joints[std::size_t(term.by)].rotary) r.fail(t->get("by"), where + ".by", "expected a rotary joint");
        if (term.by == term.joint) r.fail(t->get("by"), where + ".by", "a joint cannot compensate itself");
        if (t->contains("points") == t->contains("fourier")) r.fail(t, where, "give points (a measured table) or fourier (a fitted series)");
        if (const auto* pts = t->get("points")) {
            const auto* pa = pts->as_array();
            if (!pa || pa->size() < 2) r.fail(pts, where + ".points", "expected at least two [angle, error] pairs");
            for (std::size_t k = 0; k < pa->size(); ++k) {
                const auto* pair = pa->get(k)->as_array();
                const std::string key = where + ".points[" + std::to_string(k) + "]";
                if (!pair || pair->size() != 2) r.fail(pa->get(k), key, "expected [angle, error]");
                term.angle.push_back(r.number(pair->get(0), key));
                term.error.push_back(r.number(pair->get(1), key));
                if (k > 0 && !(term.angle[k] > term.angle[k - 1])) r.fail(pa->get(k), key, "angles must increase");
            }
            const std::string interp = t->contains("interpolation") ? r.string(t->get("interpolation"), where + ".interpolation") : "linear";
            if (interp == "periodic") term.periodic = true;
            else if (interp != "linear") r.fail(t->get("interpolation"), where + ".interpolation", "expected \"linear\" or \"periodic\"");
            if (term.periodic && term.angle.back() - term.angle.front() >= 360)
                r.fail(pts, where + ".points", "a periodic table spans less than 360 degrees");
            const std::string outside = t->contains("outside") ? r.string(t->get("outside"), where + ".outside") : "refuse";
            if (outside == "clamp") term.clamp = true;
            else if (outside != "refuse") r.fail(t->get("outside"), where + ".outside", "expected \"refuse\" or \"clamp\"");
        } else {
            const auto* f = t->get("fourier")->as_table();
            if (!f) r.fail(t->get("fourier"), where + ".fourier", "expected { a0 = .., cos = [..], sin = [..] }");
            r.only_keys(*f, where + ".fourier", {"a0", "cos", "sin"});
            term.kind = CompensationTerm::Kind::Fourier;
            if (f->contains("a0")) term.a0 = r.number(f->get("a0"), where + ".fourier.a0");
            for (const char* k : {"cos", "sin"}) {
                if (!f->contains(k)) continue;
                const auto* ca = f->get(k)->as_array();
                if (!ca) r.fail(f->get(k), where + ".fourier." + k, "expected an array of numbers");
                for (std::size_t j = 0; j < ca->size(); ++j)
                    (std::string(k) == "cos" ? term.cosines : term.sines).push_back(r.number(ca->get(j), where + ".fourier." + k));
            }
        }
        c.terms.push_back(term);
    }
    // Undo is exact only if no corrected joint is also an input of a term.
    for (const auto& a : c.terms)
        for (const auto& b : c.terms)
            if (a.joint == b.by) r.fail(node, "compensation", std::string("joint ") + m.joints[std::size_t(a.joint)].name + " is both corrected and an input");
    return c;
}

toml::table parse(const std::string& text, const std::string& path) {
    try {
        return toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        std::ostringstream os;
        os << path << ":" << e.source().begin.line << ": " << e.description();
        throw MachineError(os.str());
    }
}

// The two chains, each joint in one of them; three linear joints, at most two rotary.
void load_chains(Reader& r, const toml::table& root, Machine& m) {
    std::vector<bool> used(m.joints.size(), false);
    m.part_chain = load_chain(r, m, "part_chain", used);
    m.tool_chain = load_chain(r, m, "tool_chain", used);
    int linear = 0, rotary = 0;
    for (std::size_t i = 0; i < m.joints.size(); ++i) {
        if (!used[i]) r.fail(r.root()["joints"].as_array()->get(i), "joints[" + std::to_string(i) + "]",
                             std::string("joint ") + m.joints[i].name + " is in neither part_chain nor tool_chain");
        (m.joints[i].rotary ? rotary : linear)++;
    }
    if (linear != 3) r.fail(root.get("joints"), "joints", "exactly three linear joints are needed, found " + std::to_string(linear));
    if (rotary > 2) r.fail(root.get("joints"), "joints", "at most two rotary joints are supported, found " + std::to_string(rotary));
}

// [tool] and [input].
void load_tool_and_input(Reader& r, const toml::table& root, Machine& m) {
    if (const auto* tool = root.get("tool")) {
        const auto* t = tool->as_table();
        if (!t) r.fail(tool, "tool", "expected a table");
        r.only_keys(*t, "tool", {"axis"});
        if (t->contains("axis")) m.tool_axis = r.unit(t->get("axis"), "tool.axis");
    }
    if (const auto* input = root.get("input")) {
        const auto* t = input->as_table();
        if (!t) r.fail(input, "input", "expected a table");
        r.only_keys(*t, "input", {"mode"});
        if (t->contains("mode")) {
            const std::string mode = r.string(t->get("mode"), "input.mode");
            if (mode == "G43.4") m.start_mode = OrientationMode::Angles;
            else if (mode == "G43.5") m.start_mode = OrientationMode::Vector;
            else if (mode == "G49") m.start_mode = OrientationMode::Joints;
            else r.fail(t->get("mode"), "input.mode", "expected \"G43.4\", \"G43.5\" or \"G49\"");
        }
    }
}

// [firmware]: the dialect, the decimals, inverse time and the planner's settings.
void load_firmware(Reader& r, const toml::table& root, Machine& m) {
    if (const auto* fw = root.get("firmware")) {
        const auto* t = fw->as_table();
        if (!t) r.fail(fw, "firmware", "expected a table");
        r.only_keys(*t, "firmware", {"dialect", "linear_decimals", "rotary_decimals", "extrusion_decimals", "inverse_time",
                                         "acceleration", "junction_deviation", "min_segment_time", "planner_blocks"});
        for (const char* k : {"acceleration", "junction_deviation", "min_segment_time", "planner_blocks"}) {
            if (!t->contains(k)) continue;
            const double v = r.number(t->get(k), std::string("firmware.") + k);
            const std::string key = k;
            if (key == "planner_blocks") {
                if (v < 2 || v > 256 || v != std::floor(v)) r.fail(t->get(k), "firmware.planner_blocks", "expected a whole number 2..256");
                m.planner.blocks = int(v);
            } else {
                if (!(v > 0) || v > 1e7) r.fail(t->get(k), std::string("firmware.") + k, "expected a positive number up to 1e7");
                (key == "acceleration" ? m.planner.acceleration : key == "junction_deviation" ? m.planner.junction_deviation : m.planner.min_segment_time) = v;
            }
        }
        if (t->contains("dialect")) {
            const std::string d = r.string(t->get("dialect"), "firmware.dialect");
            if (d == "marlin") m.dialect.firmware = FirmwareDialect::Marlin;
            else if (d == "marlin-articulated") m.dialect.firmware = FirmwareDialect::MarlinArticulated;
            else if (d == "reprap") m.dialect.firmware = FirmwareDialect::RepRap;
            else if (d == "klipper") m.dialect.firmware = FirmwareDialect::Klipper;
            else if (d == "generic") m.dialect.firmware = FirmwareDialect::Generic;
            else r.fail(t->get("dialect"), "firmware.dialect", "expected marlin, marlin-articulated, reprap, klipper or generic");
        }
        for (const char* k : {"linear_decimals", "rotary_decimals", "extrusion_decimals"}) {
            if (!t->contains(k)) continue;
            const double d = r.number(t->get(k), std::string("firmware.") + k);
            if (d < 0 || d > 9 || d != std::floor(d)) r.fail(t->get(k), std::string("firmware.") + k, "expected a whole number 0..9");
            const std::string key = k;
            (key == "linear_decimals" ? m.dialect.linear_decimals
                                      : key == "rotary_decimals" ? m.dialect.rotary_decimals : m.dialect.extrusion_decimals) = int(d);
        }
        if (const auto* it = t->get("inverse_time")) {
            const auto b = it->value<bool>();
            if (!b) r.fail(it, "firmware.inverse_time", "expected true or false");
            m.dialect.inverse_time = *b;
            if (*b && m.dialect.firmware != FirmwareDialect::RepRap)
                r.fail(it, "firmware.inverse_time", "only RepRapFirmware takes G93 inverse-time feeds");
        }
    }
}

// [motion]: the split's tolerances and the rotary feed.
void load_motion(Reader& r, const toml::table& root, Machine& m) {
    if (const auto* mo = root.get("motion")) {
        const auto* t = mo->as_table();
        if (!t) r.fail(mo, "motion", "expected a table");
        r.only_keys(*t, "motion", {"tolerance", "angle_tolerance", "rotary_feed"});
        auto positive = [&](const char* k, double& into) {
            if (!t->contains(k)) return;
            into = r.number(t->get(k), std::string("motion.") + k);
            if (!(into > 0)) r.fail(t->get(k), std::string("motion.") + k, "must be positive");
        };
        positive("tolerance", m.motion.tolerance);
        positive("angle_tolerance", m.motion.angle_tolerance);
        positive("rotary_feed", m.motion.rotary_feed);
    }
}

Machine build(const toml::table& root, const std::string& path, const std::map<std::string, double>& overrides) {
    Reader r(path, root);
    r.only_keys(root, "", {"name", "description", "source", "parameters", "joints", "part_chain", "tool_chain",
                           "tool", "input", "firmware", "motion", "compensation", "bodies", "collision"});
    Machine m;
    m.source_path = path;
    m.name = r.string(root.get("name"), "name");
    if (root.contains("description")) m.description = r.string(root.get("description"), "description");
    if (root.contains("source")) (void)r.string(root.get("source"), "source");
    load_parameters(r, overrides);
    m.parameters = r.params;
    load_joints(r, m);
    load_chains(r, root, m);
    load_tool_and_input(r, root, m);
    load_firmware(r, root, m);
    load_motion(r, root, m);
    if (root.contains("compensation")) {
        m.compensation = load_terms(r, m, std::as_const(root)["compensation"]);
        m.compensation.source = path;
    }
    load_geometry(root, path, r.params, m);
    return m;
}

}  // namespace

std::string read_machine_file(const std::string& path, const std::string& what) {
    try {
        return read_small_file(path, kMaxMachineFileBytes, "a " + what);
    } catch (const IoError&) {
        throw MachineError(path + ": cannot open " + what);
    } catch (const InputError& e) {
        throw MachineError(e.what());
    }
}

void load_compensation_file(const std::string& path, Machine& m) {
    const std::string text = read_machine_file(path, "compensation file");
    toml::table root;
    try {
        root = toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        std::ostringstream os;
        os << path << ":" << e.source().begin.line << ": " << e.description();
        throw MachineError(os.str());
    }
    Reader r(path, root);
    r.params = m.parameters;
    r.only_keys(root, "", {"description", "source", "compensation"});
    if (!root.contains("compensation")) r.fail(nullptr, "compensation", "missing: list the terms as [[compensation]]");
    m.compensation = load_terms(r, m, std::as_const(root)["compensation"]);
    m.compensation.source = path;
}

// First match wins (docs/machines.md, "Where machine files are found"): the user's and the
// system's own files come before the shipped ones, so a copy edited there replaces a bundled one.
std::vector<std::string> machine_search_path() {
    namespace fs = std::filesystem;
    std::vector<std::string> dirs;
    const auto add = [&dirs](const fs::path& dir) {
        const std::string d = dir.lexically_normal().string();
        if (!d.empty() && std::find(dirs.begin(), dirs.end(), d) == dirs.end()) dirs.push_back(d);
    };
    if (const char* env = std::getenv("XLATE5_MACHINES"); env && *env) add(env);
    // XDG base directories: a relative XDG_CONFIG_HOME is invalid and ignored.
    if (const char* xdg = std::getenv("XDG_CONFIG_HOME"); xdg && *xdg == '/')
        add(fs::path(xdg) / "xlate5/machines");
    else if (const char* home = std::getenv("HOME"); home && *home == '/')
        add(fs::path(home) / ".config/xlate5/machines");
    add("/etc/xlate5/machines");
    // The shipped files, found from the executable: PREFIX/bin/xlate5 -> PREFIX/share/xlate5/machines
    // wherever the tree was installed or unpacked (the build tree links that path to machines/).
    std::error_code ec;
    if (const fs::path exe = fs::read_symlink("/proc/self/exe", ec); !ec)
        add(exe.parent_path().parent_path() / "share/xlate5/machines");
    if (*XLATE5_INSTALLED_MACHINE_DIR) add(XLATE5_INSTALLED_MACHINE_DIR);
    return dirs;
}

std::map<std::string, std::string> bundled_machines() {
    std::map<std::string, std::string> found;
    for (const auto& dir : machine_search_path()) {
        std::error_code ec;
        for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
            if (entry.path().extension() != ".toml") continue;
            found.emplace(entry.path().stem().string(), entry.path().string());  // first on the path wins
        }
    }
    return found;
}

Machine load_machine_text(const std::string& toml_text, const std::string& source_name,
                          const std::map<std::string, double>& overrides) {
    return build(parse(toml_text, source_name), source_name, overrides);
}

struct ParsedMachineFile {
    toml::table root;
};

MachineTemplate::MachineTemplate(const std::string& toml_text, const std::string& source_name)
    : parsed_(std::make_shared<const ParsedMachineFile>(ParsedMachineFile{parse(toml_text, source_name)})), source_(source_name) {
    (void)build({});  // a broken file fails here, once, as load_machine_text would
}

Machine MachineTemplate::build(const std::map<std::string, double>& overrides) const {
    return xlate5::build(parsed_->root, source_, overrides);
}

Machine load_machine(const std::string& name_or_path, const std::map<std::string, double>& overrides) {
    std::string path = name_or_path;
    const bool looks_like_path = name_or_path.find('/') != std::string::npos || name_or_path.ends_with(".toml");
    if (!looks_like_path) {
        auto all = bundled_machines();
        auto it = all.find(name_or_path);
        if (it == all.end()) {
            std::string names, dirs;
            std::vector<std::string> known;
            for (const auto& [n, p] : all) names += (names.empty() ? "" : ", ") + n, known.push_back(n);
            for (const auto& d : machine_search_path()) dirs += (dirs.empty() ? "" : ", ") + d;
            const std::string guess = nearest_name(name_or_path, known);
            throw MachineError("no machine named '" + name_or_path + "'" + (guess.empty() ? "" : "; did you mean '" + guess + "'?") +
                               " (found: " + (names.empty() ? "none" : names) + "; looked in " + dirs +
                               "); give a path to a .toml file for your own, or put NAME.toml in one of those directories");
        }
        path = it->second;
    }
    return build(parse(read_machine_file(path), path), path, overrides);
}

}  // namespace xlate5
