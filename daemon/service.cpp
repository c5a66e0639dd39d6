// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/service.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"
#include "translators/error.hpp"

namespace xlate5 {
namespace {

// M114 prints joints to two decimals: a report this close to the translator's joints is them.
constexpr double kReportResolution = 0.005;

// Commands whose answer comes with (or before) the firmware's ok: the sender gets that ok, so
// reports arrive where it expects them and waits (M400, M109) stay truthful.
bool answered_by_firmware(const proto::Code& c) {
    if (c.letter != 'M') return false;
    switch (c.code10 / 10) {
        case 20: case 27: case 31: case 105: case 109: case 114: case 119: case 190: case 211: case 400: case 503:
            return c.code10 % 10 == 0;
        default:
            return false;
    }
}

// A firmware that reads at most max_line bytes per line must never get a longer one: F moves to
// a line of its own, a message is shortened; anything else is refused.
template <class Firmware>
bool split_for_firmware(const Firmware& fw, const std::string& cmd, std::vector<std::string>& parts) {
    parts.clear();
    if (fw.fits(cmd)) {
        parts.push_back(cmd);
        return true;
    }
    const auto code = proto::command_code(cmd);
    if (code.letter == 'G' && (code.code10 == 0 || code.code10 == 10)) {
        const auto f = cmd.find(" F");
        if (f != std::string::npos) {
            auto end = cmd.find(' ', f + 1);
            const std::string fword = cmd.substr(f + 1, end == std::string::npos ? std::string::npos : end - f - 1);
            std::string rest = cmd.substr(0, f) + (end == std::string::npos ? "" : cmd.substr(end));
            const std::string feed = cmd.substr(0, cmd.find(' ')) + " " + fword;
            if (fw.fits(feed) && fw.fits(rest)) {
                parts.push_back(feed);  // F alone moves nothing and sets the feed for the next line
                parts.push_back(rest);
                return true;
            }
        }
        return false;
    }
    if (code.letter == 'M' && (code.code10 == 1170 || code.code10 == 1180)) {
        std::string s = cmd;
        while (!s.empty() && !fw.fits(s)) s.pop_back();
        parts.push_back(s);
        return true;
    }
    return false;
}

// G28 with no axis named homes every axis: the position is known again.
bool homes_all(std::string_view command) {
    const std::string text = proto::strip_comment(command);
    const auto space = text.find(' ');
    if (space == std::string::npos) return true;
    for (std::size_t i = space; i < text.size(); ++i)
        if (std::string_view("XYZABCUVWxyzabcuvw").find(text[i]) != std::string_view::npos) return false;
    return true;
}

// A command the translator passes on as written (not a move) that no firmware line could hold:
// refused before the sender is answered, so that the lines acknowledged before it never wait
// behind a line that cannot be sent (docs/service.md).
template <class Firmware>
std::optional<std::string> unsendable(const Firmware& fw, const proto::Code& code, std::string_view command) {
    if (code.letter == 'G' && code.code10 <= 30 && code.code10 % 10 == 0) return std::nullopt;  // G0-G3: written anew
    const std::string text = proto::strip_comment(command);
    std::vector<std::string> parts;
    if (split_for_firmware(fw, text, parts)) return std::nullopt;
    return "'" + text + "' is longer than the firmware's line buffer (" + std::to_string(fw.max_command()) +
           " characters with its line number and checksum)";
}

}  // namespace

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
    // The steps of Service::process, without the queue: M105 passes untranslated; a wait or a
    // report releases what the look-back holds first; a line the translator refuses ends it.
    const Kinematics kin(machine);
    TranslatorOptions o = options;
    o.input_name = "sender";
    Translator t(kin, o);
    t.set_lookback(Translator::kDefaultLookback);
    const FirmwareProtocol fw(firmware);
    ServePlan plan;
    std::string text;
    std::vector<std::string> fresh, parts;
    const auto take = [&](std::uint64_t line_no, const std::string& line) {
        fresh.clear();
        proto::append_commands(text, fresh);
        bool noted = false;
        for (auto& cmd : fresh) {
            if (!split_for_firmware(fw, cmd, parts)) {
                plan.cancel = ServePlan::Point{line_no, line};
                plan.cause = "'" + cmd + "' is longer than the firmware's line buffer";
                plan.too_long = true;
                return false;
            }
            if ((parts.size() > 1 || parts[0] != cmd) && !noted) plan.split.push_back({line_no, line}), noted = true;
            plan.translated.push_back(std::move(cmd));
            for (auto& p : parts) plan.commands.push_back(std::move(p));
        }
        return true;
    };
    std::uint64_t n = 0;
    for (const auto& line : lines) {
        ++n;
        const auto code = proto::command_code(line);
        text.clear();
        if (code.is('M', 105)) {
            text = proto::strip_comment(line) + "\n";
            if (!take(n, line)) return plan;
            continue;
        }
        if (const auto why = unsendable(fw, code, line)) {
            plan.cancel = ServePlan::Point{n, line};
            plan.cause = *why;
            plan.too_long = true;
            return plan;
        }
        if (answered_by_firmware(code)) {
            t.finish(text);
            if (!text.empty()) plan.releases.push_back({n, line});
            if (!take(n, line)) return plan;
            text.clear();
        }
        try {
            t.feed(line, n, text);
        } catch (const InputError& e) {
            plan.cancel = ServePlan::Point{n, line};
            plan.cause = e.message();
            return plan;
        }
        if (!take(n, line)) return plan;
    }
    text.clear();
    t.finish(text);
    take(n, "(end of the print)");
    return plan;
}

