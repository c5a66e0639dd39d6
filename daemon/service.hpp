// SPDX-License-Identifier: GPL-3.0-or-later
// The service: senders' lines in, through the translator, into a bounded queue, out to the
// firmware link; the firmware's replies back to the senders (positions converted to tool space).
// One io_context drives everything; nothing blocks and nothing polls. Stage: the service's
// middle; may call the translator (its public API), sender_session, firmware_link.
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "daemon/firmware_link.hpp"
#include "daemon/lifetime.hpp"
#include "daemon/log_policy.hpp"
#include "daemon/position_report.hpp"
#include "daemon/sender_limits.hpp"
#include "daemon/sender_session.hpp"
#include "daemon/serve_steps.hpp"
#include "translators/kinematics/kinematics.hpp"
#include "translators/machine/machine.hpp"
#include "translators/pipeline/translator.hpp"

namespace xlate5 {

// The sender limits as serve's settings give them, and the translator's options.
struct ServiceOptions : SenderLimits {
    TranslatorOptions translator;
};

struct ServiceStats {
    std::uint64_t lines_in = 0, lines_out = 0, rejected = 0, split_long = 0;
    std::uint64_t cancelled = 0, faults = 0;  // prints cancelled at a refused line; firmware faults (each stops the print)
};

// What the service sends the firmware for `lines` (before any line is split for a short
// buffer): the translation of a whole stream, as one sender would send it.
std::vector<std::string> firmware_commands(const Machine& machine, const std::vector<std::string>& lines,
                                           const TranslatorOptions& options = {});

// What `serve` does with a whole file, as a sender would print it (numbered lines, no pauses):
// translated line by line through the same ServeSteps as Service::process, for `serve --check`. It differs from
// offline translation only where the look-back's held output is released early.
struct ServePlan {
    struct Point {
        std::uint64_t line = 0;
        std::string text;
    };
    std::vector<std::string> translated;  // what the translator gave, before splitting for the firmware
    std::vector<std::string> commands;    // what the firmware gets
    std::vector<Point> releases;          // waits and reports: held output goes to the firmware before them
    std::vector<Point> split;             // lines whose output was split or shortened for the firmware's line buffer
    std::optional<Point> cancel;          // where serve would cancel the print, and why (cause)
    std::string cause;
    bool too_long = false;                // cancelled for the firmware's line buffer, not by the translator
};
ServePlan plan_as_serve(const Machine& machine, const std::vector<std::string>& lines, const TranslatorOptions& options,
                        const FirmwareOptions& firmware);

class Service final : public FirmwareLink::Listener, public SenderSession::Host {
public:
    Service(asio::io_context& io, const Machine& machine, ServiceOptions options);
    ~Service() override;

    // The firmware end (a serial port or the virtual printer's pseudo-terminal).
    void attach_firmware(std::shared_ptr<Link> link, FirmwareOptions options);
    // How to open the firmware's port again after it vanished (M999 after a USB unplug); throws
    // IoError when it is still not there.
    void set_reopen(std::function<std::shared_ptr<Link>()> reopen) { reopen_ = std::move(reopen); }
    // A sender end (the pseudo-terminal, or a TCP connection).
    void add_sender(std::shared_ptr<Link> link, const std::string& name, bool tcp = false);

    // Stop taking lines from senders and call `done` once every accepted line is executed (or
    // the firmware faulted); after `timeout` seconds, the unsent lines are dropped explicitly.
    void drain(double timeout, std::function<void(const std::string& outcome)> done);
    bool idle() const;
    // Of the lines senders were answered ok for: how many are not yet executed (or confirmed),
    // and whether the look-back still holds output of theirs.
    std::size_t acknowledged_not_run() const { return firmware_ ? firmware_->sender_lines_queued() : 0; }
    bool holding() const { return steps_.holding(); }
    // Calls `f` once the service is idle (at once if it is): nothing queued, held or in flight.
    void when_idle(std::function<void()> f);
    bool stopped() const { return !stop_reason_.empty(); }
    // What the service is doing, in one word for the status page and systemd: "stopped",
    // "idle", "reading position" (its own M114 after a greeting, no sender's line waiting) or
    // "printing". Not idle while it reads the position, yet no print is running.
    const char* activity() const;
    const std::string& stop_reason() const { return stop_reason_; }
    FirmwareLink* firmware() { return firmware_.get(); }
    const ServiceStats& stats() const { return stats_; }
    // Replaces the machine (SIGHUP reload); only when idle. Returns false when busy.
    bool replace_machine(const Machine& machine);

