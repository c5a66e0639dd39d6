// The service's configuration (`config/xlate5.toml`, documented there): which machine, the
// firmware's port, the sender endpoints, the virtual printer. Command-line flags override it.
#pragma once
#include <optional>
#include <string>

#include "daemon/firmware_link.hpp"
#include "daemon/virtual_printer.hpp"
#include "translators/machine.hpp"

namespace xlate5 {

struct ServeConfig {
    std::string source;                 // the file it was read from ("" for defaults)
    std::string machine = "rw2";
    std::string compensation;           // a compensation file replacing the machine's own
    double tolerance = 0;               // 0: the machine's
    std::optional<OrientationMode> mode;  // the orientation mode senders' files start in (default: the machine's)
    char extruder_letter = 'E';         // the input letter that carries extrusion
    // Firmware
    std::string port = "sim";           // a serial device, or "sim" for the built-in virtual printer
    int baud = 115200;
    FirmwareOptions firmware;
    // Senders
    std::string pty = "/run/xlate5/printer";  // symlink to the pseudo-terminal senders open ("" for none)
    std::string pty_group;              // give the pseudo-terminal to this group ("" : the service's own)
    std::string tcp;                    // "host:port" ("" for none)
    bool allow_remote = false;          // binding beyond loopback must be asked for
    std::size_t queue_lines = 64;
    double busy_interval = 2;           // seconds between "busy: processing" to a sender held by a full queue
    double hold_seconds = 1;            // a pause this long in the stream ends the look-back window
    std::size_t max_pending = 256;      // lines a sender may write ahead before it is read no further
    double drain_timeout = 60;          // seconds SIGTERM waits for the queue to drain
    // Virtual printer
    SimOptions sim;
    std::string log_level = "info";
};

// Reads a configuration file. Throws MachineError-style errors: "path:line: key: cause".
ServeConfig load_serve_config(const std::string& path);

// Applies "key=value" overrides of the virtual printer's faults, e.g. "corrupt=0.01".
void set_sim_fault(SimFaults& f, const std::string& assignment);
void set_sim_fault(SimFaults& f, const std::string& name, double value);

}  // namespace xlate5
