// SPDX-License-Identifier: GPL-3.0-or-later
// The virtual printer's Klipper personality: klippy's pseudo-terminal as its source shows it
// (klippy/gcode.py GCodeIO and GCodeDispatch, extras/gcode_move.py, extras/manual_stepper.py),
// built from those rules (docs/firmware.md, "Klipper"):
//  - lines are split at '\n' only and run one after another; each draws exactly one ok, sent
//    when its handler returns (a move: once the toolhead queued it, which waits while the
//    lookahead is full; G4, G28, M109, M190, M400 hold everything behind them), even an empty
//    line, a comment, an unknown command and a refused one;
//  - "N<n>" at the start is skipped and "*<cs>" is read as a parameter nobody asks for: neither
//    is checked, M110 does nothing, nothing is ever resent;
//  - a refusal is "!! <message>" before that line's ok (the position stays where it was:
//    gcode_move resets it on gcode:command_error); an unknown command is
//    `// Unknown command:"G93"` and an ok;
//  - M112 in the lines of one read acts at once while fewer than 20 lines are pending
//    (GCodeIO's out-of-order check): "// Klipper state: Shutdown", and from then on every command
//    but the base ones (M110 M112 M115 M105 STATUS ECHO HELP RESTART FIRMWARE_RESTART) is refused;
//  - M115 answers on its ok line ("ok FIRMWARE_NAME:Klipper FIRMWARE_VERSION:…"), M105 too;
//  - M114 reports "X:%.3f Y:%.3f Z:%.3f E:%.3f" only; GET_POSITION names every gcode axis;
//  - G92 reads only X Y Z E, and with none of them acts as a bare G92 (zeroes all four);
//  - an extra axis (A, B, C…) moves only once `MANUAL_STEPPER STEPPER=n GCODE_AXIS=A` ran; its
//    words are dropped silently before; SET_POSITION is refused while it is registered;
//  - G90/G91 set absolute_coord, M82/M83 absolute_extrude; E is relative when either says so;
//  - moves before G28 are refused ("Must home axis first") unless klipper_homed;
//  - a move out of `limits` is refused: "Move out of range: x y z [e]" (the extra axes left out).
// Left out: temperatures (fixed values), real kinematics and timing (a move takes move_ms),
// macros, SD files, other extended commands (their names are unknown commands here), and the
// host restarting (FIRMWARE_RESTART is taken and answered as the shutdown it would end).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <regex>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"
#include "daemon/virtual_printer.hpp"

