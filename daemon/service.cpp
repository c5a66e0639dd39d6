// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/service.hpp"

#include <algorithm>
#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"
#include "translators/machine/firmware_config.hpp"

namespace xlate5 {

std::vector<std::string> firmware_commands(const Machine& machine, const std::vector<std::string>& lines, const TranslatorOptions& options) {
    // As `xlate5 translate` does it: with the look-back window, finished at the end.
    const Kinematics kin(machine);
    TranslatorOptions o = options;
    o.input_name = "sender";
    Translator t(kin, o);
    t.set_lookback(Translator::kDefaultLookback);
    std::vector<std::string> out;
    std::string text;
    std::uint64_t n = 0;
    for (const auto& l : lines) {
        text.clear();
        t.feed(l, ++n, text);
        proto::append_commands(text, out);
    }
    text.clear();
    t.finish(text);
    proto::append_commands(text, out);
    return out;
}

ServePlan plan_as_serve(const Machine& machine, const std::vector<std::string>& lines, const TranslatorOptions& options,
                        const FirmwareOptions& firmware) {
    // Service::process's steps (ServeSteps), without the queue: a file is printed from a known
    // position, with no pauses; the first line refused ends it.
    const Kinematics kin(machine);
    TranslatorOptions o = options;
    o.input_name = "sender";
    ServeSteps steps(machine, o, ServeSteps::Position::Known);
    steps.reset(kin);
    steps.set_room({FirmwareProtocol(firmware).max_command()});
    ServePlan plan;
    const auto take = [&](std::uint64_t line_no, const std::string& line, ServeSteps::Batch& b) {
        if (b.changed) plan.split.push_back({line_no, line});
        for (auto& c : b.translated) plan.translated.push_back(std::move(c));
        for (auto& c : b.lines) plan.commands.push_back(std::move(c));
    };
    const auto cancel = [&](std::uint64_t line_no, const std::string& line, std::string cause, bool too_long) {
        plan.cancel = ServePlan::Point{line_no, line};
        plan.cause = std::move(cause);
        plan.too_long = too_long;
        return plan;
    };
    std::uint64_t n = 0;
    for (const auto& line : lines) {
        ++n;
        auto step = steps.line(line, proto::command_code(line), n);
        if (!step.release_bad.empty()) return cancel(n, line, "'" + step.release_bad + "' is longer than the firmware's line buffer", true);
        if (!step.released.translated.empty()) plan.releases.push_back({n, line});
        take(n, line, step.released);
        if (!step.refused.empty()) return cancel(n, line, step.refused, step.too_long);
        take(n, line, step.own);
    }
    ServeSteps::Batch rest;
    std::string bad;
    if (!steps.release(rest, bad)) return cancel(n, "(end of the print)", "'" + bad + "' is longer than the firmware's line buffer", true);
    take(n, "(end of the print)", rest);
    return plan;
}

Service::Service(asio::io_context& io, const Machine& machine, ServiceOptions options)
    : io_(io), machine_(machine), opt_(std::move(options)), steps_(machine_, opt_.translator), busy_timer_(io), drain_timer_(io),
      hold_timer_(io), idle_timer_(io) {
    kin_ = std::make_unique<Kinematics>(machine_);
    reset_translator();
}

Service::~Service() {
    for (auto& s : sessions_) s->close();
}

void Service::reset_translator() { steps_.reset(*kin_); }

void Service::release_held() {
    // The end of the look-back window: what the translator holds is final.
    if (!steps_.holding() || !firmware_) return;
    ServeSteps::Batch batch;
    std::string bad;
    if (!steps_.release(batch, bad)) return cancel_unsendable(bad);
    stats_.split_long += batch.split;
    enqueue_all(batch, 0, {});
}

void Service::cancel_unsendable(const std::string& bad) {
    stop_healthy_ = true;
    ++stats_.cancelled;
    stop("'" + bad + "' is longer than the firmware's line buffer");
}

bool Service::replace_machine(const Machine& machine) {
    if (!idle()) return false;
    auto kin = std::make_unique<Kinematics>(machine);
    machine_ = machine;
    kin_ = std::move(kin);
    reset_translator();
    return true;
}

void Service::attach_firmware(std::shared_ptr<Link> link, FirmwareOptions options) {
    firmware_options_ = options;
    firmware_.reset();
    firmware_ = std::make_unique<FirmwareLink>(std::move(link), options, *this);
    steps_.set_room({firmware_->max_command()});
    firmware_->start();
}

void Service::add_sender(std::shared_ptr<Link> link, const std::string& name, bool tcp) {
    if (tcp) {
        const auto connected = std::count_if(sessions_.begin(), sessions_.end(), [](const auto& x) { return x->tcp && x->open(); });
        if (std::size_t(connected) >= opt_.max_tcp) {
            // Each connection holds a descriptor and buffers: past the bound, a newcomer is told
            // why and closed, and the ones connected keep working.
            spdlog::warn("{}: turned away: {} TCP senders are connected (sender.max_tcp)", name, connected);
            link->send("echo:xlate5: too many senders connected (" + std::to_string(connected) + "); try again later\n");
            link->close();
            return;
        }
    }
    auto s = std::make_shared<SenderSession>(std::move(link), *this, name);
    s->tcp = tcp;
    sessions_.push_back(s);
    s->start();
    // "sender connected" is logged by the endpoint when one does (serve.cpp): a pseudo-terminal
    // is added here at start-up, before anyone has opened it.
    if (tcp) arm_idle_check();
}

void Service::arm_idle_check() {
    // A TCP sender that went quiet without closing (a crashed host, a half-open connection) would
    // hold its place for ever: after idle_seconds of silence it is closed, unless it is printing.
    if (idle_armed_) return;
    idle_armed_ = true;
    idle_timer_.expires_after(std::chrono::milliseconds(std::int64_t(opt_.idle_seconds * 250)));
    idle_timer_.async_wait(lifetime_.guard([this](boost::system::error_code ec) {
        idle_armed_ = false;
        if (ec) return;
        const auto now = std::chrono::steady_clock::now();
        const auto owner = owner_.lock();
        bool any = false;
        for (auto& s : sessions_) {
            if (!s->tcp || !s->open()) continue;
            any = true;
            const bool printing = owner == s && !idle();
            if (printing || now - s->last_heard() < std::chrono::milliseconds(std::int64_t(opt_.idle_seconds * 1000))) continue;
            spdlog::info("{}: nothing received for {:.0f} s: disconnected (sender.idle_seconds)", s->name(), opt_.idle_seconds);
            s->send_line("echo:xlate5: disconnected after " + std::to_string(int(opt_.idle_seconds)) + " s without a line");
            s->close();
            sender_gone(*s);
        }
        if (any) arm_idle_check();
    }));
}

void Service::sender_left(SenderSession& s) {
    // The documented rule: when the sender that prints leaves, the print ends at the last line
    // it was answered ok for. Those lines run (as a firmware runs its buffer when the host goes);
    // the lines it wrote without an ok yet are dropped, so nothing runs that no sender was told
    // of. The next sender starts from a fresh state (home or place the tool first).
    auto owner = owner_.lock();
    if (owner.get() != &s) return;
    owner_.reset();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - owner_since_).count();
    const auto lines = stats_.lines_in - owner_lines_;
    spdlog::info("{} left: {} lines in {:.1f} s ({:.0f} lines/s)", s.name(), lines, seconds, seconds > 0 ? double(lines) / seconds : 0.0);
    std::size_t dropped = 0;
    for (auto it = pending_.begin(); it != pending_.end();) {
        if (it->session.lock().get() == &s) it = pending_.erase(it), ++dropped;
        else ++it;
    }
    s.in_service = 0;
    if (!stopped() && firmware_ && firmware_->state() == FirmwareLink::State::Ready) release_held();
    // The translator stays where the machine is (and in the modes the sender left, as a
    // firmware would): the next sender's moves start from there, not from home.
    if (dropped) spdlog::warn("{} left with {} lines not yet answered: dropped, not run", s.name(), dropped);
    check_drained();
}

