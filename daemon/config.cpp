// SPDX-License-Identifier: GPL-3.0-or-later
// The service's configuration: one table of settings, read from a TOML file or from flags
// (stage: configuration; may call toml++ and the machine's types).
#include "daemon/config.hpp"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <toml++/toml.h>

#include "translators/error.hpp"
#include "translators/inputs/small_file.hpp"

namespace xlate5 {
namespace {

using Kind = ServeSetting::Kind;

// The bounds are the documented ones (config/xlate5.toml); each keeps a cast below it defined
// (every whole-number bound fits the type it is cast to) and rules out a value no printer needs.
const std::vector<ServeSetting> kSettings = {
    {"machine", "-m,--machine", Kind::Text, 0, 0, "", "", "machine name (see 'xlate5 machines') or path to a machine .toml"},
    {"compensation", "--compensation", Kind::Text, 0, 0, "", "", "a compensation file replacing the machine file's own"},
    {"tolerance", "--tolerance", Kind::Number, 0, 10, "mm", "", "largest tip deviation from the programmed line; 0: the machine file's"},
    {"mode", "--mode", Kind::Choice, 0, 0, "", "G43.4|G43.5|G49", "the orientation mode senders' files start in"},
    {"extruder_letter", "--extruder-letter", Kind::Text, 0, 0, "", "", "the input letter that carries extrusion"},
    {"firmware.port", "--port", Kind::Text, 0, 0, "", "", "the firmware's serial device (see 'xlate5 ports'), or 'sim'"},
    {"firmware.baud", "--baud", Kind::Whole, 300, 4000000, "", "", "the firmware's baud rate"},
    {"firmware.flavor", "--flavor", Kind::Choice, 0, 0, "", "marlin|reprap|klipper", "the firmware"},
    {"firmware.window", "--window", Kind::Whole, 0, 64, "lines", "", "lines in flight; 0: 2, or learned from ADVANCED_OK"},
    {"firmware.rx_bytes", "--rx-bytes", Kind::Whole, 64, 1 << 20, "bytes", "",
     "bytes in flight at most: the firmware's serial receive buffer less one"},
    {"firmware.max_line", "--max-line", Kind::Whole, 32, 4096, "bytes", "", "the firmware's line buffer (Marlin MAX_CMD_SIZE)"},
    {"firmware.reply_timeout", "--reply-timeout", Kind::Number, 0.05, 600, "s", "",
     "seconds without a firmware reply while lines are in flight before it is probed"},
    {"firmware.long_timeout", "--long-timeout", Kind::Number, 1, 86400, "s", "",
     "RepRapFirmware: the same after homing, heating, dwelling"},
    {"firmware.boot_wait", "--boot-wait", Kind::Number, 0, 60, "s", "", "seconds to wait for the firmware's 'start' after opening the port"},
    {"firmware.max_timeouts", "--max-timeouts", Kind::Whole, 1, 1000, "", "", "probes in a row without a reply before the firmware is gone"},
    {"firmware.settle", "--settle", Kind::Number, 0.001, 60, "s", "", "seconds of quiet that end a resync or the greeting's wait"},
    {"firmware.nudge", "--nudge", Kind::Number, 0, 60, "s", "",
     "Marlin: seconds of silence with lines in flight before one empty line (ends a line whose newline was lost); 0: never"},
    {"firmware.max_greetings", "--max-greetings", Kind::Whole, 1, 100, "", "", "greeting attempts before the firmware is unresponsive"},
    {"firmware.max_resyncs", "--max-resyncs", Kind::Whole, 1, 100000, "", "",
     "resyncs in a row without a line acknowledged before the firmware lost its place"},
    {"sender.pty", "--pty", Kind::Text, 0, 0, "", "", "path of the symlink to the pseudo-terminal senders open"},
    {"sender.pty_group", "--pty-group", Kind::Text, 0, 0, "", "",
     "give the pseudo-terminal to this group, read-write (e.g. dialout, for OctoPrint)"},
    {"sender.tcp", "--tcp", Kind::Text, 0, 0, "", "", "also accept senders on HOST:PORT (port 0: any free one; loopback unless --allow-remote)"},
    {"sender.allow_remote", "--allow-remote", Kind::Switch, 0, 0, "", "", "allow --tcp and --http on an address other than loopback"},
    {"http", "--http", Kind::Text, 0, 0, "", "",
     "serve a read-only status page and JSON on HOST:PORT, without authentication (port 0: any free one; loopback unless --allow-remote)"},
    {"sender.queue_lines", "--queue-lines", Kind::Whole, 1, 1 << 20, "lines", "",
     "translated lines held for the firmware before a sender's ok waits"},
    {"sender.drain_timeout", "--drain-timeout", Kind::Number, 0, 86400, "s", "", "seconds SIGTERM waits for the queue to drain"},
    {"sender.busy_interval", "--busy-interval", Kind::Number, 0.1, 60, "s", "",
     "seconds between 'busy: processing' to a sender held by a full queue"},
    {"sender.hold_seconds", "--hold-seconds", Kind::Number, 0.01, 60, "s", "", "a pause this long in the sender's stream ends the look-back window"},
    {"sender.max_pending", "--max-pending", Kind::Whole, 2, 1 << 20, "lines", "",
     "lines a sender may write ahead of the queue before it is read no further"},
    {"sender.max_tcp", "--max-tcp", Kind::Whole, 1, 1024, "connections", "", "TCP senders connected at once; more are turned away"},
    {"sender.idle_seconds", "--idle-seconds", Kind::Number, 1, 86400, "s", "",
     "a TCP sender that sends nothing this long (and is not printing) is disconnected"},
    {"sim.flavor", "--sim-flavor", Kind::Choice, 0, 0, "", "marlin|reprap|klipper", "virtual printer personality"},
    {"sim.advanced_ok", "--sim-advanced-ok", Kind::Switch, 0, 0, "", "", "virtual printer: Marlin's ADVANCED_OK"},
    {"sim.buffer", "--sim-buffer", Kind::Whole, 1, 64, "lines", "", "virtual printer: command buffer (BUFSIZE)"},
    {"sim.planner", "--sim-planner", Kind::Whole, 1, 256, "moves", "", "virtual printer: planner slots"},
    {"sim.baud", "--sim-baud", Kind::Whole, 0, 4000000, "", "", "virtual printer: the link's speed, 0 for unlimited"},
    {"sim.usb", "--sim-usb", Kind::Switch, 0, 0, "", "", "virtual printer: a native-USB board (writes arrive whole, read once a 1 ms frame)"},
    {"sim.rx_size", "--sim-rx-size", Kind::Whole, 16, 1 << 20, "bytes", "", "virtual printer: serial receive buffer (RX_BUFFER_SIZE)"},
    {"sim.record", "--record", Kind::Text, 0, 0, "", "", "virtual printer: write every executed command to this file"},
    {"log.level", "--log-level", Kind::Choice, 0, 0, "", "trace|debug|info|warn|error", "how much the service logs"},
};

std::string bound_text(double v) {
    char buf[40];
    if (v == std::floor(v) && std::fabs(v) < 1e15) std::snprintf(buf, sizeof buf, "%.0f", v);
    else std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

bool is_choice(const ServeSetting& s, const std::string& v) {
    const std::string all = std::string("|") + s.choices + "|";
    return !v.empty() && v.find('|') == std::string::npos && all.find("|" + v + "|") != std::string::npos;
}

std::string choice_list(const ServeSetting& s) {
    std::string out, c = s.choices;
    std::size_t at = 0;
    while (true) {
        const auto bar = c.find('|', at);
        const std::string one = c.substr(at, bar == std::string::npos ? std::string::npos : bar - at);
        if (!out.empty()) out += bar == std::string::npos ? " or " : ", ";
        out += "\"" + one + "\"";
        if (bar == std::string::npos) break;
        at = bar + 1;
    }
    return out;
}

// The value of one setting once its form is known; the one place a value is stored.
struct Value {
    double number = 0;
    std::string text;
    bool on = false;
};

void store(ServeConfig& c, const std::string& k, const Value& v) {
    const auto whole = [&] { return static_cast<long long>(v.number); };  // checked within the row's bounds before
    if (k == "machine") c.machine = v.text;
    else if (k == "http") {
        if (!v.text.empty()) parse_tcp_endpoint(v.text);
        c.http = v.text;
    }
    else if (k == "compensation") c.compensation = v.text;
    else if (k == "tolerance") c.tolerance = v.number;
    else if (k == "mode") c.mode = v.text == "G43.4" ? OrientationMode::Angles : v.text == "G43.5" ? OrientationMode::Vector : OrientationMode::Joints;
    else if (k == "extruder_letter") {
        if (v.text.size() != 1 || !std::isalpha(static_cast<unsigned char>(v.text[0]))) throw SettingError("expected one letter");
        c.extruder_letter = char(std::toupper(static_cast<unsigned char>(v.text[0])));
    } else if (k == "firmware.port") c.port = v.text;
    else if (k == "firmware.baud") c.baud = int(whole());
    else if (k == "firmware.flavor") {
        c.firmware.reprap = v.text == "reprap";
        c.firmware.klipper = v.text == "klipper";
    }
    else if (k == "firmware.window") c.firmware.window = int(whole());
    else if (k == "firmware.rx_bytes") c.firmware.rx_bytes = std::size_t(whole());
    else if (k == "firmware.max_line") c.firmware.max_line = std::size_t(whole());
    else if (k == "firmware.reply_timeout") c.firmware.reply_timeout = v.number;
    else if (k == "firmware.long_timeout") c.firmware.long_timeout = v.number;
    else if (k == "firmware.boot_wait") c.firmware.boot_wait = v.number;
    else if (k == "firmware.max_timeouts") c.firmware.max_timeouts = int(whole());
    else if (k == "firmware.settle") c.firmware.settle = v.number;
    else if (k == "firmware.nudge") c.firmware.nudge = v.number;
    else if (k == "firmware.max_greetings") c.firmware.max_greetings = int(whole());
    else if (k == "firmware.max_resyncs") c.firmware.max_resyncs = int(whole());
    else if (k == "sender.pty") c.pty = v.text;
    else if (k == "sender.pty_group") c.pty_group = v.text;
    else if (k == "sender.tcp") {
        if (!v.text.empty()) parse_tcp_endpoint(v.text);
        c.tcp = v.text;
    } else if (k == "sender.allow_remote") c.allow_remote = v.on;
    else if (k == "sender.queue_lines") c.queue_lines = std::size_t(whole());
    else if (k == "sender.drain_timeout") c.drain_timeout = v.number;
    else if (k == "sender.busy_interval") c.busy_interval = v.number;
    else if (k == "sender.hold_seconds") c.hold_seconds = v.number;
    else if (k == "sender.max_pending") c.max_pending = std::size_t(whole());
    else if (k == "sender.max_tcp") c.max_tcp = std::size_t(whole());
    else if (k == "sender.idle_seconds") c.idle_seconds = v.number;
    else if (k == "sim.flavor") {
        c.sim.reprap = v.text == "reprap";
        c.sim.klipper = v.text == "klipper";
    }
    else if (k == "sim.advanced_ok") c.sim.advanced_ok = v.on;
    else if (k == "sim.buffer") c.sim.buffer = int(whole());
    else if (k == "sim.planner") c.sim.planner = int(whole());
    else if (k == "sim.baud") c.sim.baud = int(whole());
    else if (k == "sim.usb") c.sim.usb = v.on;
    else if (k == "sim.rx_size") c.sim.rx_size = std::size_t(whole());
    else if (k == "sim.record") c.sim.record_path = v.text;
    else if (k == "log.level") c.log_level = v.text;
    else throw std::logic_error("serve setting without a store: " + k);
}

// A number of a Number or Whole row: finite, whole when asked, within the bounds.
void check_number(const ServeSetting& s, double d, const std::string& as_written) {
    const bool whole = s.kind == Kind::Whole;
    if (std::isfinite(d) && d >= s.lo && d <= s.hi && (!whole || d == std::floor(d))) return;
    throw SettingError("'" + as_written + "' is not " + (whole ? "a whole number " : "a number ") + serve_setting_range(s));
}

void check_text(const ServeSetting& s, const std::string& t) {
    if (s.kind == Kind::Choice && !is_choice(s, t)) throw SettingError("expected " + choice_list(s) + ", got '" + t + "'");
}

}  // namespace

const std::vector<ServeSetting>& serve_settings() { return kSettings; }

const ServeSetting* find_serve_setting(const std::string& key) {
    for (const auto& s : kSettings)
        if (key == s.key) return &s;
    return nullptr;
}

std::string serve_setting_range(const ServeSetting& s) {
    return "from " + bound_text(s.lo) + " to " + bound_text(s.hi) + (*s.unit ? std::string(" (") + s.unit + ")" : "");
}

void apply_serve_setting(ServeConfig& c, const ServeSetting& s, const std::string& text) {
    Value v;
    switch (s.kind) {
        case Kind::Number:
        case Kind::Whole: {
            errno = 0;
            char* end = nullptr;
            const double d = std::strtod(text.c_str(), &end);
            if (text.empty() || !end || *end || errno == ERANGE) check_number(s, NAN, text);
            check_number(s, d, text);
            v.number = d;
            break;
        }
        case Kind::Switch:
            if (text == "true" || text == "on" || text == "1") v.on = true;
            else if (text == "false" || text == "off" || text == "0") v.on = false;
            else throw SettingError("expected true or false, got '" + text + "'");
            break;
        case Kind::Text:
        case Kind::Choice:
            check_text(s, text);
            v.text = text;
            break;
    }
    store(c, s.key, v);
}

std::string serve_setting_text(const ServeConfig& c, const ServeSetting& s) {
    const std::string k = s.key;
    const auto num = [](double d) { return bound_text(d); };
    if (k == "machine") return c.machine;
    if (k == "http") return c.http;
    if (k == "compensation") return c.compensation;
    if (k == "tolerance") return num(c.tolerance);
    if (k == "mode") return !c.mode ? "" : *c.mode == OrientationMode::Angles ? "G43.4" : *c.mode == OrientationMode::Vector ? "G43.5" : "G49";
    if (k == "extruder_letter") return std::string(1, c.extruder_letter);
    if (k == "firmware.port") return c.port;
    if (k == "firmware.baud") return num(c.baud);
    if (k == "firmware.flavor") return c.firmware.reprap ? "reprap" : c.firmware.klipper ? "klipper" : "marlin";
    if (k == "firmware.window") return num(c.firmware.window);
    if (k == "firmware.rx_bytes") return num(double(c.firmware.rx_bytes));
    if (k == "firmware.max_line") return num(double(c.firmware.max_line));
    if (k == "firmware.reply_timeout") return num(c.firmware.reply_timeout);
    if (k == "firmware.long_timeout") return num(c.firmware.long_timeout);
    if (k == "firmware.boot_wait") return num(c.firmware.boot_wait);
    if (k == "firmware.max_timeouts") return num(c.firmware.max_timeouts);
    if (k == "firmware.settle") return num(c.firmware.settle);
    if (k == "firmware.nudge") return num(c.firmware.nudge);
    if (k == "firmware.max_greetings") return num(c.firmware.max_greetings);
    if (k == "firmware.max_resyncs") return num(c.firmware.max_resyncs);
    if (k == "sender.pty") return c.pty;
    if (k == "sender.pty_group") return c.pty_group;
    if (k == "sender.tcp") return c.tcp;
    if (k == "sender.allow_remote") return c.allow_remote ? "true" : "false";
    if (k == "sender.queue_lines") return num(double(c.queue_lines));
    if (k == "sender.drain_timeout") return num(c.drain_timeout);
    if (k == "sender.busy_interval") return num(c.busy_interval);
    if (k == "sender.hold_seconds") return num(c.hold_seconds);
    if (k == "sender.max_pending") return num(double(c.max_pending));
    if (k == "sender.max_tcp") return num(double(c.max_tcp));
    if (k == "sender.idle_seconds") return num(c.idle_seconds);
    if (k == "sim.flavor") return c.sim.reprap ? "reprap" : c.sim.klipper ? "klipper" : "marlin";
    if (k == "sim.advanced_ok") return c.sim.advanced_ok ? "true" : "false";
    if (k == "sim.buffer") return num(c.sim.buffer);
    if (k == "sim.planner") return num(c.sim.planner);
    if (k == "sim.baud") return num(c.sim.baud);
    if (k == "sim.usb") return c.sim.usb ? "true" : "false";
    if (k == "sim.rx_size") return num(double(c.sim.rx_size));
    if (k == "sim.record") return c.sim.record_path;
    if (k == "log.level") return c.log_level;
    throw std::logic_error("serve setting without a text: " + k);
}

TcpEndpoint parse_tcp_endpoint(const std::string& text) {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos || colon == 0) throw SettingError("expected HOST:PORT, e.g. 127.0.0.1:8250, got '" + text + "'");
    const std::string port = text.substr(colon + 1);
    const bool digits = !port.empty() && port.size() <= 5 && port.find_first_not_of("0123456789") == std::string::npos;
    const long value = digits ? std::strtol(port.c_str(), nullptr, 10) : -1;
    if (value < 0 || value > 65535)
        throw SettingError("'" + port + "' in '" + text + "' is not a port number from 0 to 65535 (0: any free port)");
    TcpEndpoint e;
    e.host = text.substr(0, colon);
    e.port = static_cast<unsigned short>(value);
    return e;
}

void set_sim_fault(SimFaults& f, const std::string& a) {
    const auto eq = a.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("expected NAME=VALUE, got '" + a + "'");
    const std::string v = a.substr(eq + 1);
    errno = 0;
    char* end = nullptr;
    const double d = std::strtod(v.c_str(), &end);
    if (v.empty() || *end || errno == ERANGE || !std::isfinite(d)) throw std::invalid_argument("'" + v + "' is not a number in '" + a + "'");
    set_sim_fault(f, a.substr(0, eq), d);
}

void set_sim_fault(SimFaults& f, const std::string& k, double d) {
    if (!(d >= 0)) throw std::invalid_argument("must not be negative");
    const auto probability = [&](double& out) {
        if (d > 1) throw std::invalid_argument("a probability must be between 0 and 1");
        out = d;
    };
    const auto seconds = [&](double& out) {
        if (d > 3600) throw std::invalid_argument("must be at most 3600 seconds");
        out = d;
    };
    const auto milliseconds = [&](double& out, double most) {
        if (d > most) throw std::invalid_argument("must be at most " + std::to_string(int(most)) + " ms");
        out = d;
    };
    // Counts: whole numbers up to 2^53, where a double still holds every integer.
    const auto count = [&](std::uint64_t& out) {
        if (d != std::floor(d) || d > 9007199254740992.0) throw std::invalid_argument("expected a whole number up to 2^53");
        out = std::uint64_t(d);
    };
    if (k == "corrupt") probability(f.corrupt);
    else if (k == "drop") probability(f.drop);
    else if (k == "lose_newline") probability(f.lose_newline);
    else if (k == "lose_ok") probability(f.lose_ok);
    else if (k == "garble_reply") probability(f.garble_reply);
    else if (k == "spurious_resend") probability(f.spurious_resend);
    else if (k == "no_ok_after_resend") f.no_ok_after_resend = d != 0;
    else if (k == "greeting_resend") f.greeting_resend = d != 0;
    else if (k == "quiet_planner") f.quiet_planner = d != 0;
    else if (k == "junk_position") f.junk_position = d != 0;
    else if (k == "stale_oks") count(f.stale_oks);
    else if (k == "busy") probability(f.busy);
    else if (k == "busy_seconds") seconds(f.busy_seconds);
    else if (k == "busy_interval") seconds(f.busy_interval);
    else if (k == "move_ms") milliseconds(f.move_ms, 3600);
    else if (k == "slow_seconds") seconds(f.slow_seconds);
    else if (k == "command_ms") milliseconds(f.command_ms, 10000);
    else if (k == "reset_after") count(f.reset_after);
    else if (k == "reset_every") count(f.reset_every);
    else if (k == "kill_after") count(f.kill_after);
    else if (k == "stop_after") count(f.stop_after);
    else if (k == "unplug_after") count(f.unplug_after);
    else if (k == "seed") count(f.seed);
    else throw std::invalid_argument("unknown fault '" + k + "'");
}

ServeConfig load_serve_config(const std::string& path) {
    std::string text;
    try {
        text = read_small_file(path, kMaxConfigBytes, "a configuration file");
    } catch (const IoError& e) {
        throw MachineError(e.what());
    } catch (const InputError& e) {
        throw MachineError(e.what());
    }
    toml::table root;
    try {
        root = toml::parse(text, path);
    } catch (const toml::parse_error& e) {
        std::ostringstream os;
        os << path << ":" << e.source().begin.line << ": " << e.description();
        throw MachineError(os.str());
    }
    const auto fail = [&path](const toml::node* node, const std::string& key, const std::string& why) {
        std::ostringstream os;
        os << path;
        if (node && node->source().begin.line) os << ":" << node->source().begin.line;
        os << ": " << key << ": " << why;
        throw MachineError(os.str());
    };
    // Every key in the file must be one of the table's: a typo is an error, not a silent default.
    const auto check_known = [&](const toml::table& t, const std::string& prefix) {
        for (const auto& [k, v] : t) {
            const std::string key = prefix + std::string(k.str());
            const bool section = prefix.empty() && (key == "firmware" || key == "sender" || key == "sim" || key == "log");
            if (!section && key != "sim.faults" && !find_serve_setting(key)) fail(&v, key, "unknown setting");
        }
    };
    check_known(root, "");
    for (const char* section : {"firmware", "sender", "sim", "log"}) {
        if (auto* n = root.get(section)) {
            if (!n->is_table()) fail(n, section, "expected a table ([" + std::string(section) + "])");
            check_known(*n->as_table(), std::string(section) + ".");
        }
    }

    ServeConfig c;
    c.source = path;
    for (const auto& s : serve_settings()) {
        const toml::node* n = root.at_path(s.key).node();
        if (!n) continue;
        Value v;
        try {
            switch (s.kind) {
                case Kind::Number: {
                    const auto d = n->value<double>();
                    if (!d || !(n->is_floating_point() || n->is_integer())) fail(n, s.key, "expected a number");
                    check_number(s, *d, bound_text(*d));
                    v.number = *d;
                    break;
                }
                case Kind::Whole: {
                    const auto i = n->value<long long>();
                    if (!i || !n->is_integer()) fail(n, s.key, "expected a whole number");
                    check_number(s, double(*i), std::to_string(*i));
                    v.number = double(*i);
                    break;
                }
                case Kind::Switch: {
                    const auto b = n->value<bool>();
                    if (!b) fail(n, s.key, "expected true or false");
                    v.on = *b;
                    break;
                }
                case Kind::Text:
                case Kind::Choice: {
                    const auto t = n->value<std::string>();
                    if (!t || !n->is_string()) fail(n, s.key, "expected a string");
                    check_text(s, *t);
                    v.text = *t;
                    break;
                }
            }
            // An extruder letter left empty in the file means the default.
            if (std::string(s.key) == "extruder_letter" && v.text.empty()) continue;
            store(c, s.key, v);
        } catch (const SettingError& e) {
            fail(n, s.key, e.what());
        }
    }
    if (auto* faults = root.at_path("sim.faults").node()) {
        if (!faults->is_table()) fail(faults, "sim.faults", "expected a table ([sim.faults])");
        for (const auto& [k, v] : *faults->as_table()) {
            auto d = v.value<double>();
            if (!d) fail(&v, "sim.faults." + std::string(k.str()), "expected a number");
            try {
                set_sim_fault(c.sim.faults, std::string(k.str()), *d);
            } catch (const std::invalid_argument& e) {
                fail(&v, "sim.faults." + std::string(k.str()), e.what());
            }
        }
    }
    return c;
}

}  // namespace xlate5
