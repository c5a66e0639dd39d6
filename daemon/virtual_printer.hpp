// A virtual printer: a Marlin-like or RepRapFirmware-like firmware on the far end of a
// pseudo-terminal, so the whole service runs with no hardware (`--printer sim`) and tests can
// inject every fault a real link shows. It records every command it executes, in order, so a
// test can prove that nothing was lost, duplicated or reordered on the way.
#pragma once
#include <cstdint>
#include <deque>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "daemon/link.hpp"

namespace xlate5 {

struct SimFaults {
    double corrupt = 0;          // per received line: one byte flipped (line noise)
    double drop = 0;             // per received line: a run of bytes lost (possibly the '\n')
    double garble_reply = 0;     // per reply line: a byte flipped on the way back
    double spurious_resend = 0;  // per accepted line: refuse it anyway with Resend (as after noise)
    bool no_ok_after_resend = false;  // some Marlin versions send Resend without an ok
    double busy = 0;             // per executed move: a busy period with "busy: processing" keepalives
    double busy_seconds = 3;
    double busy_interval = 1;    // seconds between keepalives (Marlin: 2)
    double move_ms = 0;          // time each planned move takes: a slow planner holds oks back when full
    double slow_seconds = 0;     // G28, G4, M109, M190, M400 take this long (Marlin: with keepalives; RRF: silent)
    std::uint64_t reset_after = 0;   // after executing this many lines: reboot ("start", state lost)
    std::uint64_t kill_after = 0;    // after this many: "Error:Printer halted. kill() called!"
    std::uint64_t unplug_after = 0;  // after this many: the port disappears
    std::uint64_t seed = 1;
};

struct SimOptions {
    bool reprap = false;       // RepRapFirmware personality (drops bad lines silently)
    bool advanced_ok = false;  // Marlin ADVANCED_OK: "ok N<n> P<p> B<b>"
    int buffer = 4;            // command buffer (BUFSIZE)
    int planner = 16;          // planner slots
    std::string axes = "XYZAB";  // the firmware's axis letters
    int baud = 0;              // 0: unlimited; else lines arrive no faster than baud/10 bytes per second
    SimFaults faults;
    std::string record_path;   // write executed commands here, one a line
    bool keep_executed = false;  // also keep them in memory (tests); off, memory stays flat however long the print
    std::size_t max_line = 96; // a longer line is cut (MAX_CMD_SIZE)
};

struct SimStats {
    std::uint64_t received = 0, executed = 0, refused = 0, dropped = 0, corrupted = 0, garbled = 0, resets = 0;
    std::uint64_t bytes = 0;  // received, newlines included
};

class VirtualPrinter : public std::enable_shared_from_this<VirtualPrinter> {
public:
    // Takes the master side of a pseudo-terminal; xlate5 opens the slave as its serial port.
    VirtualPrinter(asio::io_context& io, int master_fd, SimOptions options);
    ~VirtualPrinter();
    void start();   // boots: sends "start" and the echo lines
    void unplug();  // the port vanishes
    const std::vector<std::string>& executed() const { return executed_; }  // with keep_executed
    const SimStats& stats() const { return stats_; }
    bool halted() const { return halted_; }

private:
    struct Command { std::string text; std::int64_t n; };
    void on_line(std::string_view raw);
    void accept(std::string_view line);
    void refuse(const char* why);
    void run_queue();
    void pump_wire();
    void execute(const Command& c);
    void reply(std::string line);
    void boot();
    std::string position_report() const;

    std::shared_ptr<DescriptorLink> link_;
    SimOptions opt_;
    std::mt19937_64 rng_;
    std::uniform_real_distribution<double> uni_{0.0, 1.0};
    std::int64_t last_n_ = 0;
    std::deque<Command> buffer_;          // accepted, not yet executed
    std::deque<std::chrono::steady_clock::time_point> planner_;  // when each planned move finishes
    asio::steady_timer run_timer_, wire_timer_, busy_timer_;
    std::deque<std::pair<std::chrono::steady_clock::time_point, std::string>> wire_;  // baud-limited arrival
    std::chrono::steady_clock::time_point wire_free_{};
    bool wire_armed_ = false;
    bool running_ = false;  // run_queue is waiting on a timer
    bool halted_ = false;
    bool unplugged_ = false;
    std::string carry_;  // a line whose newline was dropped
    std::vector<std::string> executed_;
    std::ofstream record_;
    std::vector<double> pos_;  // per axis letter, plus E last
    SimStats stats_;
};

}  // namespace xlate5