void Service::sender_reset(SenderSession& s) {
    // A new print (M110) after a cancelled one: the cancel is over for its owner.
    if (stopped() && stop_healthy_ && (!owner_.lock() || owner_.lock().get() == &s)) {
        spdlog::info("{}: M110, a new print after: {}", s.name(), stop_reason_);
        clear_stop();
    }
}

void Service::clear_stop() {
    stop_reason_.clear();
    stop_healthy_ = false;
    pending_.clear();
    for (auto& x : sessions_) x->in_service = 0;
    deferred_.clear();
    // The translator is where the lines that ran left the machine (a fault reset it, and the
    // firmware's greeting will place it).
}

void Service::sender_gone(SenderSession& s) {
    spdlog::info("sender gone: {}", s.name());
    sender_left(s);
    asio::post(io_, lifetime_.guard([this, p = &s] {
        std::erase_if(sessions_, [p](const auto& x) { return x.get() == p; });
    }));
}

const char* Service::activity() const {
    if (stopped()) return "stopped";
    if (idle()) return "idle";
    if (position_tag_ != 0 && pending_.empty() && !steps_.holding() && (!firmware_ || firmware_->sender_lines_queued() == 0))
        return "reading position";
    return "printing";
}

bool Service::idle() const { return pending_.empty() && !steps_.holding() && (!firmware_ || firmware_->idle()); }

