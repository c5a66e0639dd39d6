// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 join`: planar files and their build directions -> one tool-space program through
// tilted planes -> the translation (stage: command line).
//
// Each part FILE@I,J,K@X,Y,Z is read in the plane whose +Z is the build direction (I,J,K) and
// whose origin is X,Y,Z in the part frame: G68.2 X Y Z with the Z-X-Z angles of that direction,
// then G53.1. A part without a direction is printed as it is (the tool along +Z). Between two
// parts: retract along the tool by the clearance (inside the old plane, +Z is the tool), cancel
// the plane, define the next, turn the tool (G53.1, tip held), travel above the next part's
// first point, then the part's own first move approaches it along the new tool axis. E and the
// temperatures run on: heaters are never switched off, motors never released, the program never
// ended, and the printer never homed between parts (those lines of a part's end and start code
// are written as comments instead); each part's E starts from 0 (G92 E0).
#include "cli/join_cmd.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "cli/options.hpp"
#include "translators/error.hpp"
#include "translators/number.hpp"
#include "translators/pipeline/work_plane.hpp"

namespace xlate5::cli {
namespace {

// Coordinates and directions beyond this are typing mistakes (mm).
constexpr double kLargest = 1e6;

struct Part {
    std::string path;
    bool tilted = false;
    Eigen::Vector3d direction = Eigen::Vector3d::UnitZ(), origin = Eigen::Vector3d::Zero();
};

Eigen::Vector3d parse_triple(const std::string& text, const std::string& arg) {
    std::vector<double> v;
    std::stringstream list(text);
    for (std::string field; std::getline(list, field, ',');) {
        const char* begin = field.c_str();
        char* end = nullptr;
        const double x = std::strtod(begin, &end);
        if (end == begin || *end != '\0' || !std::isfinite(x) || std::fabs(x) > kLargest)
            throw CLI::ValidationError("FILE@I,J,K@X,Y,Z", "'" + field + "' in '" + arg + "' is not a number from -1000000 to 1000000");
        v.push_back(x);
    }
    if (v.size() != 3 || text.empty() || text.back() == ',')
        throw CLI::ValidationError("FILE@I,J,K@X,Y,Z", "expected three comma-separated numbers, got '" + text + "' in '" + arg + "'");
    return {v[0], v[1], v[2]};
}

Part parse_part(const std::string& arg) {
    Part p;
    const auto at1 = arg.find('@');
    p.path = arg.substr(0, at1);
    if (p.path.empty()) throw CLI::ValidationError("FILE@I,J,K@X,Y,Z", "no file name in '" + arg + "'");
    if (at1 == std::string::npos) return p;
    const auto at2 = arg.find('@', at1 + 1);
    p.tilted = true;
    p.direction = parse_triple(arg.substr(at1 + 1, at2 == std::string::npos ? std::string::npos : at2 - at1 - 1), arg);
    if (!(p.direction.norm() > 1e-9)) throw CLI::ValidationError("FILE@I,J,K@X,Y,Z", "the build direction in '" + arg + "' has length 0");
    if (at2 != std::string::npos) p.origin = parse_triple(arg.substr(at2 + 1), arg);
    return p;
}

// The words of a line (comments removed), upper case: "M104 S0" -> {"M104", "S0"}.
std::vector<std::string> words_of(const std::string& line) {
    std::string code = line.substr(0, line.find(';'));
    if (const auto paren = code.find('('); paren != std::string::npos) code = code.substr(0, paren);
    std::vector<std::string> w;
    std::string cur;
    for (const char c : code) {
        if (std::isalpha(static_cast<unsigned char>(c))) {
            if (!cur.empty()) w.push_back(cur);
            cur = std::string(1, char(std::toupper(static_cast<unsigned char>(c))));
        } else if (!std::isspace(static_cast<unsigned char>(c)) && !cur.empty()) {
            cur += c;
        }
    }
    if (!cur.empty()) w.push_back(cur);
    return w;
}

bool is(const std::string& word, const char* code) {
    // "G0" matches "G0" and "G00", not "G01".
    if (word.empty() || word[0] != code[0]) return false;
    char* end = nullptr;
    const double a = std::strtod(word.c_str() + 1, &end);
    if (*end != '\0' || end == word.c_str() + 1) return false;
    return a == std::strtod(code + 1, nullptr);
}

bool heater_off(const std::vector<std::string>& w) {
    if (w.empty() || !(is(w[0], "M104") || is(w[0], "M109") || is(w[0], "M140") || is(w[0], "M190"))) return false;
    for (const auto& x : w)
        if ((x[0] == 'S' || x[0] == 'R') && std::strtod(x.c_str() + 1, nullptr) == 0) return true;
    return false;
}

// Lines of a part that would stop the print between parts.
bool stops_between(const std::vector<std::string>& w) {
    if (w.empty()) return false;
    for (const char* c : {"M84", "M18", "M0", "M1", "M2", "M30", "M81"})
        if (is(w[0], c)) return true;
    return heater_off(w);
}

bool is_move(const std::vector<std::string>& w) {
    for (const auto& x : w)
        if (is(x, "G0") || is(x, "G1")) return true;
    return false;
}

std::string num(double v) {
    std::string s;
    append_shortest(s, std::abs(v) < 1e-12 ? 0.0 : v);
    return s;
}

struct Joined {
    std::string text;
    std::vector<SourceLine> origin;
    void add(const std::string& line, const std::string& file, std::uint64_t at, bool inserted) {
        text += line;
        text += '\n';
        origin.push_back({file, at, inserted});
    }
};

Joined join_parts(const std::vector<Part>& parts, double clearance) {
    Joined j;
    bool previous_tilted = false, previous = false, e_relative = false;
    std::string previous_file;
    std::uint64_t previous_last = 0;
    for (std::size_t k = 0; k < parts.size(); ++k) {
        const Part& p = parts[k];
        const bool last = k + 1 == parts.size();
        std::ifstream in(p.path, std::ios::binary);
        if (!in) throw IoError(p.path + ": cannot open: " + std::strerror(errno));
        std::vector<std::string> lines;
        for (std::string line; std::getline(in, line);) {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            lines.push_back(std::move(line));
        }
        // The first point the part moves to (each coordinate the first given), in its own frame.
        Eigen::Vector3d first = Eigen::Vector3d::Zero();
        bool seen[3] = {false, false, false};
        for (const auto& line : lines) {
            const auto w = words_of(line);
            if (!is_move(w)) continue;
            for (const auto& x : w)
                if (x[0] >= 'X' && x[0] <= 'Z' && !seen[x[0] - 'X']) seen[x[0] - 'X'] = true, first[x[0] - 'X'] = std::strtod(x.c_str() + 1, nullptr);
        }
        bool started = false;
        for (std::size_t n = 0; n < lines.size(); ++n) {
            const std::string& line = lines[n];
            const std::uint64_t at = n + 1;
            const auto w = words_of(line);
            if (!started && is_move(w)) {
                started = true;
                if (previous) {
                    // Retract along the tool: inside a plane its +Z, outside it +Z as printed.
                    j.add("; xlate5 join: change to " + p.path, p.path, at, true);
                    j.add("G91", previous_file, previous_last, true);
                    j.add("G0 Z" + num(clearance), previous_file, previous_last, true);
                    j.add("G90", previous_file, previous_last, true);
                    j.add(e_relative ? "M83" : "M82", previous_file, previous_last, true);
                    if (previous_tilted) j.add("G69", p.path, at, true);
                }
                if (p.tilted) {
                    const Eigen::Vector3d a = euler_for_direction(p.direction);
                    j.add("G68.2 X" + num(p.origin.x()) + " Y" + num(p.origin.y()) + " Z" + num(p.origin.z()) + " I" + num(a.x()) +
                              " J" + num(a.y()) + " K" + num(a.z()),
                          p.path, at, true);
                    j.add("G53.1", p.path, at, true);
                }
                if (previous) {
                    // Above the part's first point, then its own first move approaches.
                    j.add("G0 X" + num(first.x()) + " Y" + num(first.y()) + " Z" + num(first.z() + clearance), p.path, at, true);
                    j.add("G92 E0", p.path, at, true);
                }
            }
            const bool drop = (!w.empty() && (is(w[0], "G28") || is(w[0], "G29")) && (k > 0 || started)) || (!last && stops_between(w));
            if (drop) {
                j.add("; xlate5 join: not between parts: " + line, p.path, at, false);
                continue;
            }
            for (const auto& x : w) {
                if (is(x, "M82") || is(x, "G90")) e_relative = false;
                if (is(x, "M83") || is(x, "G91")) e_relative = true;
            }
            j.add(line, p.path, at, false);
        }
        if (!started) throw IoError(p.path + ": no move (G0 or G1) to join");
        previous = true;
        previous_tilted = p.tilted;
        previous_file = p.path;
        previous_last = lines.size();
    }
    if (previous_tilted) j.add("G69", previous_file, previous_last, true);
    return j;
}

}  // namespace

std::unique_ptr<JoinCommand> add_join_command(CLI::App& app) {
    auto c = std::make_unique<JoinCommand>();
    c->join = app.add_subcommand("join", "one joint-space file from planar files, each printed in the plane of its build direction "
                                         "(3+2), with a safe change between them");
    c->join->add_option("parts", c->parts, "FILE, or FILE@I,J,K (build direction, the plane's +Z) or FILE@I,J,K@X,Y,Z (and the plane's origin in the part frame)")
        ->required()
        ->option_text("FILE[@I,J,K[@X,Y,Z]] ...");
    c->join->add_option("--clearance", c->clearance, with_default("retract along the tool between parts, and height above the next part's first point", "5 mm"))
        ->check(number_in(0, 1000, "mm", true))
        ->option_text("MM");
    return c;
}

int run_join_command(const JoinCommand& c, const Common& common, const TranslateOptions& translate) {
    if (!c.join->parsed()) return -1;
    MadeInput made;
    try {
        if (!translate.file.empty() || translate.input != "-")
            throw CLI::ValidationError("join", "reads the FILE arguments after it (no -i or FILE before it)");
        std::vector<Part> parts;
        for (const auto& a : c.parts) parts.push_back(parse_part(a));
        Joined joined = join_parts(parts, c.clearance);
        // The joined program goes to the translation as a file of its own, never to disk.
        made.fd = ::memfd_create("xlate5-join", MFD_CLOEXEC);
        if (made.fd < 0) throw IoError(std::string("cannot make the joined program: ") + std::strerror(errno));
        for (std::size_t done = 0; done < joined.text.size();) {
            const ssize_t n = ::write(made.fd, joined.text.data() + done, joined.text.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) throw IoError(std::string("cannot make the joined program: ") + std::strerror(errno));
            done += std::size_t(n);
        }
        if (::lseek(made.fd, 0, SEEK_SET) != 0) throw IoError(std::string("cannot make the joined program: ") + std::strerror(errno));
        made.origin = std::move(joined.origin);
    } catch (...) {
        if (made.fd >= 0) ::close(made.fd);
        return exit_with(std::current_exception());
    }
    const int code = run_translate(common, translate, &made);
    ::close(made.fd);
    return code;
}

}  // namespace xlate5::cli
