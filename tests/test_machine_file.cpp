// SPDX-License-Identifier: GPL-3.0-or-later
// Machine files: every error names the file, the line and the key; parameters and overrides.
#include <doctest/doctest.h>

#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "helpers.hpp"
#include "translators/error.hpp"
#include "translators/inputs/expr.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"

using namespace xlate5;
using xlate5::test::read;

namespace {

bool contains(const std::string& hay, const std::string& needle) { return hay.find(needle) != std::string::npos; }

// A small valid machine; `extra` is appended, `replace` swaps one line.
std::string base_text() {
    return R"(name = "t"
[parameters]
off = 5
[[joints]]
name = "X"
type = "linear"
min = -100
max = 100
[[joints]]
name = "Y"
type = "linear"
min = -100
max = 100
[[joints]]
name = "Z"
type = "linear"
min = -100
max = 100
[[joints]]
name = "B"
type = "rotary"
min = -90
max = 90
[[tool_chain]]
joint = "X"
axis = [1, 0, 0]
[[tool_chain]]
joint = "Y"
axis = [0, 1, 0]
[[tool_chain]]
joint = "Z"
axis = [0, 0, 1]
[[tool_chain]]
joint = "B"
axis = [0, 1, 0]
point = [0, 0, "off * 2"]
)";
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    REQUIRE(at != std::string::npos);
    return text.replace(at, from.size(), to);
}

// The error message of loading `text`, which must fail.
std::string error_of(const std::string& text, const std::map<std::string, double>& overrides = {}) {
    try {
        load_machine_text(text, "mine.toml", overrides);
    } catch (const MachineError& e) {
        return e.what();
    }
    FAIL("no error");
    return {};
}

}  // namespace

TEST_CASE("a valid file loads with expressions over parameters") {
    const Machine m = load_machine_text(base_text(), "mine.toml");
    CHECK(m.name == "t");
    CHECK(m.joints.size() == 4);
    CHECK(m.tool_chain[3].point.z() == 10);
    const Machine m2 = load_machine_text(base_text(), "mine.toml", {{"off", 7}});
    CHECK(m2.tool_chain[3].point.z() == 14);
}

TEST_CASE("errors name file, line and key") {
    struct Case {
        std::string text, expect;
    };
    const Case cases[] = {
        {replace(base_text(), "min = -100\nmax = 100\n[[joints]]\nname = \"Y\"", "min = \"abc\"\nmax = 100\n[[joints]]\nname = \"Y\""),
         "mine.toml:7: joints[0].min: unknown parameter 'abc'"},
        {replace(base_text(), "axis = [0, 1, 0]\npoint", "axis = [0, 1]\npoint"), "mine.toml:35: tool_chain[3].axis: expected an array of 3 numbers"},
        {replace(base_text(), "type = \"rotary\"", "typ = \"rotary\""), "mine.toml:21: joints[3].typ: unknown key"},
        {replace(base_text(), "type = \"rotary\"", "type = \"spinny\""), "mine.toml:21: joints[3].type: expected \"linear\" or \"rotary\""},
        {replace(base_text(), "joint = \"Z\"", "joint = \"Q\""), "tool_chain[2].joint: letter Q cannot name an axis"},
        {replace(base_text(), "joint = \"Z\"", "joint = \"X\""), "tool_chain[2].joint: joint X appears twice in the chains"},
        {replace(base_text(), "axis = [0, 0, 1]", "axis = [0, 0, 0]"), "mine.toml:32: tool_chain[2].axis: direction has length 0"},
        {replace(base_text(), "min = -90", "min = 91"), "joints[3].min: min is greater than max"},
        {replace(base_text(), "name = \"t\"", "name = \"t\"\nbogus = 1"), "mine.toml:2: bogus: unknown key"},
        {replace(base_text(), "[[tool_chain]]\njoint = \"B\"", "[[part_chain]]\njoint = \"B\""), ""},  // valid: B on the part chain
        {"name = \"t\"\n[[joints]\n", "mine.toml:2: "},  // TOML syntax error with its line
        {replace(base_text(), "off = 5", "off = \"five\""), "mine.toml:3: parameters.off: expected a number"},
    };
    for (const Case& c : cases) {
        CAPTURE(c.text);
        if (c.expect.empty()) {
            CHECK_NOTHROW(load_machine_text(c.text, "mine.toml"));
            continue;
        }
        const std::string e = error_of(c.text);
        CAPTURE(e);
        CHECK(e.find(c.expect) != std::string::npos);
        CHECK(e.rfind("mine.toml:", 0) == 0);
    }
}