void Service::broadcast(std::string_view line) {
    for (auto& s : sessions_)
        if (s->open()) s->send_line(line);
}

std::string Service::sender_m115() {
    std::string out;
    if (firmware_) {
        for (const auto& l : firmware_->m115()) {
            // Positions would come in joint space: senders must ask with M114, which xlate5 converts.
            if (l.rfind("Cap:AUTOREPORT_POS:", 0) == 0) out += "Cap:AUTOREPORT_POS:0\n";
            else out += l + "\n";
        }
    }
    if (!firmware_ || firmware_->m115().empty()) out += "FIRMWARE_NAME:xlate5 (firmware not connected)\n";
    out += "XLATE5:" XLATE5_VERSION_STRING " MACHINE:" + machine_.name + " (tool-space translation in front of the firmware)";
    return out;
}

void Service::sender_emergency(SenderSession& s, std::string_view command) {
    spdlog::warn("{}: {} sent to the firmware at once", s.name(), command);
    // M112 stops the firmware link itself (one fault, one count of the lines not executed,
    // told the sender and the log alike); M108 and M410 just go ahead of the queue.
    if (firmware_) firmware_->send_now(command);
    else if (proto::command_code(command).is('M', 112)) stop("emergency stop (M112) from " + s.name());
}

bool Service::claim(SenderSession& s) {
    // One sender prints at a time. Another may ask for temperatures (M105) and stop the printer
    // (M112); the printer passes to it only when the queue is empty.
    auto owner = owner_.lock();
    if (owner && owner.get() != &s && owner->open() && !idle()) return false;
    if (!owner || owner.get() != &s) {
        if (owner) spdlog::info("{} now prints (the queue was empty)", s.name());
        else spdlog::info("{} prints", s.name());
        owner_ = s.weak_from_this();
        owner_lines_ = stats_.lines_in;
        owner_since_ = std::chrono::steady_clock::now();
    }
    return true;
}

