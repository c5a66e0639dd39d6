// SPDX-License-Identifier: GPL-3.0-or-later
// `xlate5 serve` and `xlate5 ports`: the service's lifecycle (ports, endpoints, signals,
// logging) around the Service.
#pragma once
#include "daemon/config.hpp"

#include <memory>
#include <optional>

#include "daemon/ports.hpp"
#include "daemon/service.hpp"
#include "daemon/virtual_printer.hpp"

namespace xlate5 {

// The service and its ends, wired as `xlate5 serve` wires them (tests build the same thing).
struct Assembly {
    std::unique_ptr<Pty> sim_pty, sender_pty;
    std::unique_ptr<SerialPort> port;
    std::shared_ptr<VirtualPrinter> sim;
    std::unique_ptr<Service> service;
    std::optional<asio::ip::tcp::acceptor> acceptor;
    std::shared_ptr<std::function<void()>> accept_next;
};
// Opens the firmware port (or starts the virtual printer), the sender pseudo-terminal and TCP
// endpoint. Throws IoError naming the port or address and the cause.
void assemble(asio::io_context& io, const ServeConfig& config, const Machine& machine, Assembly& a);

// Runs until SIGTERM/SIGINT (queue drained, or stopped between lines after drain_timeout).
// Returns the process exit code.
int run_serve(const ServeConfig& config);

// `serve --check FILE`: prints what serve would do with the file that offline translation does
// not, and the link settings it would use; opens nothing. 0 when serve prints the file exactly
// as offline translation does, 1 when not, 3 for a broken machine, 4 for an unreadable file.
// A line longer than serve's bound (Link::kMaxLine) is where serve would cancel the print, and
// nothing after it is read. The check holds the file and its translation (three copies of it) in
// memory, unlike serve, which streams: it refuses a file past these bounds (docs/limits.md).
inline constexpr std::uint64_t kMaxCheckBytes = 32u << 20;       // of input
inline constexpr std::uint64_t kMaxCheckLines = 1u << 21;        // of input
inline constexpr std::uint64_t kMaxCheckOutputBytes = 32u << 20;  // of its translation
int run_serve_check(const ServeConfig& config, const std::string& path);

// Lists serial ports with their USB vendor/product and description.
int run_ports();

}  // namespace xlate5
