// SPDX-License-Identifier: GPL-3.0-or-later
// Small helpers shared by the tests: split output into lines and words, run the xlate5 binary.
#pragma once
#include <doctest/doctest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "translators/machine/machine.hpp"

// doctest's CAPTURE reads its argument inside a lambda, and clang 14 cannot capture a structured
// binding there: this captures a reference to it, under the binding's own name in the message.
#define CAPTURE_BINDING(x)              \
    const auto& x##_captured = (x);     \
    INFO(#x " := ", x##_captured)

namespace xlate5::test {

// Built with AddressSanitizer: gcc says so with __SANITIZE_ADDRESS__, clang with __has_feature.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitized = true;
#else
inline constexpr bool kAddressSanitized = false;
#endif
#else
inline constexpr bool kAddressSanitized = false;
#endif

// Cases of a long random loop. The sanitizer tree looks for memory errors and undefined
// behaviour on the code paths the release tree checks numerically with every case, so it runs a
// tenth of them (at least one): each case costs some ten times as much under the sanitizers.
inline constexpr int sampled(int cases) { return kAddressSanitized ? std::max(1, cases / 10) : cases; }

// A long corpus file's first lines: a tenth of them under the sanitizers (as sampled()), all of it
// in the release tree. For the whole-file tests of a file of tens of thousands of lines.
inline std::string sampled_lines(const std::string& text) {
    if (!kAddressSanitized) return text;
    const auto lines = std::count(text.begin(), text.end(), '\n');
    std::size_t at = std::string::npos;  // the kept lines' last '\n' (npos + 1 is 0: the search starts at the front)
    for (auto kept = std::max<decltype(lines)>(1, lines / 10); kept > 0; --kept)
        if ((at = text.find('\n', at + 1)) == std::string::npos) return text;
    return text.substr(0, at + 1);
}

// A whole file as text ("" when it cannot be read).
inline std::string read(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

// A word for /bin/sh, in single quotes.
inline std::string quote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

// A fresh directory under the system temp dir, removed with everything in it.
struct TempDir {
    std::filesystem::path path;
    TempDir() {
        std::string pattern = (std::filesystem::temp_directory_path() / "xlate5-test-XXXXXX").string();
        REQUIRE(::mkdtemp(pattern.data()) != nullptr);
        path = pattern;
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    std::filesystem::path write(const std::string& name, const std::string& text) const {
        const auto p = path / name;
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : std::filesystem::directory_iterator(path)) names.push_back(e.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }
};

// The third-party corpus (XLATE5_CORPUS_DIR, ../shared/corpus next to the checkout; the variable
// of that name in the environment wins): read at test time, never copied into the repository. A
// checkout without it skips the tests that read it, and says so once on standard error.
#ifdef XLATE5_BINARY
// What a run of the xlate5 binary gave.
struct RunResult {
    int code = -1;
    std::string out, err;
};
// Standard input of a run: /dev/null, this text (from a file), or what the prefix pipes in.
struct RunInput {
    std::optional<std::string> text;
    bool piped = false;
};

// Runs the xlate5 binary with `args` (quoted already) through the shell, standard output and
// error to files in `dir`. `prefix` goes before the binary: env(1), a limit, a pipe into it.
inline RunResult run_xlate5(const TempDir& dir, const std::string& args, const std::string& prefix = "", const RunInput& in = {}) {
    const std::filesystem::path stdin_file = dir.path / ".stdin", out = dir.path / ".stdout", err = dir.path / ".stderr";
    std::string redirect = " </dev/null";
    if (in.piped) redirect.clear();
    if (in.text) {
        std::ofstream(stdin_file, std::ios::binary) << *in.text;
        redirect = " <" + quote(stdin_file.string());
    }
    const std::string cmd = prefix + quote(XLATE5_BINARY) + " " + args + redirect + " >" + quote(out.string()) + " 2>" + quote(err.string());
    const int status = std::system(cmd.c_str());
    RunResult r;
    REQUIRE(status != -1);
    REQUIRE(WIFEXITED(status));
    r.code = WEXITSTATUS(status);
    r.out = read(out);
    r.err = read(err);
    std::error_code ec;
    for (const auto& f : {stdin_file, out, err}) std::filesystem::remove(f, ec);
    return r;
}
#endif

inline std::string corpus_dir() {
    const char* env = std::getenv("XLATE5_CORPUS_DIR");
    return env && *env ? env : XLATE5_CORPUS_DIR;
}
inline bool corpus_absent() {
    static const bool absent = [] {
        const bool a = !std::filesystem::is_directory(corpus_dir());
        if (a) std::fprintf(stderr, "skipping the tests that read the corpus: %s is absent\n", corpus_dir().c_str());
        return a;
    }();
    return absent;
}

constexpr double kPi = 3.14159265358979323846;
inline double rad(double deg) { return deg * kPi / 180.0; }

// The distance from p to the segment a-b (mm): how far an emitted piece's tip strays from the
// programmed line.
inline double seg_dist(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    double t = ab.squaredNorm() > 0 ? (p - a).dot(ab) / ab.squaredNorm() : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return (a + t * ab - p).norm();
}

inline double angle_deg(const Eigen::Vector3d& u, const Eigen::Vector3d& v) { return std::acos(std::clamp(u.dot(v), -1.0, 1.0)) * 180 / kPi; }

// The angle (degrees) from unit vector x to the great-circle arc from a to b (exact: the
// nearest point of the circle's plane, or the nearer end when that lies off the arc).
inline double arc_distance(const Eigen::Vector3d& x, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d n = a.cross(b);
    double best = std::min(angle_deg(x, a), angle_deg(x, b));
    if (n.norm() < 1e-12) return best;
    const Eigen::Vector3d nn = n.normalized();
    const Eigen::Vector3d p = x - x.dot(nn) * nn;
    if (p.norm() > 1e-12 && a.cross(p).dot(nn) >= 0 && p.cross(b).dot(nn) >= 0)
        best = std::min(best, std::asin(std::min(1.0, std::abs(x.dot(nn)))) * 180 / kPi);
    return best;
}

inline bool contains(const std::string& hay, const std::string& needle) { return hay.find(needle) != std::string::npos; }

inline std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> lines;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) lines.push_back(line);
    return lines;
}

// "G1 X1.5 Y-2 A30" -> {'G':1, 'X':1.5, 'Y':-2, 'A':30}; a flag word maps to NaN.
inline std::map<char, double> words_of(const std::string& line) {
    std::map<char, double> w;
    std::istringstream in(line);
    std::string tok;
    while (in >> tok) {
        REQUIRE(!tok.empty());
        const char letter = tok[0];
        REQUIRE(std::isalpha(static_cast<unsigned char>(letter)));
        REQUIRE_MESSAGE(w.count(letter) == 0, "letter " << letter << " twice in '" << line << "'");
        w[letter] = tok.size() > 1 ? std::stod(tok.substr(1)) : std::nan("");
    }
    return w;
}

// The firmware's joints after each line of output, as the firmware reads them: G0/G1 set the
// joints they name, G92 says where a joint is (the same pose).
inline void apply_joint_lines(const Machine& m, const std::string& text, std::vector<double>& q) {
    for (const auto& line : lines_of(text)) {
        if (line.empty() || line[0] == ';') continue;
        const auto w = words_of(line.substr(0, line.find(';')));
        if (!w.count('G')) continue;
        const double g = w.at('G');
        if (g != 0 && g != 1 && g != 92) continue;
        for (std::size_t j = 0; j < m.joints.size(); ++j)
            if (w.count(m.joints[j].output)) q[j] = w.at(m.joints[j].output);
    }
}

// A layer-change file for the look-back: azimuth printing A 0 -> 300 on rw2, whose A stops at
// +-168; the travel move at A = 150 (the layer change) is turned onto the other branch by the
// look-back, as `xlate5 translate` does. `wait_after_travel` puts an M400 right after it.
inline std::vector<std::string> unwinding_print(bool wait_after_travel) {
    std::vector<std::string> lines = {"M83"};
    const auto tip = [](double a, double z) {
        char buf[128];
        const double r = -a * 3.14159265358979323846 / 180;
        std::snprintf(buf, sizeof buf, " X%.4f Y%.4f Z%.4f A%.3f B30", 110 + 20 * std::cos(r), 110 + 20 * std::sin(r), z, a);
        return std::string(buf);
    };
    double z = 5;
    lines.push_back("G0" + tip(0, z) + " F1200");
    for (double a = 0; a < 300; a += 5) {
        if (a == 150) {
            z += 0.3;
            lines.push_back("G0" + tip(a, z));
            if (wait_after_travel) lines.push_back("M400");
        }
        lines.push_back("G1" + tip(a + 5, z) + " E0.05");
    }
    return lines;
}

// An ASCII STL of a cube of `size` mm at the origin, two triangles a face, outward normals by the
// right-hand rule (for the slicers the tests run).
inline std::string cube_stl(int size) {
    const int quads[6][4][3] = {{{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
                                {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
                                {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}}};
    std::ostringstream stl;
    stl << "solid cube\n";
    for (const auto& q : quads)
        for (const int t : {1, 2}) {
            stl << " facet normal 0 0 0\n  outer loop\n";
            for (const int k : {0, t, t + 1})
                stl << "   vertex " << size * q[k][0] << " " << size * q[k][1] << " " << size * q[k][2] << "\n";
            stl << "  endloop\n endfacet\n";
        }
    stl << "endsolid cube\n";
    return stl.str();
}

// A bundled machine with the bodies of tests/bodies/NAME.toml appended: GUESSES from its source
// document (each file says which), not shipped in machines/ because the check's cost is still
// far above the translation's (docs/limits.md).
inline std::string machine_text_with_bodies(const std::string& name) {
    const std::filesystem::path dir(XLATE5_MACHINE_DIR_FOR_TESTS);
    return read_machine_file((dir / (name + ".toml")).string()) + "\n" + read(dir.parent_path() / "tests" / "bodies" / (name + ".toml"));
}
inline Machine load_with_bodies(const std::string& name) {
    return load_machine_text(machine_text_with_bodies(name), std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/" + name + ".toml");
}

// rw2: a wall along Y at X 50, Y 80..120, 30 layers of 0.2 mm (6 mm high), printed with relative E.
inline std::string rw2_wall() {
    std::string s = "G21\nG90\nM83\nG43.4\nG1 X50 Y80 Z0.2 A0 B0 F3000\n";
    for (int k = 0; k < 30; ++k) {
        char line[80];
        std::snprintf(line, sizeof line, "G1 X50 Y80 Z%.2f\nG1 X50 Y120 E1.5\nG1 X50 Y80\n", 0.2 * (k + 1));
        s += line;
    }
    return s + "G1 Z20\n";
}

}  // namespace xlate5::test
