#include "daemon/config.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <toml++/toml.h>

#include "translators/error.hpp"

namespace xlate5 {
namespace {

class ConfigReader {
public:
    ConfigReader(const toml::table& root, std::string path) : root_(root), path_(std::move(path)) {}

    [[noreturn]] void fail(const toml::node* node, const std::string& key, const std::string& why) const {
        std::ostringstream os;
        os << path_;
        if (node && node->source().begin.line) os << ":" << node->source().begin.line;
        os << ": " << key << ": " << why;
        throw MachineError(os.str());
    }
    const toml::node* find(const std::string& dotted) const { return root_.at_path(dotted).node(); }

    void get(const std::string& key, std::string& out) const {
        if (auto* n = find(key)) {
            auto v = n->value<std::string>();
            if (!v) fail(n, key, "expected a string");
            out = *v;
        }
    }
    void get(const std::string& key, double& out, double lo, double hi) const {
        if (auto* n = find(key)) {
            auto v = n->value<double>();
            if (!v) fail(n, key, "expected a number");
            if (!(*v >= lo && *v <= hi)) fail(n, key, "must be between " + num(lo) + " and " + num(hi));
            out = *v;
        }
    }
    template <class Int>
    void get_int(const std::string& key, Int& out, long long lo, long long hi) const {
        if (auto* n = find(key)) {
            auto v = n->value<long long>();
            if (!v || !n->is_integer()) fail(n, key, "expected a whole number");
            if (*v < lo || *v > hi) fail(n, key, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
            out = Int(*v);
        }
    }
    void get(const std::string& key, bool& out) const {
        if (auto* n = find(key)) {
            auto v = n->value<bool>();
            if (!v) fail(n, key, "expected true or false");
            out = *v;
        }
    }
    // Every key in the file must be one this reader knows: a typo is an error, not a silent default.
    void check_known(const toml::table& t, const std::string& prefix, const std::vector<std::string>& known) const {
        for (const auto& [k, v] : t) {
            const std::string key = prefix + std::string(k.str());
            bool ok = false;
            for (const auto& n : known) ok = ok || n == key;
            if (!ok) fail(&v, key, "unknown setting");
        }
    }
    static std::string num(double v) {
        std::ostringstream os;
        os << v;
        return os.str();
    }

private:
    const toml::table& root_;
    std::string path_;
};

}  // namespace

void set_sim_fault(SimFaults& f, const std::string& a) {
    const auto eq = a.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("expected NAME=VALUE, got '" + a + "'");
    const std::string v = a.substr(eq + 1);
    char* end = nullptr;
    const double d = std::strtod(v.c_str(), &end);
    if (v.empty() || *end) throw std::invalid_argument("'" + v + "' is not a number in '" + a + "'");
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
    else if (k == "stale_oks") count(f.stale_oks);
    else if (k == "busy") probability(f.busy);
    else if (k == "busy_seconds") seconds(f.busy_seconds);
    else if (k == "busy_interval") seconds(f.busy_interval);
    else if (k == "move_ms") seconds(f.move_ms);
    else if (k == "slow_seconds") seconds(f.slow_seconds);
    else if (k == "reset_after") count(f.reset_after);
    else if (k == "kill_after") count(f.kill_after);
    else if (k == "stop_after") count(f.stop_after);
    else if (k == "unplug_after") count(f.unplug_after);
    else if (k == "seed") count(f.seed);
    else throw std::invalid_argument("unknown fault '" + k + "'");
}

ServeConfig load_serve_config(const std::string& path) {
    toml::table root;
    try {
        root = toml::parse_file(path);
    } catch (const toml::parse_error& e) {
        std::ostringstream os;
        os << path << ":" << e.source().begin.line << ": " << e.description();
        throw MachineError(os.str());
    }
    ConfigReader r(root, path);
    r.check_known(root, "", {"machine", "compensation", "tolerance", "mode", "extruder_letter", "firmware", "sender", "sim", "log"});
    if (auto* t = root["firmware"].as_table())
        r.check_known(*t, "firmware.", {"firmware.port", "firmware.baud", "firmware.flavor", "firmware.window", "firmware.rx_bytes",
                                        "firmware.max_line", "firmware.reply_timeout", "firmware.long_timeout", "firmware.boot_wait", "firmware.max_timeouts",
                                        "firmware.settle", "firmware.max_greetings", "firmware.max_resyncs"});
    if (auto* t = root["sender"].as_table())
        r.check_known(*t, "sender.", {"sender.pty", "sender.pty_group", "sender.tcp", "sender.allow_remote", "sender.queue_lines", "sender.drain_timeout", "sender.busy_interval",
                                      "sender.hold_seconds", "sender.max_pending"});
    if (auto* t = root["sim"].as_table())
        r.check_known(*t, "sim.", {"sim.flavor", "sim.advanced_ok", "sim.buffer", "sim.planner", "sim.baud", "sim.record", "sim.faults", "sim.rx_size"});
    if (auto* t = root["log"].as_table()) r.check_known(*t, "log.", {"log.level"});

    ServeConfig c;
    c.source = path;
    r.get("machine", c.machine);
    r.get("compensation", c.compensation);
    r.get("tolerance", c.tolerance, 0, 10);
    std::string mode;
    r.get("mode", mode);
    if (mode == "G43.4") c.mode = OrientationMode::Angles;
    else if (mode == "G43.5") c.mode = OrientationMode::Vector;
    else if (mode == "G49") c.mode = OrientationMode::Joints;
    else if (!mode.empty()) r.fail(r.find("mode"), "mode", "expected \"G43.4\", \"G43.5\" or \"G49\"");
    std::string letter;
    r.get("extruder_letter", letter);
    if (!letter.empty()) {
        if (letter.size() != 1 || !std::isalpha(static_cast<unsigned char>(letter[0])))
            r.fail(r.find("extruder_letter"), "extruder_letter", "expected one letter");
        c.extruder_letter = char(std::toupper(static_cast<unsigned char>(letter[0])));
    }
    r.get("firmware.port", c.port);
    r.get_int("firmware.baud", c.baud, 300, 4000000);
    std::string flavor = "marlin";
    r.get("firmware.flavor", flavor);
    if (flavor != "marlin" && flavor != "reprap") r.fail(r.find("firmware.flavor"), "firmware.flavor", "expected \"marlin\" or \"reprap\"");
    c.firmware.reprap = flavor == "reprap";
    r.get_int("firmware.window", c.firmware.window, 0, 64);
    r.get_int("firmware.rx_bytes", c.firmware.rx_bytes, 64, 1 << 20);
    r.get_int("firmware.max_line", c.firmware.max_line, 32, 4096);
    r.get("firmware.reply_timeout", c.firmware.reply_timeout, 0.05, 600);
    r.get("firmware.long_timeout", c.firmware.long_timeout, 1, 86400);
    r.get("firmware.boot_wait", c.firmware.boot_wait, 0, 60);
    r.get_int("firmware.max_timeouts", c.firmware.max_timeouts, 1, 1000);
    r.get("firmware.settle", c.firmware.settle, 0.001, 60);
    r.get_int("firmware.max_greetings", c.firmware.max_greetings, 1, 100);
    r.get_int("firmware.max_resyncs", c.firmware.max_resyncs, 1, 100000);
    r.get("sender.pty", c.pty);
    r.get("sender.pty_group", c.pty_group);
    r.get("sender.tcp", c.tcp);
    r.get("sender.allow_remote", c.allow_remote);
    r.get_int("sender.queue_lines", c.queue_lines, 1, 1 << 20);
    r.get("sender.drain_timeout", c.drain_timeout, 0, 86400);
    r.get("sender.busy_interval", c.busy_interval, 0.1, 60);
    r.get("sender.hold_seconds", c.hold_seconds, 0.01, 60);
    r.get_int("sender.max_pending", c.max_pending, 2, 1 << 20);
    std::string sim_flavor = "marlin";
    r.get("sim.flavor", sim_flavor);
    if (sim_flavor != "marlin" && sim_flavor != "reprap") r.fail(r.find("sim.flavor"), "sim.flavor", "expected \"marlin\" or \"reprap\"");
    c.sim.reprap = sim_flavor == "reprap";
    r.get("sim.advanced_ok", c.sim.advanced_ok);
    r.get_int("sim.buffer", c.sim.buffer, 1, 64);
    r.get_int("sim.planner", c.sim.planner, 1, 256);
    r.get_int("sim.baud", c.sim.baud, 0, 4000000);
    r.get_int("sim.rx_size", c.sim.rx_size, 16, 1 << 20);
    r.get("sim.record", c.sim.record_path);
    if (auto* t = root.at_path("sim.faults").as_table()) {
        for (const auto& [k, v] : *t) {
            auto d = v.value<double>();
            if (!d) r.fail(&v, "sim.faults." + std::string(k.str()), "expected a number");
            try {
                set_sim_fault(c.sim.faults, std::string(k.str()), *d);
            } catch (const std::invalid_argument& e) {
                r.fail(&v, "sim.faults." + std::string(k.str()), e.what());
            }
        }
    }
    r.get("log.level", c.log_level);
    return c;
}

}  // namespace xlate5