void Service::sender_command(SenderSession& s, std::string_view command, proto::Code code, std::uint64_t line_no, bool numbered) {
    if (!code.is('M', 105) && !claim(s)) {
        const auto owner = owner_.lock();
        const std::string why = "xlate5: busy: " + (owner ? owner->name() : std::string("another sender")) +
                                " is printing; '" + proto::strip_comment(command) + "' was not run";
        s.turned_away(why);
        return;
    }
    if (code.is('M', 999)) {
        // Restart after a stop: the queue is empty, the firmware is greeted again (after M999,
        // which revives a stopped Marlin), and the translator starts over (the position is
        // unknown until the program homes or places it).
        if (!stopped()) {
            s.ok();
            return;
        }
        spdlog::info("{}: M999, restarting after: {}", s.name(), stop_reason_);
        if (!stop_healthy_ && firmware_ && !firmware_->link().open()) {
            // The port went away: open it again, or stay stopped and say why.
            if (!reopen_) {
                s.send_line("Error:xlate5: the firmware's port is gone and cannot be reopened; restart the service");
                s.ok();
                return;
            }
            try {
                attach_firmware(reopen_(), firmware_options_);
            } catch (const std::exception& e) {
                s.send_line(std::string("Error:xlate5: cannot reopen the firmware's port: ") + e.what());
                s.ok();
                return;
            }
        } else if (!stop_healthy_ && firmware_) {
            firmware_->restart();
        }
        clear_stop();
        s.ok();
        return;
    }
    pending_.push_back({s.weak_from_this(), std::string(command), code, line_no, numbered});
    // Back-pressure: a sender that writes ahead without waiting for its oks is read no further
    // until the service has caught up.
    if (++s.in_service >= opt_.max_pending) s.pause_reading();
    ++lines_seen_;
    pump();
    arm_hold();
}

void Service::sender_refused(SenderSession& s, std::string_view command, std::uint64_t line_no, bool numbered, std::string cause) {
    // In its turn, so that every line before it runs (the sender's lines stay in order).
    pending_.push_back({s.weak_from_this(), std::string(command), proto::Code{}, line_no, numbered, std::move(cause)});
    if (++s.in_service >= opt_.max_pending) s.pause_reading();
    ++lines_seen_;
    pump();
}

void Service::arm_hold() {
    // A pause in the stream ends the look-back window: what is held goes to the firmware.
    if (!steps_.holding()) return;
    const auto seen = lines_seen_;
    hold_timer_.expires_after(std::chrono::milliseconds(std::int64_t(opt_.hold_seconds * 1000)));
    hold_timer_.async_wait(lifetime_.guard([this, seen](boost::system::error_code ec) {
        if (ec || seen != lines_seen_ || !pending_.empty()) return;
        release_held();
        check_drained();
    }));
}

void Service::pump() {
    while (!pending_.empty()) {
        ServeSteps::QueueState q;
        q.draining = draining_;
        q.stopped = stopped();
        q.firmware = firmware_ != nullptr;
        q.firmware_ready = firmware_ && firmware_->state() == FirmwareLink::State::Ready;
        q.queued = firmware_ ? firmware_->queued() : 0;
        q.queue_lines = opt_.queue_lines;
        const auto gate = steps_.gate(q);
        if (gate == ServeSteps::Gate::Keep) break;
        if (gate == ServeSteps::Gate::Wait) {
            arm_busy();  // the sender waits for its ok: keep it from timing out
            return;
        }
        const Pending p = std::move(pending_.front());
        pending_.pop_front();
        if (auto s = p.session.lock()) {
            if (s->in_service > 0) --s->in_service;
            if (s->in_service <= opt_.max_pending / 2) s->resume_reading();
        }
        process(p);
    }
    check_drained();
}

void Service::refuse_line(const Pending& p, const std::string& cause) {
    // The command's own text, not "sender:1023"; the words are SenderProtocol::refused's.
    auto session = p.session.lock();
    const std::string quoted = "line " + std::to_string(p.line_no) + " '" + proto::strip_comment(p.command) + "': " + cause;
    ++stats_.rejected;
    log_refusal(session, "refused " + quoted);
    if (session) session->refused(quoted, p.numbered);
    // Typed in a terminal: refused, and nothing else changes.
    if (!p.numbered) return;
    // Part of a print: the print ends there; every line before it runs (what the look-back
    // held included), nothing after it.
    release_held();
    stop_healthy_ = true;
    ++stats_.cancelled;
    stop("print cancelled at " + quoted);
}

Service::View Service::view() const {
    View v;
    if (const auto owner = owner_.lock()) v.sender = owner->name(), v.line = owner->last_line();
    v.joints = steps_.translator().joints(), v.pose = steps_.translator().pose();
    return v;
}

