// SPDX-License-Identifier: GPL-3.0-or-later
// The service's configuration (`config/xlate5.toml`, documented there): which machine, the
// firmware's port, the sender endpoints, the virtual printer. Command-line flags override it.
// Stage: configuration, read before the service starts; may call the machine loader's types only.
// Every setting is one row of one table (serve_settings()): its key in the file, its flag, its
// bounds. The file and the flags are checked by the same rows, so no value reaches a cast
// unchecked by either way in.
#pragma once
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "daemon/firmware_link.hpp"
#include "daemon/sender_limits.hpp"
#include "daemon/virtual_printer.hpp"
#include "translators/machine/machine.hpp"

namespace xlate5 {

// Its sender.* settings are the SenderLimits the service takes.
struct ServeConfig : SenderLimits {
    std::string source;                 // the file it was read from ("" for defaults)
    std::string machine;                // required: no machine decides moves by default
    std::string http;                   // HOST:PORT of the read-only status page; empty: none
    std::string compensation;           // a compensation file replacing the machine's own
    double tolerance = 0;               // 0: the machine's
    std::optional<OrientationMode> mode;  // the orientation mode senders' files start in (default: the machine's)
    char extruder_letter = 'E';         // the input letter that carries extrusion
    // Firmware
    std::string port;                   // a serial device, or "sim" for the built-in virtual printer; required
    int baud = 115200;
    FirmwareOptions firmware;
    // Senders
    std::string pty = "/run/xlate5/printer";  // symlink to the pseudo-terminal senders open ("" for none)
    std::string pty_group;              // give the pseudo-terminal to this group ("" : the service's own)
    std::string tcp;                    // "host:port" ("" for none)
    bool allow_remote = false;          // binding beyond loopback must be asked for
    double drain_timeout = 60;          // seconds SIGTERM waits for the queue to drain
    // Virtual printer
    SimOptions sim;
    std::string log_level = "info";
};

// A value refused by a setting's bounds or form; the message is the cause only (the caller adds
// where it came from: "file:line: key: " or "--flag: ").
struct SettingError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// One setting of `xlate5 serve`.
struct ServeSetting {
    enum class Kind { Text, Number, Whole, Switch, Choice };
    const char* key;      // in the configuration file: "firmware.reply_timeout"
    const char* names;    // the command line's: "--reply-timeout" (CLI11 spelling, e.g. "-m,--machine")
    Kind kind;
    double lo, hi;        // Number, Whole: inclusive bounds
    const char* unit;     // of the bounds, for messages and the help ("s", "bytes", "")
    const char* choices;  // Choice: "marlin|reprap"
    const char* help;
};
const std::vector<ServeSetting>& serve_settings();
const ServeSetting* find_serve_setting(const std::string& key);

// Sets `s` in `c` from text (a flag's argument): a number must be finite and within the bounds,
// a whole number whole, a choice one of the choices. Throws SettingError.
void apply_serve_setting(ServeConfig& c, const ServeSetting& s, const std::string& text);
// The setting's value in `c` as text (the help's defaults, `serve --check`).
std::string serve_setting_text(const ServeConfig& c, const ServeSetting& s);
// "from 0.05 to 600 (s)": the bounds as the help and the errors write them.
std::string serve_setting_range(const ServeSetting& s);

// "host:port" split and checked: a port from 0 (any free port) to 65535. Throws SettingError.
struct TcpEndpoint {
    std::string host;
    unsigned short port = 0;
};
TcpEndpoint parse_tcp_endpoint(const std::string& text);

// The largest configuration file read (docs/limits.md); the shipped one, every key commented, is 7 KiB.
inline constexpr std::size_t kMaxConfigBytes = 64u << 10;

// Reads a configuration file. Throws MachineError-style errors: "path:line: key: cause".
ServeConfig load_serve_config(const std::string& path);

// Applies "key=value" overrides of the virtual printer's faults, e.g. "corrupt=0.01".
void set_sim_fault(SimFaults& f, const std::string& assignment);
void set_sim_fault(SimFaults& f, const std::string& name, double value);

}  // namespace xlate5