Service::Service(asio::io_context& io, const Machine& machine, ServiceOptions options)
    : io_(io), machine_(machine), opt_(std::move(options)), busy_timer_(io), drain_timer_(io), hold_timer_(io), idle_timer_(io) {
    kin_ = std::make_unique<Kinematics>(machine_);
    reset_translator();
}

Service::~Service() {
    for (auto& s : sessions_) s->close();
}

void Service::reset_translator() {
    // A fresh interpreter: modal state from the machine file, position unknown until homed or
    // placed; the same look-back window as offline translation (output held until decided).
    translator_ = std::make_unique<Translator>(*kin_, opt_.translator);
    translator_->set_lookback(Translator::kDefaultLookback);
    holding_ = false;
}

void Service::release_held() {
    // The end of the look-back window: what the translator holds is final.
    if (!holding_ || !translator_ || !firmware_) return;
    holding_ = false;
    out_.clear();
    translator_->finish(out_);
    std::vector<std::string> commands, lines;
    proto::append_commands(out_, commands);
    std::string bad;
    if (!split_all(commands, lines, bad)) {
        stop_healthy_ = true;
        ++stats_.cancelled;
        stop("'" + bad + "' is longer than the firmware's line buffer");
        return;
    }
    enqueue_all(lines, 0, {}, window_first_, stats_.lines_in - window_first_ + 1);
}

bool Service::split_all(const std::vector<std::string>& commands, std::vector<std::string>& lines, std::string& bad) {
    std::vector<std::string> parts;
    for (const auto& cmd : commands) {
        if (!split_for_firmware(*firmware_, cmd, parts)) {
            bad = cmd;
            return false;
        }
        if (parts.size() > 1) ++stats_.split_long;
        for (auto& part : parts) lines.push_back(std::move(part));
    }
    return true;
}

bool Service::replace_machine(const Machine& machine) {
    if (!idle()) return false;
    auto kin = std::make_unique<Kinematics>(machine);
    translator_.reset();
    machine_ = machine;
    kin_ = std::move(kin);
    reset_translator();
    return true;
}

void Service::attach_firmware(std::shared_ptr<Link> link, FirmwareOptions options) {
    firmware_options_ = options;
    firmware_.reset();
    firmware_ = std::make_unique<FirmwareLink>(std::move(link), options, *this);
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

bool Service::idle() const { return pending_.empty() && !holding_ && (!firmware_ || firmware_->idle()); }

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
    if (!holding_) return;
    const auto seen = lines_seen_;
    hold_timer_.expires_after(std::chrono::milliseconds(std::int64_t(opt_.hold_seconds * 1000)));
    hold_timer_.async_wait(lifetime_.guard([this, seen](boost::system::error_code ec) {
        if (ec || seen != lines_seen_ || !pending_.empty()) return;
        release_held();
        check_drained();
    }));
}

