// SPDX-License-Identifier: GPL-3.0-or-later
// A TEST DOUBLE of a printer's firmware (stage: service, used by tests, `--printer sim` and the
// bench; may call line_checker, line_protocol, link, and error.hpp for its IoError): a
// Marlin-like or RepRapFirmware-like firmware on the far end of a pseudo-terminal, so the
// whole service runs with no hardware and tests can inject the faults a real link shows. It
// records every command it executes, in order, so a test can prove that nothing was lost,
// duplicated or reordered on the way.
//
// It follows Marlin's receive rules as docs/service.md states them from Marlin's
// queue.cpp: a serial receive buffer of `rx_size` bytes (bytes beyond it are lost), a command
// buffer of `buffer` lines that the receive buffer is read into only while it has room, lines
// read up to MAX_CMD_SIZE - 1 characters (the rest is read as a new line), the line number
// checked before the checksum, a repeat of last_N or last_N - 1 dropped without a word, every
// refusal emptying the whole receive buffer, and "ok" only once a command is taken (a move: once
// the planner has room). M112 acts as its bytes arrive (EMERGENCY_PARSER).
//
// What Marlin does when a command RUNS, not when it is received, happens here when it runs too:
// M110 N<n> sets the line number again (gcode/host/M110.cpp; lines taken between receipt and run
// are then counted from n again), M999 asks for the line after the last one, G92 sets positions,
// G90/G91 and M82/M83 change how later moves' words are read, M114 reports the position of the
// moves run so far. The line number on receipt, M112 (EMERGENCY_PARSER) and the "stopped"
// refusal of moves are the receive-time effects.
//
// What it leaves out: temperatures (M105 reports fixed values, M109/M190 only take time), real
// motion (a move takes `move_ms`; positions are the last commanded), SD cards, host action
// commands, multiple serial ports, the exact text of most echo: messages, and what Marlin's
// parser makes of the tail of a cut line beyond "unknown command" (a tail that starts with a G
// or M code is run, as Marlin would). RepRapFirmware is modelled only as far as its reply to
// a bad line (dropped silently) and its silence during long commands.
#pragma once
#include <cstdint>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "daemon/firmware_protocol.hpp"
#include "daemon/line_checker.hpp"
#include "daemon/link.hpp"