void Service::log_refusal(const std::shared_ptr<SenderSession>& s, const std::string& what) {
    last_error_ = what;
    std::uint64_t skipped = 0;
    if (!refusal_log_.allow(std::chrono::steady_clock::now(), skipped)) return;
    if (skipped) spdlog::warn("{} more refused lines were not logged (at most 10 a minute are)", skipped);
    spdlog::warn("{}: {}", s ? s->name() : std::string("a sender gone since"), what);
}

void Service::enqueue_all(ServeSteps::Batch& batch, std::uint64_t tag, const std::weak_ptr<SenderSession>& who) {
    auto& commands = batch.lines;
    const std::uint64_t first = batch.first, span = batch.span;
    // Each firmware line is marked with the sender line it comes from, so a fault counts sender
    // lines. Output the look-back released covers the lines of its window, which the translator
    // does not mark one by one: they are spread over it in order (an estimate within a line or
    // two when each sender line became a similar number of moves).
    for (std::size_t i = 0; i < commands.size(); ++i) {
        const std::uint64_t origin = first + (span > 1 ? std::uint64_t(i) * span / commands.size() : 0);
        std::uint64_t t = 0;
        if (tag && i + 1 == commands.size()) {
            t = tag;
            deferred_[tag] = who;
        }
        firmware_->enqueue(std::move(commands[i]), t, origin);
        ++stats_.lines_out;
    }
}

void Service::process(const Pending& p) {
    auto session = p.session.lock();
    if (stopped() || !firmware_) {
        // A cancelled print leaves the printer fine: not an Error: (OctoPrint would send M112).
        if (session)
            session->not_run(proto::strip_comment(p.command), stopped() ? stop_reason_ : std::string("no firmware"), stop_healthy_);
        ++stats_.rejected;
        log_refusal(session, "line " + std::to_string(p.line_no) + " '" + proto::strip_comment(p.command) + "' not run: " +
                                 (stopped() ? stop_reason_ : std::string("no firmware")));
        return;
    }
    if (!p.refused.empty()) return refuse_line(p, p.refused);
    auto step = steps_.line(p.command, p.code, p.line_no);
    stats_.lines_in = steps_.lines_in();
    // What the look-back held goes first (before a wait or a report), whatever becomes of the line.
    if (!step.release_bad.empty()) cancel_unsendable(step.release_bad);
    stats_.split_long += step.released.split;
    enqueue_all(step.released, 0, {});
    if (!step.refused.empty()) return refuse_line(p, step.refused);
    // All or nothing: a line refused above leaves nothing of itself in the queue.
    std::uint64_t tag = 0;
    if (step.firmware_answers && !step.own.lines.empty()) tag = next_tag_++;
    stats_.split_long += step.own.split;
    enqueue_all(step.own, tag, p.session);
    if (session && tag == 0) session->ok();
}

void Service::stop(const std::string& why) {
    if (stopped()) return;
    stop_reason_ = why;
    last_error_ = "print stopped: " + why;
    spdlog::error("print stopped: {}", why);
    // Senders waiting on a report get their ok now; the lines they send next are refused.
    for (auto& [tag, w] : deferred_)
        if (auto s = w.lock()) s->ok();
    deferred_.clear();
    pump();
}

void Service::arm_busy() {
    if (busy_armed_) return;
    busy_armed_ = true;
    busy_timer_.expires_after(std::chrono::milliseconds(int(opt_.busy_interval * 1000)));
    busy_timer_.async_wait(lifetime_.guard([this](boost::system::error_code ec) {
        busy_armed_ = false;
        if (ec || pending_.empty()) return;
        if (auto s = pending_.front().session.lock()) s->busy();
        arm_busy();
    }));
}

void Service::firmware_ready(const std::vector<std::string>&) {
    // The Klipper dialect's preamble (each extra axis registered as a G-code axis), at every
    // greeting: a Klipper restart forgets it, and without it Klipper drops A/B/C words silently.
    // Empty for the other dialects. Ahead of the position question, whose answer then has them.
    if (firmware_) {
        std::vector<std::string> preamble;
        proto::append_commands(firmware_preamble(machine_), preamble);
        for (auto& c : preamble) firmware_->enqueue(std::move(c));
    }
    ask_position();
    pump();
}