void Service::pump() {
    // While draining for a stop, lines not yet acknowledged stay with the sender, unsent.
    while (!pending_.empty() && !draining_) {
        if (!stopped() && position_ == Position::Asking) {
            arm_busy();  // the firmware is asked where it is: nothing is translated before it answers
            return;
        }
        if (!stopped() && firmware_ && (firmware_->state() != FirmwareLink::State::Ready || firmware_->queued() >= opt_.queue_lines)) {
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
    if (translator_) v.joints = translator_->joints(), v.pose = translator_->pose();
    return v;
}

void Service::log_refusal(const std::shared_ptr<SenderSession>& s, const std::string& what) {
    last_error_ = what;
    std::uint64_t skipped = 0;
    if (!refusal_log_.allow(std::chrono::steady_clock::now(), skipped)) return;
    if (skipped) spdlog::warn("{} more refused lines were not logged (at most 10 a minute are)", skipped);
    spdlog::warn("{}: {}", s ? s->name() : std::string("a sender gone since"), what);
}

void Service::enqueue_all(std::vector<std::string>& commands, std::uint64_t tag, const std::weak_ptr<SenderSession>& who,
                          std::uint64_t first, std::uint64_t span) {
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
    if (const auto why = unplaceable(p)) return refuse_line(p, *why);
    if (firmware_)
        if (const auto why = unsendable(*firmware_, p.code, p.command)) return refuse_line(p, *why);
    ++stats_.lines_in;
    const bool wait_for_firmware = answered_by_firmware(p.code);
    std::vector<std::string> commands;
    // The sender lines this line's output stands for: its own, and those of the look-back window
    // it may release (see enqueue_all).
    std::uint64_t first = stats_.lines_in;
    if (p.code.is('M', 105)) {
        // Temperatures: nothing to translate, and no reason to end the look-back window.
        commands.push_back(proto::strip_comment(p.command));
    } else {
        // A wait or a report (M400, M114, M109 …) is answered by the firmware once everything
        // before it ran: the look-back window ends there.
        if (wait_for_firmware) release_held();
        const bool was_holding = holding_;
        if (was_holding) first = window_first_;
        out_.clear();
        try {
            translator_->feed(p.command, p.line_no, out_);
        } catch (const InputError& e) {
            refuse_line(p, e.message());
            return;
        }
        // Held only while a look-back window is open: with none, there is nothing undecided to
        // wait for (no hold_seconds at the end of a print whose last window has closed).
        holding_ = translator_->holding();
        // A window opens here (or a new one after the old one's output came out).
        if (holding_ && (!was_holding || !out_.empty())) window_first_ = stats_.lines_in;
        if (out_.empty()) first = stats_.lines_in;
        proto::append_commands(out_, commands);
        if (p.code.is('G', 28) && position_ == Position::Unknown && homes_all(p.command)) position_ = Position::Known;
    }
    std::vector<std::string> lines;
    std::string bad;
    if (!split_all(commands, lines, bad)) {
        refuse_line(p, "'" + bad + "' is longer than the firmware's line buffer");
        return;
    }
    // All or nothing: a line that fails above leaves nothing of itself in the queue.
    std::uint64_t tag = 0;
    if (wait_for_firmware && !lines.empty()) tag = next_tag_++;
    enqueue_all(lines, tag, p.session, first, stats_.lines_in - first + 1);
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
    ask_position();
    pump();
}

void Service::ask_position() {
    // Nothing of a sender's is translated before the answer: a move translated from an assumed
    // position (the machine's home) can run far from where the sender meant.
    if (!firmware_ || firmware_->state() != FirmwareLink::State::Ready || holding_) return;
    position_ = Position::Asking;
    position_tag_ = next_tag_++;
    firmware_->enqueue("M114", position_tag_);
}

std::optional<Service::Reported> Service::read_position(std::string_view report, std::string& why) const {
    // "X:7.00 Y:0.00 Z:0.00 A:10.00 B:5.00 E:0.00 Count X:560 …": the words before "Count".
    Reported r;
    r.q.assign(machine_.joints.size(), 0.0);
    std::vector<bool> seen(machine_.joints.size(), false);
    std::string_view words = report.substr(0, report.find("Count"));
    for (std::size_t i = 0; i + 1 < words.size(); ++i) {
        if (words[i + 1] != ':' || (i > 0 && words[i - 1] != ' ')) continue;
        std::string_view v = words.substr(i + 2);
        while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
        const std::string_view token = v.substr(0, v.find(' '));
        double x = 0;
        const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), x);
        const bool number = ec == std::errc() && end == token.data() + token.size() && std::isfinite(x);
        if (words[i] == 'E') {
            if (number) r.e = x;
            continue;
        }
        for (std::size_t j = 0; j < machine_.joints.size(); ++j) {
            if (machine_.joints[j].output != words[i]) continue;
            if (!number) {
                why = std::string("its ") + words[i] + " is '" + std::string(token) + "', not a number";
                return std::nullopt;
            }
            r.q[j] = x;
            seen[j] = true;
        }
    }
    for (std::size_t j = 0; j < machine_.joints.size(); ++j)
        if (!seen[j]) {
            why = std::string("it has no ") + machine_.joints[j].output;
            return std::nullopt;
        }
    machine_.compensation.undo(r.q);
    return r;
}