namespace xlate5 {

struct SimFaults {
    double corrupt = 0;          // per received line: one bit flipped (line noise)
    double drop = 0;             // per received line: one byte lost (possibly the '\n')
    double lose_newline = 0;     // per received line: its '\n' lost (it joins the next line)
    double lose_ok = 0;          // per ok: not sent
    double garble_reply = 0;     // per reply line: a byte flipped on the way back
    double spurious_resend = 0;  // per accepted line: refuse it anyway (as after noise)
    bool no_ok_after_resend = false;  // some Marlin versions send Resend without an ok
    bool greeting_resend = false;     // the firmware still holds an old line number: the first line it gets draws a stale Resend
    std::uint64_t stale_oks = 0;      // oks of earlier lines still on their way when the host greets again
    bool junk_position = false;  // M114 answers with a report that names no Z and an X that is no number
    bool quiet_planner = false;  // no busy: keepalives while a move waits for the planner (HOST_KEEPALIVE off)
    double busy = 0;             // per executed move: a busy period with "busy: processing" keepalives
    double busy_seconds = 3;
    double busy_interval = marlin::kKeepaliveSeconds;  // seconds between keepalives
    double move_ms = 0;          // time each planned move takes: a slow planner holds oks back when full
    // Time each command takes to parse and queue before its ok (an AVR Marlin's main loop: its
    // `advance()` runs one command at a time, and the receive buffer is not read meanwhile, so
    // bytes keep arriving into it). Milliseconds, 0 to 10000.
    double command_ms = 0;
    double slow_seconds = 0;     // G28, G4, M109, M190, M400 take this long (Marlin: with keepalives; RRF: silent)
    std::uint64_t reset_after = 0;   // after executing this many lines: reboot ("start", state lost)
    std::uint64_t reset_every = 0;   // each time the lines executed reach a multiple of this: reboot
    std::uint64_t kill_after = 0;    // after this many: "Error:Printer halted. kill() called!"
    std::uint64_t stop_after = 0;    // after this many: "Error:Printer stopped…" (M999 revives it)
    std::uint64_t unplug_after = 0;  // after this many: the port disappears
    std::uint64_t seed = 1;
};

struct SimOptions {
    bool reprap = false;       // RepRapFirmware personality (drops bad lines silently)
    // Klipper's host (klippy) on its pseudo-terminal (virtual_klipper.cpp): plain lines, N and *
    // ignored, one ok per line once it ran, "!!" errors, "//" messages; XYZE-only G92 and M114.
    bool klipper = false;
    std::map<char, std::pair<double, double>> limits;  // Klipper: position_min/max per axis letter ("Move out of range")
    bool klipper_homed = false;  // Klipper: X Y Z homed at start (else moves need G28 first)
    bool advanced_ok = false;  // Marlin ADVANCED_OK: "ok N<n> P<p> B<b>"
    int buffer = marlin::kBufSize;         // command buffer (BUFSIZE)
    int planner = marlin::kPlannerSize;    // planner slots
    std::size_t rx_size = marlin::kRxBufferSize;  // serial receive buffer (RX_BUFFER_SIZE)
    std::string axes = "XYZAB";  // the firmware's axis letters
    std::vector<double> start;   // per axis letter: where the axes are at power-up (empty: all 0)
    int baud = 0;              // 0: unlimited; else bytes arrive no faster than baud/10 per second (a UART, paced)
    // Native USB (baud 0 only): the host's writes arrive whole, and the main loop reads the
    // receive buffer once per USB frame (1 ms), so lines written together are taken together,
    // before the first of them runs.
    bool usb = false;
    SimFaults faults;
    std::string record_path;   // write executed commands here, one a line
    bool keep_executed = false;  // also keep them in memory (tests); off, memory stays flat however long the print
    std::size_t max_line = marlin::kMaxCmdSize;  // MAX_CMD_SIZE: lines are read up to max_line - 1 characters
    std::string firmware_name;   // overrides the M115 FIRMWARE_NAME (a firmware of another flavour)
};

struct SimStats {
    std::uint64_t received = 0, executed = 0, refused = 0, dropped = 0, corrupted = 0, garbled = 0, resets = 0;
    std::uint64_t duplicates = 0, flushed_bytes = 0, overflow_bytes = 0, lost_oks = 0, lost_newlines = 0, cut_lines = 0;
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
    // Baud-limited link only: called when bytes arrive after the wire stood idle, with the time
    // the last byte before finished crossing, the time the new ones came, and the time the bytes
    // before them came (a bench's count of gaps and their causes).
    using Clock = std::chrono::steady_clock;
    using GapHandler = std::function<void(Clock::time_point idle_from, Clock::time_point resumed, Clock::time_point bytes_before)>;
    void on_wire_gap(GapHandler f) { on_gap_ = std::move(f); }
    Clock::time_point last_ok() const { return last_ok_; }      // when the latest ok was written
    Clock::time_point wire_free() const { return wire_free_; }  // when the last byte sent finishes crossing

private:
    struct Command { std::string text; std::int64_t n; };
    void on_line(std::string_view raw);
    void on_bytes(std::size_t n);
    std::chrono::steady_clock::duration wire_time(std::uint64_t bytes) const;
    void arrive(const std::string& bytes);
    void schedule();
    void read_serial();
    void process(const std::string& line);
    void refuse(std::string_view why);
    void run_queue();
    void pump_wire();
    void execute(const Command& c);
    void reply(std::string line);
    void boot();
    void halt(const std::string& why);
    std::string position_report() const;
    // Klipper (virtual_klipper.cpp).
    void klipper_line(std::string line);
    void klipper_run();
    void klipper_execute(const std::string& raw);
    bool klipper_g1(const std::string& upper, std::string& error);
    void klipper_error(const std::string& message);
    void klipper_shutdown(const std::string& why);
    std::string klipper_axes(const std::vector<std::pair<char, double>>& v) const;
    std::deque<std::string> kpending_;
    std::map<char, double> klast_, kbase_;        // gcode_move's last_position and base_position, by letter
    std::map<char, std::string> kregistered_;     // extra axis letter -> manual_stepper name
    std::map<std::string, double> kstepper_;      // manual_stepper positions
    bool kabsolute_ = true, kabsolute_e_ = true, khomed_ = false, kshutdown_ = false, kbusy_ = false;
    std::string kshutdown_why_;
    double kspeed_ = 25;  // mm/s

    std::shared_ptr<DescriptorLink> link_;
    SimOptions opt_;
    std::mt19937_64 rng_;
    std::uniform_real_distribution<double> uni_{0.0, 1.0};
    proto::LineChecker checker_;
    std::string rx_;                      // serial receive buffer: received, not yet read
    std::string line_;                    // the line being read
    std::deque<Command> ring_;            // command buffer: taken, not yet executed
    std::deque<std::chrono::steady_clock::time_point> planner_;  // when each planned move finishes
    asio::steady_timer run_timer_, wire_timer_, busy_timer_, usb_timer_;
    std::deque<std::pair<std::chrono::steady_clock::time_point, std::string>> wire_;  // baud-limited arrival
    std::chrono::steady_clock::time_point wire_free_{};
    // The wire by the byte: each read's bytes, as the count read so far and when its last byte is across.
    struct Chunk { std::uint64_t end; std::chrono::steady_clock::time_point done; };
    std::deque<Chunk> chunks_;
    std::uint64_t raw_bytes_ = 0;
    GapHandler on_gap_;
    Clock::time_point bytes_at_{};  // when the latest bytes came from the host
    Clock::time_point last_ok_{};
    std::optional<Clock::time_point> front_ready_;  // command_ms: when the command in front is parsed
    bool processing_ = false;                        // command_ms: the main loop is busy with a command
    std::chrono::steady_clock::time_point blocked_since_{}, last_keepalive_{};
    bool wire_armed_ = false;
    bool scheduled_ = false;
    bool running_ = false;  // run_queue is waiting on a timer
    bool halted_ = false;
    bool stopped_ = false;  // Marlin's "stopped" state: moves refused until M999
    bool unplugged_ = false;
    bool greeted_once_ = false;
    bool stale_resend_due_ = false;
    std::vector<std::string> executed_;
    std::ofstream record_;
    std::vector<double> pos_;  // per axis letter, plus E last
    bool relative_ = false;    // G91: axis words are offsets (as of the moves run so far)
    bool relative_e_ = false;  // M83 (or G91): E words are offsets
    SimStats stats_;
};

}  // namespace xlate5