TEST_CASE("structural errors: joints in no chain, wrong counts, unknown --set") {
    // A joint in neither chain.
    std::string t = base_text() + "[[joints]]\nname = \"C\"\ntype = \"rotary\"\n";
    CHECK(error_of(t).find("joint C is in neither part_chain nor tool_chain") != std::string::npos);
    // Only two linear joints.
    t = replace(replace(base_text(), "[[joints]]\nname = \"Z\"\ntype = \"linear\"\nmin = -100\nmax = 100\n", ""),
                "[[tool_chain]]\njoint = \"Z\"\naxis = [0, 0, 1]\n", "");
    CHECK(error_of(t).find("exactly three linear joints") != std::string::npos);
    // --set of a parameter the file does not have.
    CHECK(error_of(base_text(), {{"nope", 1}}).find("no parameter 'nope'") != std::string::npos);
    // Two parallel rotary axes cannot orient a tool: refused when the kinematics is built.
    t = base_text() + "[[joints]]\nname = \"C\"\ntype = \"rotary\"\n[[tool_chain]]\njoint = \"C\"\naxis = [0, 1, 0]\n";
    const Machine m = load_machine_text(t, "mine.toml");
    CHECK_THROWS_AS(Kinematics{m}, MachineError);
}

TEST_CASE("bundled machines all load and name themselves") {
    const auto all = bundled_machines();
    for (const char* name : {"rw2", "wpi5", "pentarod", "koc5", "addin4", "xyzac-trt"}) {
        CAPTURE(name);
        REQUIRE(all.count(name) == 1);
        const Machine m = load_machine(name);
        CHECK(m.name == name);
        CHECK_FALSE(m.description.empty());
        CHECK_NOTHROW(Kinematics{m});
    }
    CHECK_THROWS_WITH_AS(load_machine("no-such-machine"), doctest::Contains("no machine named 'no-such-machine'"), MachineError);
}

TEST_CASE("a mistyped machine name, parameter or key is answered with the nearest one and where xlate5 looked") {
    // A name: the nearest machine found, and the directories searched, in their order.
    try {
        load_machine("rw3");
        FAIL("rw3 loaded");
    } catch (const MachineError& e) {
        const std::string m = e.what();
        CAPTURE(m);
        CHECK(contains(m, "no machine named 'rw3'; did you mean 'rw2'?"));
        std::string dirs;
        for (const auto& d : machine_search_path()) dirs += (dirs.empty() ? "" : ", ") + d;
        CHECK(contains(m, "looked in " + dirs));
        CHECK(contains(m, "pentarod"));
    }
    CHECK_THROWS_WITH_AS(load_machine("zzzzzzzz"), doctest::Contains("no machine named 'zzzzzzzz' (found: "), MachineError);
    // --set: the machine's own parameters, and the nearest.
    try {
        load_machine("rw2", {{"lz", 3}});
        FAIL("--set lz taken");
    } catch (const MachineError& e) {
        const std::string m = e.what();
        CAPTURE(m);
        CHECK(contains(m, "--set lz: the machine has no parameter 'lz'; did you mean 'la'?"));
        CHECK(contains(m, "(its parameters: la, lb)"));
    }
    CHECK_THROWS_WITH_AS(load_machine("rw2", {{"wavelength", 3}}), doctest::Contains("'wavelength' (its parameters: la, lb)"), MachineError);
    // A key of the file: the nearest allowed key at that place, or none when nothing is near.
    const std::string good = read(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml");
    const auto broken = [&](const std::string& from, const std::string& to) {
        const auto at = good.find(from);
        REQUIRE(at != std::string::npos);
        std::string t = good;
        t.replace(at, from.size(), to);
        return t;
    };
    CHECK_THROWS_WITH_AS(load_machine_text(broken("[parameters]", "[parametrs]"), "mine.toml"),
                         doctest::Contains("parametrs: unknown key; did you mean 'parameters'?"), MachineError);
    CHECK_THROWS_WITH_AS(load_machine_text(broken("max_feed = 7200", "max_fed = 7200"), "mine.toml"),
                         doctest::Contains("max_fed: unknown key; did you mean 'max_feed'?"), MachineError);
    try {
        load_machine_text(broken("[firmware]", "[firmware]\nwobble = 1"), "mine.toml");
        FAIL("wobble taken");
    } catch (const MachineError& e) {
        CHECK(contains(e.what(), "firmware.wobble: unknown key"));
        CHECK_FALSE(contains(e.what(), "did you mean"));
    }
}

TEST_CASE("a machine parsed once and built with other parameters is the machine load_machine_text gives") {
    std::mt19937 rng(19);
    std::uniform_real_distribution<double> u(-1, 1);
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        std::ifstream in(path);
        std::ostringstream text;
        text << in.rdbuf();
        const MachineTemplate file(text.str(), path);
        const Machine start = load_machine_text(text.str(), path);
        REQUIRE_FALSE(start.parameters.empty());
        for (int trial = 0; trial < 4; ++trial) {
            std::map<std::string, double> values = start.parameters;
            for (auto& [k, v] : values) v += u(rng) * (1 + std::abs(v)) * 0.01;
            const Machine a = file.build(values), b = load_machine_text(text.str(), path, values);
            CHECK(a.parameters == b.parameters);
            CHECK(a.parameters == values);
            const Kinematics ka(a), kb(b);
            std::vector<double> q = a.home_joints();
            for (std::size_t j = 0; j < q.size(); ++j) q[j] += u(rng) * 10;
            CHECK((ka.forward(q).tip - kb.forward(q).tip).norm() == 0.0);
            CHECK((ka.forward(q).axis - kb.forward(q).axis).norm() == 0.0);
        }
        // Errors come as from load_machine_text: an unknown parameter names the file.
        CHECK_THROWS_WITH_AS(file.build({{"no_such_parameter", 1.0}}), doctest::Contains(path.c_str()), MachineError);
    }
    // A broken file fails when it is parsed, naming the file and line.
    CHECK_THROWS_WITH_AS(MachineTemplate(replace(base_text(), "off = 5", "off = = 5"), "mine.toml"),
                         doctest::Contains("mine.toml:3"), MachineError);
    CHECK_THROWS_WITH_AS(MachineTemplate(replace(base_text(), "off * 2", "nope * 2"), "mine.toml"),
                         doctest::Contains("mine.toml"), MachineError);
}