std::optional<std::string> Service::unplaceable(const Pending& p) const {
    // While the position is unknown, only homing may move the machine.
    if (position_ != Position::Unknown || p.code.letter != 'G') return std::nullopt;
    const int g = p.code.code10;
    if (g != 0 && g != 10 && g != 20 && g != 30) return std::nullopt;
    return "the printer's position is not known (" + position_why_ + "): home it (G28) first";
}

void Service::firmware_acked(std::uint64_t tag, std::string_view ok_payload) {
    if (tag != 0 && tag == position_tag_) {
        position_tag_ = 0;
        if (position_ == Position::Asking) {
            position_ = Position::Unknown;
            position_why_ = "the firmware did not answer M114 with a position";
            spdlog::warn("position: {}", position_why_);
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
    position_ = Position::Unknown;
    position_why_ = "the firmware stopped: " + why;
    ++stats_.faults;
    broadcast("Error:xlate5: " + why + "; print stopped, " + std::to_string(lines_not_executed) +
              " queued lines not executed or not confirmed (nothing is replayed). Send M999 to restart.");
    stop(why);
    reset_translator();
    check_drained();
}

std::string Service::tool_space_position(const Reported& at) const {
    // The nominal joints read_position took from the firmware's report -> tip and angles in the
    // part frame.
    const std::vector<double>& q = at.q;
    const Pose pose = kin_->forward(q);
    const Eigen::Vector3d tip = pose.tip - translator_->program_offset();
    char buf[96];
    std::snprintf(buf, sizeof buf, "X:%.2f Y:%.2f Z:%.2f", tip.x(), tip.y(), tip.z());
    std::string out = buf;
    // E right after Z: OctoPrint 1.x reads M114 only as "X: Y: Z: E:" (docs/service.md); the
    // rotaries follow.
    if (at.e) {
        std::snprintf(buf, sizeof buf, " E:%.2f", *at.e);
        out += buf;
    }
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) {
        if (!machine_.joints[j].rotary) continue;
        std::snprintf(buf, sizeof buf, " %c:%.2f", machine_.joints[j].name, q[j]);
        out += buf;
    }
    return out;
}

void Service::firmware_message(std::string_view line) {
    if (line.rfind("X:", 0) == 0 && line.find(" Y:") != std::string_view::npos) {
        std::string why;
        const auto at = read_position(line, why);
        if (position_ == Position::Asking && position_tag_ != 0) {
            // The service's own question: the answer places the translator; no sender asked.
            if (at) {
                translator_->place_at(at->q, at->e, kReportResolution);
                position_ = Position::Known;
                spdlog::info("position: the firmware reports {}", line);
            } else {
                position_ = Position::Unknown;
                position_why_ = "the firmware's M114 answer could not be read: " + why;
                spdlog::warn("position: {} ('{}')", position_why_, line);
            }
            return;
        }
        if (!at) {
            broadcast("echo:xlate5: the firmware's position report could not be read (" + why + "): " + std::string(line));
            return;
        }
        broadcast(tool_space_position(*at));
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
