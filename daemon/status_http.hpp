// SPDX-License-Identifier: GPL-3.0-or-later
// `serve --http HOST:PORT`: a read-only status page and its JSON over HTTP/1.1, a thin
// Boost.Beast adapter on the service's io_context (stage: the service's edge; may call Asio and
// Beast, never the service itself: serve.cpp hands it a function that writes the JSON).
// GET / (the page), GET /status.js (its script), GET /status.json; HEAD of each; every other
// method is 405 and nothing changes anything. No authentication (docs/service.md).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "daemon/link.hpp"  // Asio, with Boost 1.74's include-order fix

namespace xlate5 {

// What the JSON says, gathered by serve.cpp from the service (all read-only copies).
struct StatusSnapshot {
    std::string version, machine;
    std::string state;        // "starting", "waiting for port", "idle", "reading position", "printing", "stopped"
    std::string stop_reason;  // when stopped
    std::string port, firmware_state;  // firmware_state: "booting", "greeting", "ready", "faulted", "" (no firmware yet)
    std::uint64_t queued = 0, window = 0, sent = 0, acked = 0, resends = 0, timeouts = 0;
    std::optional<double> link_busy_percent;  // share of the wire's capacity used over the last sample
    std::string sender;       // the sender printing, empty when none
    std::int64_t line = -1;   // its last numbered line
    std::uint64_t lines_from_senders = 0, lines_to_firmware = 0, refused = 0, cancelled = 0, faults = 0;
    std::vector<std::string> joint_names;
    std::vector<double> joints;                 // the last translated line's joints
    std::optional<std::array<double, 6>> pose;  // tip x y z, tool axis i j k (part frame)
    std::string last_error;
};

std::string status_json(const StatusSnapshot& s);

struct StatusHttpOptions {
    std::size_t max_connections = 8;       // open at once; more are answered 503 and closed
    std::size_t max_header_bytes = 8192;   // request line and headers; past it 431
    double idle_seconds = 10;              // a connection quiet this long is closed
};

class StatusHttp {
public:
    // Binds at once (throws IoError naming the address and the cause); serves from the next run
    // of `io`. `json` is called for each GET /status.json.
    StatusHttp(asio::io_context& io, const std::string& host_port, bool allow_remote, std::function<std::string()> json,
               StatusHttpOptions options = {});
    ~StatusHttp();
    StatusHttp(const StatusHttp&) = delete;
    StatusHttp& operator=(const StatusHttp&) = delete;
    std::string url() const;  // http://HOST:PORT/ with the bound port

    struct Impl;  // the acceptor and the count of open connections (status_http.cpp)

private:
    std::shared_ptr<Impl> impl_;
};

}  // namespace xlate5