TEST_CASE("an expression nested deeper than kMaxExpressionDepth is a MachineError naming file, line and key, not a crash") {
    // 30,000 nested parentheses (60 KB): a recursive parser without a bound overflows the stack.
    const std::string deep = std::string(30000, '(') + "off" + std::string(30000, ')');
    const std::string e = error_of(replace(base_text(), "point = [0, 0, \"off * 2\"]", "point = [0, 0, \"" + deep + "\"]"));
    CAPTURE(e.substr(0, 300));
    CHECK(e.rfind("mine.toml:36: tool_chain[3].point[2]: expression nests deeper than 64", 0) == 0);
    CHECK(e.size() < 300);  // the expression is quoted cut short
    // So do unary signs, the parser's other recursion.
    CHECK(contains(error_of(replace(base_text(), "\"off * 2\"", "\"" + std::string(30000, '-') + "off\"")), "nests deeper than 64"));
    // The bound itself: 64 levels load, 65 do not.
    const auto nested = [](int levels) {
        std::string s = "\"";
        s.append(std::size_t(levels), '(');
        s += "off * 2";
        s.append(std::size_t(levels), ')');
        return s + '"';
    };
    const Machine m = load_machine_text(replace(base_text(), "\"off * 2\"", nested(kMaxExpressionDepth)), "mine.toml");
    CHECK(m.tool_chain[3].point.z() == 10);
    CHECK(contains(error_of(replace(base_text(), "\"off * 2\"", nested(kMaxExpressionDepth + 1))), "nests deeper than 64"));
    CHECK(evaluate_expression("-(-(1 + 2))", {}) == 3);
}

TEST_CASE("bundled machines: every joint's home is inside its limits, and the tip is not below the bed there") {
    for (const auto& [name, path] : bundled_machines()) {
        CAPTURE_BINDING(name);
        const Machine m = load_machine(path);
        for (const Joint& j : m.joints) {
            CAPTURE(j.name);
            CHECK(j.home >= j.min);
            CHECK(j.home <= j.max);
        }
        // Where G28 leaves it, the tip is on or above the plate (z >= 0 in the part frame).
        CHECK(Kinematics(m).forward(m.home_joints()).tip.z() >= -1e-9);
    }
    // The two whose files say where Z homes: rw2 at its max switch, koc5 (a delta) at the top.
    for (const char* name : {"rw2", "koc5"}) {
        CAPTURE(name);
        const Machine m = load_machine(name);
        const Joint& z = m.joints[std::size_t(m.joint_index('Z'))];
        CHECK(z.home == z.max);
    }
}