    // FirmwareLink::Listener
    void firmware_ready(const std::vector<std::string>& m115) override;
    void firmware_acked(std::uint64_t tag, std::string_view ok_payload) override;
    void firmware_message(std::string_view line) override;
    void firmware_fault(const std::string& why, std::size_t lines_not_executed) override;
    void firmware_progress() override;
    // SenderSession::Host
    void sender_command(SenderSession& s, std::string_view command, proto::Code code, std::uint64_t line_no, bool numbered) override;
    void sender_emergency(SenderSession& s, std::string_view command) override;
    std::string sender_m115() override;
    void sender_gone(SenderSession& s) override;
    void sender_left(SenderSession& s) override;
    void sender_reset(SenderSession& s) override;
    void sender_refused(SenderSession& s, std::string_view command, std::uint64_t line_no, bool numbered, std::string cause) override;
    std::size_t pending_lines() const { return pending_.size(); }

    // Read-only view for the status endpoint (daemon/status_http): the sender printing and its
    // last numbered line, the translator's latest joints (machine order) and tool pose (what
    // the service assumes; a new sender starts from home), and the latest stop or refusal.
    struct View {
        std::string sender;
        std::int64_t line = -1;
        std::vector<double> joints;
        Pose pose;
    };
    View view() const;
    const std::string& last_error() const { return last_error_; }
    const Machine& machine() const { return machine_; }

private:
    struct Pending {
        std::weak_ptr<SenderSession> session;
        std::string command;
        proto::Code code;
        std::uint64_t line_no;
        bool numbered;
        std::string refused = {};  // non-empty: refused in its turn with this cause (sender_refused)
    };
    void pump();
    void process(const Pending& p);
    void stop(const std::string& why);
    void broadcast(std::string_view line);
    void arm_busy();
    void check_drained();
    void ask_position();
    void reset_translator();
    void release_held();
    void cancel_unsendable(const std::string& bad);
    void arm_hold();
    void arm_idle_check();
    bool claim(SenderSession& s);
    void clear_stop();
    void refuse_line(const Pending& p, const std::string& cause);
    void log_refusal(const std::shared_ptr<SenderSession>& s, const std::string& what);
    void enqueue_all(ServeSteps::Batch& batch, std::uint64_t tag, const std::weak_ptr<SenderSession>& who);

    asio::io_context& io_;
    Machine machine_;
    std::unique_ptr<Kinematics> kin_;
    ServiceOptions opt_;
    ServeSteps steps_;  // the translator, the look-back window and the position: what is done with each line
    std::unique_ptr<FirmwareLink> firmware_;
    FirmwareOptions firmware_options_;
    std::function<std::shared_ptr<Link>()> reopen_;
    std::vector<std::shared_ptr<SenderSession>> sessions_;
    std::deque<Pending> pending_;                                   // received, not yet in the queue
    std::map<std::uint64_t, std::weak_ptr<SenderSession>> deferred_;  // tag -> who waits for the firmware's ok
    std::uint64_t next_tag_ = 1;
    // Where the machine is: the translator starts every move from its joints, so they must be
    // the firmware's. Asked with M114 whenever the firmware is greeted; kept across senders.
    std::uint64_t position_tag_ = 0;  // the service's own M114
    std::string stop_reason_;
    bool draining_ = false;
    std::function<void(const std::string&)> drained_;
    std::function<void()> idle_waiter_;
    asio::steady_timer busy_timer_, drain_timer_, hold_timer_, idle_timer_;
    bool idle_armed_ = false;  // a check for silent TCP senders is due
    std::uint64_t lines_seen_ = 0;
    bool stop_healthy_ = false;       // stopped by a refused line, not by the firmware: the printer is fine
    std::weak_ptr<SenderSession> owner_;  // the sender printing
    std::uint64_t owner_lines_ = 0;       // lines_in when it began
    std::chrono::steady_clock::time_point owner_since_;
    bool busy_armed_ = false;
    ServiceStats stats_;
    std::string last_error_;
    LogBudget refusal_log_{10, std::chrono::seconds(60)};  // each refused line logged, 10 a minute at most
    Lifetime lifetime_;  // last member: handlers check it first
};

}  // namespace xlate5