namespace xlate5 {
namespace {

using Clock = std::chrono::steady_clock;

Clock::duration kms(double v) { return std::chrono::microseconds(std::int64_t(v * 1000)); }

// gcode.py: args_r = re.compile('([A-Z_]+|[A-Z*])') split of the upper-cased line; a leading N
// word is skipped; the command is the first letter word and its number.
struct KCommand {
    std::string cmd;                            // "G1", "M115", "MANUAL_STEPPER", "" for none
    std::vector<std::pair<std::string, std::string>> params;  // in order, upper-cased keys
    std::string rest;                           // the text after the command (extended parameters)
};

KCommand parse(const std::string& line) {
    KCommand k;
    std::string s = line;
    const auto semi = s.find(';');
    if (semi != std::string::npos) s.resize(semi);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
    std::size_t i = 0;
    while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    s.erase(0, i);
    // A leading line number is skipped, with the blanks after it.
    if (!s.empty() && (s[0] == 'N' || s[0] == 'n') && s.size() > 1 && std::isdigit(static_cast<unsigned char>(s[1]))) {
        std::size_t j = 1;
        while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
        while (j < s.size() && s[j] == ' ') ++j;
        s.erase(0, j);
    }
    std::string up;
    for (char c : s) up += char(std::toupper(static_cast<unsigned char>(c)));
    static const std::regex word(R"(([A-Z_]+|[A-Z*])([^A-Z_*]*))");
    std::vector<std::pair<std::string, std::string>> parts;
    for (std::sregex_iterator it(up.begin(), up.end(), word), end; it != end; ++it) {
        std::string v = (*it)[2];
        while (!v.empty() && v.back() == ' ') v.pop_back();
        while (!v.empty() && v.front() == ' ') v.erase(0, 1);
        parts.emplace_back((*it)[1], v);
    }
    if (parts.empty()) return k;
    // "G1" (a letter and its number), or an extended command's name ("MANUAL_STEPPER").
    k.cmd = parts[0].first.size() > 1 ? parts[0].first : parts[0].first + parts[0].second;
    for (std::size_t j = 1; j < parts.size(); ++j) k.params.push_back(parts[j]);
    const auto sp = s.find(' ');
    if (sp != std::string::npos) k.rest = s.substr(sp + 1);
    return k;
}

// Extended commands read NAME=value pairs (shlex-split).
std::map<std::string, std::string> extended(const std::string& rest) {
    std::map<std::string, std::string> out;
    std::size_t i = 0;
    while (i < rest.size()) {
        while (i < rest.size() && rest[i] == ' ') ++i;
        const std::size_t end = std::min(rest.find(' ', i), rest.size());
        const std::string w = rest.substr(i, end - i);
        const auto eq = w.find('=');
        if (eq != std::string::npos) {
            std::string key = w.substr(0, eq);
            for (auto& c : key) c = char(std::toupper(static_cast<unsigned char>(c)));
            out[key] = w.substr(eq + 1);
        }
        i = end;
    }
    return out;
}

bool base_command(const std::string& cmd) {
    for (const char* c : {"M110", "M112", "M115", "M105", "STATUS", "ECHO", "HELP", "RESTART", "FIRMWARE_RESTART"})
        if (cmd == c) return true;
    return false;
}

bool is_slow(const std::string& cmd) { return cmd == "G28" || cmd == "G4" || cmd == "M109" || cmd == "M190" || cmd == "M400"; }

const std::regex kM112(R"(^(?:[nN][0-9]+)?\s*[mM]112(?:\s|$))");

}  // namespace

void VirtualPrinter::klipper_line(std::string line) {
    ++stats_.received;
    stats_.bytes += line.size() + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // line.strip()
    // GCodeIO: M112 among the lines of a read acts at once while fewer than 20 are pending.
    if (kpending_.size() < 20 && std::regex_search(line, kM112)) {
        if (opt_.keep_executed) executed_.push_back("M112");
        if (record_.is_open()) record_ << "M112\n";
        klipper_shutdown("Shutdown due to M112 command");
    }
    kpending_.push_back(std::move(line));
    klipper_run();
}

void VirtualPrinter::klipper_shutdown(const std::string& why) {
    if (kshutdown_) return;
    kshutdown_ = true;
    kshutdown_why_ = why;
    planner_.clear();
    reply("// Klipper state: Shutdown");
}

void VirtualPrinter::klipper_error(const std::string& message) {
    // gcode.py _respond_error: a message of several lines goes first whole as "//" lines, then
    // "!! " and its first line.
    std::vector<std::string> lines;
    for (std::size_t p = 0; p <= message.size();) {
        const std::size_t q = std::min(message.find('\n', p), message.size());
        lines.push_back(message.substr(p, q - p));
        p = q + 1;
    }
    if (lines.size() > 1)
        for (const auto& l : lines) reply("// " + l);
    reply("!! " + lines.front());
}

std::string VirtualPrinter::klipper_axes(const std::vector<std::pair<char, double>>& v) const {
    std::string out;
    char buf[48];
    for (const auto& [l, x] : v) {
        std::snprintf(buf, sizeof buf, "%s%c:%.6f", out.empty() ? "" : " ", l, x);
        out += buf;
    }
    return out;
}

void VirtualPrinter::klipper_run() {
    if (kbusy_ || unplugged_) return;
    std::weak_ptr<VirtualPrinter> weak = shared_from_this();
    const auto later = [&](Clock::time_point until) {
        kbusy_ = true;
        run_timer_.expires_at(until);
        run_timer_.async_wait([weak](boost::system::error_code ec) {
            auto self = weak.lock();
            if (!self) return;
            self->kbusy_ = false;
            if (!ec) self->klipper_run();
        });
    };
    while (!kpending_.empty() && !unplugged_) {
        const auto now = Clock::now();
        while (!planner_.empty() && planner_.front() <= now) planner_.pop_front();
        const KCommand k = parse(kpending_.front());
        const bool move = k.cmd == "G0" || k.cmd == "G1";
        if (!kshutdown_ && move && int(planner_.size()) >= opt_.planner) {
            later(planner_.front());  // the toolhead's lookahead is full: the handler (and its ok) waits
            return;
        }
        if (!kshutdown_ && k.cmd == "M400" && !planner_.empty()) {
            later(planner_.back());
            return;
        }
        if (!kshutdown_ && opt_.faults.slow_seconds > 0 && is_slow(k.cmd) && !front_ready_) {
            front_ready_ = now + kms(opt_.faults.slow_seconds * 1000);
            later(*front_ready_);
            return;
        }
        front_ready_.reset();
        const std::string line = std::move(kpending_.front());
        kpending_.pop_front();
        klipper_execute(line);
    }
}

bool VirtualPrinter::klipper_g1(const std::string& upper, std::string& error) {
    const KCommand k = parse(upper);
    std::map<char, double> next = klast_;
    for (const auto& [key, value] : k.params) {
        if (key.size() != 1) continue;
        const char l = key[0];
        const bool e = l == 'E';
        const bool axis = l == 'X' || l == 'Y' || l == 'Z' || e || kregistered_.count(l);
        if (!axis && l != 'F') continue;  // an unregistered A/B/C word: dropped without a word
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (value.empty() || end != value.c_str() + value.size()) {
            error = "Unable to parse move '" + upper + "'";
            return false;
        }
        if (l == 'F') {
            if (v <= 0) {
                error = "Invalid speed in '" + upper + "'";
                return false;
            }
            kspeed_ = v / 60;
            continue;
        }
        const bool relative = !kabsolute_ || (e && !kabsolute_e_);
        next[l] = relative ? next[l] + v : v + kbase_[l];
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "%.3f %.3f %.3f [%.3f]", next['X'], next['Y'], next['Z'], next['E']);
    bool moves_xyz = false;
    for (const char l : {'X', 'Y', 'Z'}) moves_xyz = moves_xyz || next[l] != klast_[l];
    if (moves_xyz && !khomed_) {
        error = std::string("Must home axis first: ") + buf;
        return false;
    }
    for (const auto& [l, v] : next) {
        const auto lim = opt_.limits.find(l);
        if (lim != opt_.limits.end() && v != klast_[l] && (v < lim->second.first || v > lim->second.second)) {
            error = std::string("Move out of range: ") + buf;
            return false;
        }
    }
    klast_ = std::move(next);
    for (const auto& [l, name] : kregistered_) kstepper_[name] = klast_[l];
    return true;
}

void VirtualPrinter::klipper_execute(const std::string& raw) {
    const KCommand k = parse(raw);
    const std::string& cmd = k.cmd;
    std::string ok = "ok";
    std::string error;
    const auto ran = [&] {
        ++stats_.executed;
        std::string text = proto::strip_comment(raw);
        if (opt_.keep_executed) executed_.push_back(text);
        if (record_.is_open()) record_ << text << '\n';
    };
    if (kshutdown_ && !base_command(cmd) && !cmd.empty()) {
        error = kshutdown_why_ + "\nOnce the underlying issue is corrected, use the\n\"FIRMWARE_RESTART\" command to reset the firmware, reload the\nconfig, and restart the host software.\nPrinter is shutdown";
    } else if (cmd.empty()) {
        // An empty line or a comment: cmd_default returns, and the ok still comes.
    } else if (cmd == "M110" || cmd == "M112") {
        ran();
    } else if (cmd == "M115") {
        ran();
        ok = "ok FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.13.0-xlate5-double";
    } else if (cmd == "M105") {
        ran();
        ok = "ok B:20.1 /0.0 T0:21.5 /0.0";
    } else if (cmd == "STATUS") {
        ran();
        if (kshutdown_) error = kshutdown_why_ + "\nKlipper state: Not ready";
        else reply("// Klipper state: Ready");
    } else if (cmd == "FIRMWARE_RESTART" || cmd == "RESTART") {
        // The host restarts: state and registrations are gone, the axes are unhomed.
        ran();
        kshutdown_ = false;
        kregistered_.clear();
        khomed_ = opt_.klipper_homed;
        planner_.clear();
        kbase_.clear();
        reply("// Klipper state: Ready");
    } else if (cmd == "G0" || cmd == "G1") {
        if (klipper_g1(raw, error)) {
            ran();
            const auto now = Clock::now();
            const auto begin = planner_.empty() ? now : std::max(now, planner_.back());
            planner_.push_back(begin + kms(opt_.faults.move_ms));
        }
    } else if (cmd == "G28") {
        ran();
        khomed_ = true;
    } else if (cmd == "G90" || cmd == "G91") {
        ran();
        kabsolute_ = cmd == "G90";
    } else if (cmd == "M82" || cmd == "M83") {
        ran();
        kabsolute_e_ = cmd == "M82";
    } else if (cmd == "G92") {
        // gcode_move.cmd_G92: X Y Z E only; none of them is a bare G92.
        ran();
        bool any = false;
        for (const auto& [key, value] : k.params) {
            if (key.size() != 1 || std::string("XYZE").find(key[0]) == std::string::npos) continue;
            any = true;
            kbase_[key[0]] = klast_[key[0]] - std::strtod(value.c_str(), nullptr);
        }
        if (!any)
            for (const char l : {'X', 'Y', 'Z', 'E'}) kbase_[l] = klast_[l];
    } else if (cmd == "M114") {
        ran();
        char buf[128];
        std::snprintf(buf, sizeof buf, "X:%.3f Y:%.3f Z:%.3f E:%.3f", klast_['X'] - kbase_['X'], klast_['Y'] - kbase_['Y'],
                      klast_['Z'] - kbase_['Z'], klast_['E'] - kbase_['E']);
        reply(buf);
    } else if (cmd == "GET_POSITION") {
        ran();
        std::vector<std::pair<char, double>> g, b;
        for (const char l : {'X', 'Y', 'Z', 'E'}) g.emplace_back(l, klast_[l]), b.emplace_back(l, kbase_[l]);
        for (const auto& [l, name] : kregistered_) g.emplace_back(l, klast_[l]), b.emplace_back(l, kbase_[l]);
        reply("// mcu: stepper_x:0 stepper_y:0 stepper_z:0\n// stepper: stepper_x:0.000000 stepper_y:0.000000 stepper_z:0.000000\n"
              "// kinematic: " + klipper_axes({g[0], g[1], g[2]}) + "\n// toolhead: " + klipper_axes(g) + "\n// gcode: " +
              klipper_axes(g) + "\n// gcode base: " + klipper_axes(b) + "\n// gcode homing: X:0.000000 Y:0.000000 Z:0.000000");
    } else if (cmd == "MANUAL_STEPPER") {
        const auto p = extended(k.rest);
        const auto name = p.find("STEPPER");
        if (name == p.end()) {
            error = "Error on '" + raw + "': missing STEPPER";
        } else {
            char letter = 0;
            for (const auto& [l, n] : kregistered_)
                if (n == name->second) letter = l;
            if (p.count("SET_POSITION") && letter) {
                error = "Must unregister from gcode axis first";
            } else if (const auto axis = p.find("GCODE_AXIS"); axis != p.end()) {
                ran();
                if (letter) kregistered_.erase(letter);
                if (!axis->second.empty()) {
                    const char l = char(std::toupper(static_cast<unsigned char>(axis->second[0])));
                    if (axis->second.size() != 1 || std::string("XYZEFN").find(l) != std::string::npos || !std::isalpha(static_cast<unsigned char>(l))) {
                        error = "Not a valid GCODE_AXIS";
                    } else {
                        kregistered_[l] = name->second;
                        klast_[l] = kstepper_[name->second];
                        kbase_[l] = 0;
                    }
                }
            } else if (const auto set = p.find("SET_POSITION"); set != p.end()) {
                ran();
                kstepper_[name->second] = std::strtod(set->second.c_str(), nullptr);
            } else {
                ran();
            }
        }
    } else if (cmd == "G4" || cmd == "M400" || cmd == "M109" || cmd == "M190" || cmd == "M104" || cmd == "M140" || cmd == "M106" ||
               cmd == "M107" || cmd == "G21" || cmd == "M84" || cmd == "M18" || cmd == "M117" || cmd == "M118" || cmd == "M220" ||
               cmd == "M221" || cmd == "M204") {
        ran();
    } else if (cmd == "G20") {
        error = "Machine does not support G20 (inches) command";
    } else {
        reply("// Unknown command:\"" + cmd + "\"");
    }
    if (!error.empty()) {
        ++stats_.refused;
        klipper_error(error);
    }
    if (opt_.faults.lose_ok > 0 && uni_(rng_) < opt_.faults.lose_ok) ++stats_.lost_oks;
    else reply(ok);
}

}  // namespace xlate5