void Service::ask_position() {
    // Nothing of a sender's is translated before the answer: a move translated from an assumed
    // position (the machine's home) can run far from where the sender meant.
    if (!firmware_ || firmware_->state() != FirmwareLink::State::Ready || !steps_.ask_position()) return;
    position_tag_ = next_tag_++;
    firmware_->enqueue("M114", position_tag_);
}


void Service::firmware_acked(std::uint64_t tag, std::string_view ok_payload) {
    if (tag != 0 && tag == position_tag_) {
        position_tag_ = 0;
        if (steps_.position() == ServeSteps::Position::Asking) {
            steps_.position_unanswered();
            spdlog::warn("position: {}", steps_.position_why());
        }
        pump();
        return;
    }
    auto it = deferred_.find(tag);
    if (it == deferred_.end()) return;
    if (auto s = it->second.lock()) s->ok(ok_payload);
    deferred_.erase(it);
}

void Service::firmware_progress() { pump(); }

void Service::firmware_fault(const std::string& why, std::size_t lines_not_executed) {
    stop_healthy_ = false;
    steps_.position_lost(why);
    ++stats_.faults;
    broadcast("Error:xlate5: " + why + "; print stopped, " + std::to_string(lines_not_executed) +
              " queued lines not executed or not confirmed (nothing is replayed). Send M999 to restart.");
    stop(why);
    reset_translator();
    check_drained();
}


void Service::firmware_message(std::string_view line) {
    if (line.rfind("X:", 0) == 0 && line.find(" Y:") != std::string_view::npos) {
        std::string why;
        const auto at = read_position(machine_, line, why);
        if (steps_.position() == ServeSteps::Position::Asking && position_tag_ != 0) {
            // The service's own question: the answer places the translator; no sender asked.
            steps_.position_read(at ? &at->q : nullptr, at ? at->e : std::nullopt, why);
            if (at) spdlog::info("position: the firmware reports {}", line);
            else spdlog::warn("position: {} ('{}')", steps_.position_why(), line);
            return;
        }
        if (!at) {
            broadcast("echo:xlate5: the firmware's position report could not be read (" + why + "): " + std::string(line));
            return;
        }
        broadcast(tool_space_position(machine_, *kin_, steps_.translator().program_offset(), *at));
        return;
    }
    broadcast(line);
}

void Service::drain(double timeout, std::function<void(const std::string&)> done) {
    if (!stopped() && firmware_ && firmware_->state() == FirmwareLink::State::Ready) release_held();
    draining_ = true;
    drained_ = std::move(done);
    drain_timer_.expires_after(std::chrono::milliseconds(std::int64_t(timeout * 1000)));
    drain_timer_.async_wait(lifetime_.guard([this](boost::system::error_code ec) {
        if (ec || !drained_) return;
        const auto left = firmware_ ? firmware_->queued() : 0;
        auto done = std::move(drained_);
        drained_ = nullptr;
        done("not drained after the timeout: " + std::to_string(left) + " lines not sent; the print is stopped between lines");
    }));
    check_drained();
}

void Service::when_idle(std::function<void()> f) {
    idle_waiter_ = std::move(f);
    check_drained();
}

void Service::check_drained() {
    if (idle_waiter_ && idle()) {
        auto f = std::move(idle_waiter_);
        idle_waiter_ = nullptr;
        f();
    }
    if (!draining_ || !drained_) return;
    const bool fw_done = !firmware_ || firmware_->idle() || firmware_->state() == FirmwareLink::State::Faulted;
    if (!fw_done) return;
    drain_timer_.cancel();
    auto done = std::move(drained_);
    drained_ = nullptr;
    done(stopped() ? "stopped: " + stop_reason_ : std::string("drained: the firmware acknowledged every accepted line"));
}

}  // namespace xlate5
