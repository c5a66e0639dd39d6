// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/firmware_protocol.hpp"

#include <algorithm>
#include <charconv>
#include <spdlog/spdlog.h>

namespace xlate5 {
namespace {

using Time = FirmwareProtocol::Time;

FirmwareProtocol::Clock::duration seconds(double s) {
    return std::chrono::duration_cast<FirmwareProtocol::Clock::duration>(std::chrono::duration<double>(s));
}

// Commands RepRapFirmware may take minutes over without a word (it sends no busy: keepalives):
// silence after them is not a lost line. Marlin keeps talking meanwhile, so it gets no such grace.
bool may_wait_long(std::string_view command) {
    const auto c = proto::command_code(command);
    if (c.letter == 'G') return c.code10 == 40 || c.code10 == 280 || c.code10 == 290;  // G4, G28, G29
    if (c.letter != 'M' || c.code10 % 10) return false;
    switch (c.code10 / 10) {
        case 0: case 1: case 109: case 116: case 190: case 191: case 303: case 400: case 600: return true;
        default: return false;
    }
}

// "Error:…, Last Line: 41" -> 41.
std::optional<std::int64_t> last_line_of(std::string_view line) {
    const auto p = line.find("Last Line:");
    if (p == std::string_view::npos) return std::nullopt;
    std::string_view s = line.substr(p + 10);
    while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
    std::int64_t v = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec != std::errc()) return std::nullopt;
    return v;
}

bool is_protocol_reply(proto::ReplyKind k) {
    using K = proto::ReplyKind;
    return k == K::Ok || k == K::Resend || k == K::Busy || k == K::LineError || k == K::Error;
}

constexpr std::string_view kProbe = "M105";  // harmless, and its "ok T:" names itself

// Where a line may be cut in two within `room` bytes: the longest head whose tail begins with a
// digit (0 when there is none). Should an error empty the firmware's receive buffer between the
// parts, the tail arrives as a line of its own, and a line beginning with a digit is no command
// to Marlin ("Unknown command"), never a move run out of its place.
std::size_t head_within(std::string_view line, std::size_t room) {
    for (std::size_t k = std::min(room, line.size() - 1); k >= 1; --k)
        if (line[k] >= '0' && line[k] <= '9') return k;
    return 0;
}

}  // namespace

FirmwareProtocol::FirmwareProtocol(FirmwareOptions options) : opt_(options) {}

int FirmwareProtocol::window() const {
    if (opt_.reprap) return 1;  // a dropped line is never reported: anything sent after it would run out of order
    if (opt_.window > 0) return opt_.window;
    if (opt_.klipper) return klipper::kWindow;
    return learned_window_ > 0 ? learned_window_ : 2;
}

namespace {
// "N<n> " with up to 8 digits, "*<cs>" with up to 3, and the newline.
constexpr std::size_t kNumberRoom = 10, kChecksumRoom = 4, kNewline = 1;
}  // namespace

bool FirmwareProtocol::fits(std::string_view command) const { return command.size() <= max_command(); }

std::size_t FirmwareProtocol::max_command() const {
    if (opt_.klipper) return budget() - kNewline;  // Klipper reads lines of any length; xlate5 sends no N or checksum
    const std::size_t frame = kNumberRoom + kChecksumRoom + kNewline;
    return opt_.max_line > frame ? opt_.max_line - frame : 0;
}

std::optional<Time> FirmwareProtocol::deadline() const {
    std::optional<Time> d;
    const auto consider = [&](const std::optional<Time>& t) {
        if (t && (!d || *t < *d)) d = t;
    };
    if (state_ == State::Booting) consider(boot_deadline_);
    if (state_ == State::Greeting || state_ == State::Ready) {
        consider(quiet_deadline_);
        consider(reply_deadline_);
        consider(nudge_deadline_);
    }
    return d;
}

void FirmwareProtocol::write_line(const std::string& line) { emit(Action::Kind::Write, line); }

void FirmwareProtocol::open(Time now) {
    state_ = State::Booting;
    tail_.clear();  // a port opened anew
    m999_after_quiet_ = false;
    greetings_ = 0;
    // A board resets when its port opens and says "start" when it is up; one that does not
    // reset stays quiet, so after boot_wait xlate5 greets it anyway.
    boot_deadline_ = now + seconds(opt_.boot_wait);
}

void FirmwareProtocol::restart(Time now) {
    // A stopped Marlin (not a halted one) runs again after M999; it answers with a Resend and
    // an ok, which the greeting's wait for quiet discards. (RepRapFirmware's M999 reboots it.)
    // A line left half sent is ended first, and M999 waits for quiet: the refusal of its first
    // part empties Marlin's buffer, and would take M999 with it.
    const bool half_sent = !tail_.empty();
    abandon_tail();
    greetings_ = 0;
    greet(now);
    // Klipper has no M999 (its "Unknown command"): after an error it runs on, and after a
    // shutdown only FIRMWARE_RESTART revives it, which the greeting's STATUS tells.
    if (opt_.reprap || opt_.klipper) return;
    if (half_sent) m999_after_quiet_ = true;
    else write_line("M999\n");
}

void FirmwareProtocol::greet(Time now) {
    state_ = State::Greeting;
    tail_.clear();  // a reset emptied the firmware's buffer; after M999, restart() ended the line
    unsent_.clear();
    in_flight_.clear();
    history_.clear();
    error_next_.reset();
    renumber_ = false;
    extra_oks_ = false;
    bytes_in_flight_ = tagged_in_flight_ = 0;
    next_n_ = 0;
    credited_n_ = -1;
    sync_ = Sync::None;
    resend_from_.reset();
    m115_.clear();
    boot_deadline_.reset();
    reply_deadline_.reset();
    nudge_deadline_.reset();
    // Whatever the firmware still says about earlier lines (oks, Resends after M999 or a
    // reconnect) is waited out first.
    greet_ = Greet::Quiet;
    quiet_deadline_ = now + seconds(opt_.settle);
}

void FirmwareProtocol::send_greeting(Time now) {
    if (++greetings_ > opt_.max_greetings) {
        fault("the firmware does not answer the greeting (M110, M115) after " + std::to_string(opt_.max_greetings) + " attempts");
        return;
    }
    ++stats_.greetings;
    if (opt_.klipper) {
        // Klipper ignores line numbers and M110 (gcode.py: cmd_M110 passes): M115 answers
        // "ok FIRMWARE_NAME:Klipper …" on its ok line, and STATUS says whether it is ready.
        write_line("M115\n");
        write_line("STATUS\n");
        klipper_ready_ = false;
        klipper_not_ready_.clear();
        greet_ = Greet::AwaitReport;
        quiet_deadline_.reset();
        reply_deadline_ = now + seconds(opt_.reply_timeout);
        return;
    }
    // M110 sets the numbering (it skips the number check); M115 says what the firmware is.
    // Marlin sets the number again when M110 runs, and both lines are often in its buffer before
    // it does (one USB packet; a busy loop): a numbered M115 taken as the next line would be
    // forgotten and the line after it refused. Unnumbered, M115 is not counted; its answer comes
    // after M110 ran, and only then does numbering go on. M110 sets 1, so the lines are numbered
    // from 2 as they were when M115 was line 1.
    write_line(proto::numbered(0, "M110 N1") + "\n");
    write_line("M115\n");
    last_m110_ = 1;
    next_n_ = 2;
    greet_ = Greet::AwaitReport;
    quiet_deadline_.reset();
    reply_deadline_ = now + seconds(opt_.reply_timeout);
}

void FirmwareProtocol::become_ready() {
    quiet_deadline_.reset();
    reply_deadline_.reset();
    if (m115_.empty()) {
        fault("the firmware did not identify itself (no FIRMWARE_NAME in its answer to M115)");
        return;
    }
    const std::string& name = m115_.front();
    const bool rrf = name.find("RepRapFirmware") != std::string::npos;
    const bool klippy = name.find("FIRMWARE_NAME:Klipper") != std::string::npos;
    if (opt_.reprap != rrf || opt_.klipper != klippy) {
        fault(std::string("flavour mismatch: xlate5 is set for ") + (opt_.reprap ? "RepRapFirmware" : opt_.klipper ? "Klipper" : "Marlin") +
              " (firmware.flavor), but the firmware reports: " + name);
        return;
    }
    klipper_waits_ = 0;
    klipper_silence_ = 0;
    klipper_gcode_.clear();
    klipper_base_.clear();
    state_ = State::Ready;
    credited_n_ = next_n_ - 1;
    greetings_ = 0;
    timeouts_in_row_ = resyncs_in_row_ = 0;
    spdlog::info("firmware ready: {}", name);
    emit(Action::Kind::Ready);
}

void FirmwareProtocol::enqueue(std::string command, std::uint64_t tag, Time now, std::uint64_t origin) {
    if (state_ == State::Faulted) return;
    unsent_.push_back({std::move(command), tag, origin});
    transmit(now);
}

std::size_t FirmwareProtocol::drop_unsent() {
    const auto n = unsent_.size();
    unsent_.clear();
    return n;
}

void FirmwareProtocol::send_unnumbered(std::string_view command, Time now) {
    finish_tail();
    std::string line(command);
    line += '\n';
    write_line(line);
    // Marlin also runs it through its queue and answers ok in turn.
    if (state_ == State::Ready) {
        in_flight_.push_back({-1, std::string(command), 0, line.size(), false, false});
        bytes_in_flight_ += line.size();
        if (!reply_deadline_ && sync_ != Sync::Quiet) reply_deadline_ = now + seconds(opt_.reply_timeout);
    }
}

void FirmwareProtocol::emergency_stop(std::string_view command, Time) {
    finish_tail();
    std::string line(command);
    line += '\n';
    write_line(line);
    // Whether or not the firmware acts on it at once (EMERGENCY_PARSER), nothing queued behind
    // it may run; the count is told once, the same to the sender and the log.
    fault("emergency stop (" + std::string(command) + ") from the sender");
}

void FirmwareProtocol::port_closed(const std::string& why) { fault(why); }

void FirmwareProtocol::send_entry(Entry e, Time now, std::size_t room) {
    std::string line = (e.n >= 0 ? proto::numbered(e.n, e.command) : e.command) + "\n";
    e.bytes = line.size();
    if (line.size() > room) {
        // Only its first bytes fit the receive buffer: they go now, the rest when an ok frees room.
        const std::size_t k = head_within(line, room);
        tail_ = line.substr(k);
        line.resize(k);
    }
    write_line(line);
    bytes_in_flight_ += e.bytes;
    if (e.tag) ++tagged_in_flight_;
    in_flight_.push_back(std::move(e));
    ++stats_.sent;
    if (!reply_deadline_) reply_deadline_ = now + seconds(opt_.reply_timeout);
    arm_nudge(now);
}

void FirmwareProtocol::arm_nudge(Time now) {
    // RepRapFirmware gets no nudge: it is sent one line at a time and resends on silence anyway.
    // Nor Klipper: it answers an empty line with an ok of its own, which would credit a line.
    if (opt_.reprap || opt_.klipper || opt_.nudge <= 0 || opt_.nudge >= opt_.reply_timeout) return;
    nudge_deadline_ = now + seconds(opt_.nudge);
}

void FirmwareProtocol::on_nudge() {
    nudge_deadline_.reset();
    // Not while a resync waits for quiet (the probe brings its own newline); not beyond the
    // firmware's receive buffer. The byte rides with the last line in flight, and leaves the
    // budget with it.
    if (state_ != State::Ready || sync_ == Sync::Quiet || in_flight_.empty()) return;
    if (!tail_.empty()) return;  // a line half sent waits for room, not for its newline
    if (bytes_in_flight_ + 1 > opt_.rx_bytes) return;
    write_line("\n");
    in_flight_.back().bytes += 1;
    bytes_in_flight_ += 1;
    ++stats_.nudges;
}

void FirmwareProtocol::transmit_klipper(Time now) {
    // Every line draws exactly one ok, in order, once it ran (a move: once it is in the
    // toolhead's queue): plain oks credit lines in order. The bounds keep what Klipper holds
    // unread within one of its reads (kReadBytes) and below the 20 pending lines at which it stops
    // reading the pty (so an M112 is still seen out of order).
    const std::size_t limit = std::size_t(window());
    while (!unsent_.empty() && in_flight_.size() < limit) {
        const Item& item = unsent_.front();
        // Klipper's M114 leaves out the axes beyond X Y Z E; GET_POSITION names them all, and its
        // answer is given back as an M114 report (on_klipper_line).
        std::string command = proto::command_code(item.command).is('M', 114) ? std::string("GET_POSITION") : item.command;
        const std::size_t bytes = command.size() + kNewline;
        if (!in_flight_.empty() && bytes_in_flight_ + bytes > budget()) break;
        Entry e{-1, std::move(command), item.tag, 0, false, false, item.origin};
        unsent_.pop_front();
        send_entry(std::move(e), now);
    }
}

void FirmwareProtocol::transmit(Time now) {
    if (state_ != State::Ready || sync_ != Sync::None) return;
    if (opt_.klipper) return transmit_klipper(now);
    if (!tail_.empty() && !write_tail()) return;  // a line in two parts is finished before any other
    if (extra_oks_ && !advanced_ok_) {
        // Plain oks cannot be counted: a group of lines goes with an M105 behind it, and the next
        // group only once its "ok T:" said that all of them were taken.
        if (!in_flight_.empty() || unsent_.empty()) return;
        const std::size_t group = std::size_t(window());
        constexpr std::size_t kAnchorBytes = 16;  // "N<n> M105*<cs>\n"
        while (!unsent_.empty() && in_flight_.size() < group) {
            const std::size_t bytes = unsent_.front().command.size() + std::to_string(next_n_).size() + 7;
            if (!in_flight_.empty() && bytes_in_flight_ + bytes + kAnchorBytes > opt_.rx_bytes) break;
            Item item = std::move(unsent_.front());
            unsent_.pop_front();
            const bool anchor = proto::command_code(item.command).is('M', 105);  // its own "ok T:" names it
            send_entry({next_n_++, std::move(item.command), item.tag, 0, anchor, false, item.origin}, now);
        }
        send_entry({next_n_++, std::string(kProbe), 0, 0, true, true, 0}, now);
        return;
    }
    const std::size_t limit = std::size_t(window());
    while (!unsent_.empty() && in_flight_.size() < limit) {
        // Without ADVANCED_OK a line a sender waits on travels alone, so the ok that comes is its own.
        if (tagged_in_flight_ > 0 && !advanced_ok_) break;
        const Item& item = unsent_.front();
        if (item.tag && !in_flight_.empty() && !advanced_ok_) break;
        // "N<n> " + command + "*<cs>\n", without building it twice.
        const std::size_t bytes = item.command.size() + std::to_string(next_n_).size() + 7;
        const bool fits_whole = in_flight_.empty() || bytes_in_flight_ + bytes <= opt_.rx_bytes;
        // Marlin's receive buffer counts bytes, not lines: when the whole line does not fit, its
        // first bytes keep the link busy while the ok for the line before is on its way. Not for
        // RepRapFirmware, which drops a damaged line whole.
        const std::size_t room = fits_whole ? SIZE_MAX : opt_.rx_bytes - std::min(opt_.rx_bytes, bytes_in_flight_);
        if (!fits_whole && (opt_.reprap || !opt_.two_parts || room == 0)) break;  // the firmware's receive buffer is full
        const bool anchor = !opt_.reprap && proto::command_code(item.command).is('M', 105);
        Entry e{next_n_++, std::move(unsent_.front().command), item.tag, 0, anchor, false, item.origin};
        unsent_.pop_front();
        send_entry(std::move(e), now, room);
        if (!tail_.empty()) break;
    }
}

bool FirmwareProtocol::write_tail() {
    const std::size_t written = bytes_in_flight_ - tail_.size();
    const std::size_t room = opt_.rx_bytes - std::min(opt_.rx_bytes, written);
    if (tail_.size() <= room) {
        write_line(std::exchange(tail_, {}));
        return true;
    }
    if (const std::size_t k = head_within(tail_, room); k > 0) {
        write_line(tail_.substr(0, k));
        tail_.erase(0, k);
    }
    return false;
}

void FirmwareProtocol::finish_tail() {
    // Before M108, M410 or M112: a refusal now would empty the firmware's buffer, and with it the
    // command, on a Marlin without EMERGENCY_PARSER. The line goes whole; the budget yields to it.
    if (!tail_.empty()) write_line(std::exchange(tail_, {}));
}

void FirmwareProtocol::abandon_tail() {
    // The line's first bytes end here: Marlin refuses them (a number without a checksum) and
    // asks for the line again, or skips an empty line if an error emptied its buffer meanwhile.
    if (tail_.empty()) return;
    tail_.clear();
    write_line("\n");
}

void FirmwareProtocol::credit_through(std::size_t index, std::string_view payload) {
    for (std::size_t j = 0; j <= index; ++j) {
        Entry e = std::move(in_flight_.front());
        in_flight_.pop_front();
        if (in_flight_.empty()) abandon_tail();  // a stray ok for a line the firmware has not had whole
        bytes_in_flight_ -= e.bytes;
        if (e.tag) --tagged_in_flight_;
        if (e.n >= 0) credited_n_ = std::max(credited_n_, e.n);
        if (!e.probe) ++stats_.acked;
        if (e.n >= 0 && !e.probe) {
            history_.push_back({e.n, e.command, 0, e.bytes, false, false, e.origin});
            if (history_.size() > opt_.history) history_.pop_front();
        }
        if (e.tag) emit(Action::Kind::Acked, j == index ? std::string(payload) : std::string(), e.tag);
    }
    progressed();
    if (in_flight_.empty()) {
        reply_deadline_.reset();
        nudge_deadline_.reset();
    }
    if (sync_ == Sync::Probing && std::none_of(in_flight_.begin(), in_flight_.end(), [](const Entry& e) { return e.probe; }))
        sync_ = Sync::None;  // the firmware took the probe: everything before it is in, numbering agrees
}

void FirmwareProtocol::credit_front(std::string_view payload) { credit_through(0, payload); }

void FirmwareProtocol::on_ok(const proto::Reply& r, Time now) {
    if (r.buffer_free && opt_.window == 0) {
        // ADVANCED_OK: B is the free command-buffer slots; one more is being executed.
        learned_window_ = std::clamp(std::max(learned_window_, *r.buffer_free + 1), 1, 32);
    }
    const auto find = [&](auto pred) -> std::optional<std::size_t> {
        for (std::size_t i = 0; i < in_flight_.size(); ++i)
            if (pred(in_flight_[i])) return i;
        return std::nullopt;
    };
    if (r.ok_line) {
        // ADVANCED_OK names the line: everything up to it is in.
        advanced_ok_ = true;
        std::optional<std::size_t> last;
        for (std::size_t i = 0; i < in_flight_.size(); ++i)
            if (in_flight_[i].n >= 0 && in_flight_[i].n <= *r.ok_line) last = i;
        if (last) credit_through(*last, r.payload);
        else ++stats_.stray_oks;
    } else if (!opt_.reprap && r.payload.find("T:") != std::string_view::npos) {
        // M105's answer: it credits everything up to the M105 it answers.
        if (const auto i = find([](const Entry& e) { return e.anchor; })) credit_through(*i, r.payload);
        else ++stats_.stray_oks;
    } else if (sync_ != Sync::None) {
        // During a resync a plain ok may be the one after a Resend: it names nothing.
        ++stats_.stray_oks;
    } else if (in_flight_.empty() || (advanced_ok_ && in_flight_.front().n >= 0) || in_flight_.front().anchor || extra_oks_) {
        // Not the answer to anything xlate5 waits for in this order. With nothing in flight, it
        // is more: the firmware answers some lines more than once, and every plain ok credited
        // may have been one of those (its buffer would then hold lines xlate5 counts as taken,
        // without bound). From then on only an M105's "ok T:" credits lines (transmit).
        ++stats_.stray_oks;
        // An M105 in front: every line before it is credited, so a plain ok now answers nothing.
        const bool extra = in_flight_.empty() || (in_flight_.front().anchor && in_flight_.front().n >= 0);
        if (extra && !extra_oks_ && !advanced_ok_ && !opt_.reprap) {
            extra_oks_ = true;
            spdlog::warn("firmware: an ok with no line in flight: it answers more than once; each group of lines is now confirmed by M105");
        }
    } else {
        credit_front(r.payload);
    }
    transmit(now);
    emit(Action::Kind::Progress);
}

void FirmwareProtocol::on_refusal(std::optional<std::int64_t> next, bool confirmed, Time now) {
    // The firmware's last line is next - 1. Above what xlate5 sent, the number was damaged on
    // the way. Below a line xlate5 counted as acknowledged it is believed only when the Error
    // line and the Resend agree: a stray ok (the tail of a cut line answered as an unknown
    // command) can credit a line the firmware never took. Otherwise the probe will tell.
    if (next && *next <= next_n_) {
        const bool beyond_credit = *next > credited_n_;
        const bool in_history = !history_.empty() && *next >= history_.front().n;
        if (beyond_credit || (confirmed && in_history)) resend_from_ = *next;
        // The line after xlate5's latest M110, long acknowledged: the firmware ran that M110
        // again after it had taken later lines (PROTOCOL rule 6). A probe would be refused the
        // same way for ever; its count is set back to where xlate5's is instead.
        else if (confirmed && *next == last_m110_ + 1 && !in_history) renumber_ = true;
    }
    if (sync_ != Sync::Quiet) {
        ++stats_.resyncs;
        if (++resyncs_in_row_ > opt_.max_resyncs) {
            fault("the firmware keeps refusing lines (" + std::to_string(opt_.max_resyncs) +
                  " resyncs without progress): it lost its place or the line is too noisy");
            return;
        }
    }
    // A line half sent is ended now, so that its refusal (if the firmware still holds its
    // first part) comes within the quiet wait.
    abandon_tail();
    sync_ = Sync::Quiet;
    quiet_deadline_ = now + seconds(opt_.settle);
    // Waiting for quiet is waiting for silence: the reply timeout must not end it. (It did, when
    // `settle` was not shorter than `reply_timeout`, or a loaded host woke late past both: a probe
    // under a fresh number, which a firmware waiting for the named line refuses, which began
    // another resync, with no line ever acknowledged.) The probe that ends the quiet arms it again.
    reply_deadline_.reset();
}

void FirmwareProtocol::rewind(std::int64_t k) {
    // Lines from k on never reached the firmware's queue: they go back, in order, ahead of the
    // unsent ones; probes are not repeated.
    abandon_tail();
    std::deque<Entry> keep;
    std::vector<Item> back;
    // Lines counted as acknowledged that the firmware says it never took (a stray ok credited
    // them) come first; their senders were answered already.
    std::size_t cut = history_.size();
    while (cut > 0 && history_[cut - 1].n >= k) --cut;
    for (std::size_t i = cut; i < history_.size(); ++i) back.push_back({std::move(history_[i].command), 0, history_[i].origin});
    history_.erase(history_.begin() + std::ptrdiff_t(cut), history_.end());
    if (credited_n_ >= k) credited_n_ = k - 1;
    bool past = false;
    for (auto& e : in_flight_) {
        past = past || e.n >= k;
        if (!past) {
            keep.push_back(std::move(e));
            continue;
        }
        if (e.n >= 0 && !e.probe) back.push_back({std::move(e.command), e.tag, e.origin});
    }
    in_flight_ = std::move(keep);
    bytes_in_flight_ = tagged_in_flight_ = 0;
    for (const auto& e : in_flight_) {
        bytes_in_flight_ += e.bytes;
        if (e.tag) ++tagged_in_flight_;
    }
    for (auto it = back.rbegin(); it != back.rend(); ++it) unsent_.push_front(std::move(*it));
    stats_.resent += back.size();
    next_n_ = k;
}

void FirmwareProtocol::send_probe(std::int64_t n, Time now) {
    ++stats_.probes;
    next_n_ = n + 1;
    // A newline first: a line whose own newline was lost ends there instead of swallowing the
    // probe (an empty line is nothing to the firmware).
    // It also ends the first bytes of a line sent in two parts.
    tail_.clear();
    write_line("\n");
    send_entry({n, std::string(kProbe), 0, 0, true, true}, now);
    in_flight_.back().bytes += 1;  // that newline, in the receive buffer's budget
    bytes_in_flight_ += 1;
    sync_ = Sync::Probing;
}

void FirmwareProtocol::send_renumber(Time now) {
    ++stats_.renumbers;
    spdlog::warn("firmware: it counts lines from {} again (an M110 ran late): re-numbering it to {}", last_m110_, credited_n_);
    tail_.clear();
    write_line("\n");
    // Unnumbered, so nothing numbered follows the M110 before it ran: the M105 behind it is
    // answered only after it, and its "ok T:" ends the resync.
    std::string m110 = "M110 N" + std::to_string(credited_n_);
    write_line(m110 + "\n");
    write_line(std::string(kProbe) + "\n");
    const std::size_t bytes = 1 + m110.size() + 1 + kProbe.size() + 1;
    in_flight_.push_back({-1, std::move(m110), 0, 0, false, true, 0});
    in_flight_.push_back({-1, std::string(kProbe), 0, bytes, true, true, 0});
    bytes_in_flight_ += bytes;
    last_m110_ = credited_n_;
    next_n_ = credited_n_ + 1;
    ++stats_.probes;
    sync_ = Sync::Probing;
    reply_deadline_ = now + seconds(opt_.reply_timeout);
}

void FirmwareProtocol::end_quiet(Time now) {
    quiet_deadline_.reset();
    const auto from = resend_from_;
    resend_from_.reset();
    if (std::exchange(renumber_, false) && !from) {
        rewind(credited_n_ + 1);
        send_renumber(now);
        return;
    }
    if (from) {
        spdlog::debug("firmware: resync from line {}", *from);
        rewind(*from);
        if (advanced_ok_) {
            // Each ok names its line: continue at once.
            sync_ = Sync::None;
            transmit(now);
            if (!in_flight_.empty() && !reply_deadline_) reply_deadline_ = now + seconds(opt_.reply_timeout);
            return;
        }
    }
    // Probe under the next number: taken, it proves every earlier line is in; refused, the
    // firmware names the line it wants.
    send_probe(next_n_, now);
}

void FirmwareProtocol::on_reply_timeout(Time now) {
    reply_deadline_.reset();
    if (in_flight_.empty()) return;
    ++stats_.timeouts;
    if (opt_.reprap) {
        const Entry& f = in_flight_.front();
        if (may_wait_long(f.command) && ++long_waits_ * opt_.reply_timeout < opt_.long_timeout) {
            // Heating, homing, dwelling: wait on (up to long_timeout) before taking silence for a lost line.
            --stats_.timeouts;
            reply_deadline_ = now + seconds(opt_.reply_timeout);
            return;
        }
    }
    if (opt_.klipper) {
        // A pseudo-terminal loses nothing, and Klipper answers a line only once it ran: silence is
        // a long command (G28, M109, G4, a full toolhead queue), never a lost line. Nothing is
        // probed or repeated; only after long_timeout is it taken as gone.
        --stats_.timeouts;
        klipper_silence_ += opt_.reply_timeout;
        if (klipper_silence_ >= opt_.long_timeout) {
            fault("Klipper has not answered for " + std::to_string(int(klipper_silence_)) + " s");
            return;
        }
        spdlog::info("firmware: Klipper still busy with '{}' ({:.0f} s)", in_flight_.front().command, klipper_silence_);
        reply_deadline_ = now + seconds(opt_.reply_timeout);
        return;
    }
    if (++timeouts_in_row_ > opt_.max_timeouts) {
        fault("the firmware has not answered for " + std::to_string(int(opt_.reply_timeout * opt_.max_timeouts)) + " s");
        return;
    }
    long_waits_ = 0;
    if (opt_.reprap) {
        // RepRapFirmware dropped the line (bad checksum) or its ok was lost: it ignores line
        // numbers, so the line goes again as it was.
        const Entry& f = in_flight_.front();
        spdlog::warn("firmware: no reply for {:.1f} s, resending line {}", opt_.reply_timeout, f.n);
        write_line(f.n >= 0 ? proto::numbered(f.n, f.command) + "\n" : f.command + "\n");
        ++stats_.resent;
        reply_deadline_ = now + seconds(opt_.reply_timeout);
        return;
    }
    // Silence: every reply that was coming has come. Marlin drops a repeat of its last line
    // without a word, so nothing is repeated: a probe under a fresh number asks where it is.
    // Earlier M105s were answered or their answers lost: they no longer name an "ok T:".
    spdlog::warn("firmware: no reply for {:.1f} s with {} lines in flight: asking where it is", opt_.reply_timeout, in_flight_.size());
    for (auto& e : in_flight_) e.anchor = false;
    resend_from_.reset();
    quiet_deadline_.reset();
    send_probe(next_n_, now);
}

void FirmwareProtocol::on_time(Time now) {
    if (state_ == State::Booting) {
        if (boot_deadline_ && *boot_deadline_ <= now) greet(now);
        return;
    }
    if (state_ == State::Greeting) {
        if (quiet_deadline_ && *quiet_deadline_ <= now) {
            if (greet_ == Greet::Quiet && m999_after_quiet_) {
                m999_after_quiet_ = false;
                write_line("M999\n");
                quiet_deadline_ = now + seconds(opt_.settle);
                return;
            }
            if (greet_ == Greet::Quiet) send_greeting(now);
            else if (greet_ == Greet::Settle) become_ready();
            if (state_ == State::Ready) transmit(now);
            return;
        }
        if (reply_deadline_ && *reply_deadline_ <= now) {
            ++stats_.timeouts;
            spdlog::warn("firmware: no answer to the greeting, greeting again");
            greet(now);
        }
        return;
    }
    if (state_ != State::Ready) return;
    if (quiet_deadline_ && *quiet_deadline_ <= now) {
        if (sync_ == Sync::Quiet) end_quiet(now);
        else quiet_deadline_.reset();
    }
    if (state_ == State::Ready && reply_deadline_ && *reply_deadline_ <= now) on_reply_timeout(now);
    if (state_ == State::Ready && nudge_deadline_ && *nudge_deadline_ <= now) on_nudge();
}

void FirmwareProtocol::on_line(std::string_view line, Time now) {
    const auto r = proto::classify(line);
    if (state_ == State::Faulted || state_ == State::Booting) {
        if (state_ == State::Booting && r.kind == proto::ReplyKind::Start) {
            greet(now);
            return;
        }
        // The firmware's own numbering (Resend:, "Last Line") means nothing to the sender.
        const bool numbering = r.kind == proto::ReplyKind::Ok || r.kind == proto::ReplyKind::Resend ||
                               r.kind == proto::ReplyKind::LineError;
        if (state_ == State::Faulted && !numbering) emit(Action::Kind::Message, std::string(line));
        else spdlog::info("firmware: {}", line);
        return;
    }
    if (opt_.klipper && state_ == State::Greeting) return on_klipper_greeting(r, line, now);
    if (opt_.klipper) return on_klipper_line(r, line, now);
    if (is_protocol_reply(r.kind)) {
        timeouts_in_row_ = 0;
        long_waits_ = 0;
        if (reply_deadline_) reply_deadline_ = now + seconds(opt_.reply_timeout);
        if (nudge_deadline_) arm_nudge(now);  // silence counts from the last reply
    }
    if (r.kind == proto::ReplyKind::Halted) {
        emit(Action::Kind::Message, std::string(line));
        fault("the firmware stopped: " + std::string(line));
        return;
    }
    if (state_ == State::Greeting) {
        if (r.kind == proto::ReplyKind::Start) {
            greet(now);  // it was still booting
            return;
        }
        const bool report = line.rfind("FIRMWARE_NAME", 0) == 0;
        if (greet_ != Greet::AwaitReport) {
            if (is_protocol_reply(r.kind) || report) quiet_deadline_ = now + seconds(opt_.settle);  // stale: wait on
            if (r.kind != proto::ReplyKind::Ok) spdlog::info("firmware: {}", line);
            return;
        }
        if (report) {
            m115_ = {std::string(line)};
        } else if (line.rfind("Cap:", 0) == 0 && !m115_.empty()) {
            m115_.emplace_back(line);
        } else if (r.kind == proto::ReplyKind::Ok && !m115_.empty()) {
            greet_ = Greet::Settle;  // M115 answered; whatever else comes now is stale
            reply_deadline_.reset();
            quiet_deadline_ = now + seconds(opt_.settle);
        } else if (r.kind == proto::ReplyKind::Resend || r.kind == proto::ReplyKind::LineError) {
            ++stats_.resend_requests;
            greet(now);  // a greeting line was refused (or a stale Resend came): again, after quiet
        } else if (r.kind != proto::ReplyKind::Ok) {
            spdlog::info("firmware: {}", line);
        }
        return;
    }
    // Ready.
    if (is_protocol_reply(r.kind) && sync_ == Sync::Quiet) quiet_deadline_ = now + seconds(opt_.settle);
    switch (r.kind) {
        case proto::ReplyKind::Ok:
            on_ok(r, now);
            return;
        case proto::ReplyKind::Resend: {
            ++stats_.resend_requests;
            const bool confirmed = error_next_ && *error_next_ == r.resend_line;
            error_next_.reset();
            on_refusal(r.resend_line, confirmed, now);
            return;
        }
        case proto::ReplyKind::LineError: {
            const auto last = last_line_of(line);
            if (last) error_next_ = *last + 1;
            else error_next_.reset();
            on_refusal(error_next_, false, now);
            return;
        }
        case proto::ReplyKind::Busy:
            ++stats_.busy;
            emit(Action::Kind::Message, std::string(line));
            return;
        case proto::ReplyKind::Wait:
            return;
        case proto::ReplyKind::Start:
            fault("the firmware restarted (it sent 'start'): its position and temperatures are lost");
            return;
        default:
            if (own_fragment(line)) {
                spdlog::info("firmware, of a piece of a line xlate5 cut: {}", line);
                return;
            }
            emit(Action::Kind::Message, std::string(line));
            return;
    }
}

namespace {

bool starts(std::string_view line, std::string_view prefix) { return line.rfind(prefix, 0) == 0; }

// The words of a command whose letters Klipper's range error leaves out (it prints X Y Z and
// [E]): "G1 X20 A200 F600" -> "A200".
std::string other_axis_words(std::string_view command) {
    std::string out;
    std::size_t i = command.find(' ');
    while (i != std::string_view::npos && i < command.size()) {
        while (i < command.size() && command[i] == ' ') ++i;
        const std::size_t end = std::min(command.find(' ', i), command.size());
        if (end > i) {
            const char l = command[i];
            if (l >= 'A' && l <= 'W' && l != 'E' && l != 'F' && l != 'N') out += (out.empty() ? "" : " ") + std::string(command.substr(i, end - i));
        }
        i = end;
    }
    return out;
}

// GET_POSITION's "gcode: X:1.000000 Y:… E:… A:…" less its "gcode base: …": the position as
// M114 reports it (gcode_move.py: last_position - base_position), with every axis Klipper has.
std::string klipper_report(std::string_view gcode, std::string_view base) {
    const auto values = [](std::string_view s) {
        std::vector<std::pair<char, double>> out;
        for (std::size_t i = 0; i + 1 < s.size(); ++i) {
            if (s[i + 1] != ':' || (i > 0 && s[i - 1] != ' ')) continue;
            double v = 0;
            const auto r = std::from_chars(s.data() + i + 2, s.data() + s.size(), v);
            if (r.ec == std::errc()) out.emplace_back(s[i], v);
        }
        return out;
    };
    const auto g = values(gcode), b = values(base);
    std::string out;
    char buf[48];
    for (const auto& [letter, v] : g) {
        double offset = 0;
        for (const auto& [l, w] : b)
            if (l == letter) offset = w;
        std::snprintf(buf, sizeof buf, "%s%c:%.6f", out.empty() ? "" : " ", letter, v - offset);
        out += buf;
    }
    return out;
}

}  // namespace

void FirmwareProtocol::on_klipper_greeting(const proto::Reply& r, std::string_view line, Time now) {
    if (greet_ != Greet::AwaitReport) {
        if (r.kind == proto::ReplyKind::Ok || starts(line, "!!") || starts(line, "//")) quiet_deadline_ = now + seconds(opt_.settle);  // stale: wait on
        if (r.kind != proto::ReplyKind::Ok) spdlog::info("firmware: {}", line);
        return;
    }
    if (r.kind == proto::ReplyKind::Ok && m115_.empty()) {
        // M115's ok carries the report (gcode.py: gcmd.ack(msg)); a plain ok is stale.
        std::string_view p = r.payload;
        while (!p.empty() && p.front() == ' ') p.remove_prefix(1);
        if (starts(p, "FIRMWARE_NAME")) m115_ = {std::string(p)};
        return;
    }
    if (starts(line, "// Klipper state: Ready")) {
        klipper_ready_ = true;
        return;
    }
    if (starts(line, "!!")) {
        klipper_not_ready_ = std::string(line);
        return;
    }
    if (r.kind != proto::ReplyKind::Ok) {
        spdlog::info("firmware: {}", line);
        return;
    }
    // STATUS answered.
    reply_deadline_.reset();
    if (klipper_ready_) {
        greet_ = Greet::Settle;
        quiet_deadline_ = now + seconds(opt_.settle);
        return;
    }
    // Starting, restarting or shut down: asked again, boot_wait later.
    if (++klipper_waits_ > klipper::kNotReadyGreetings) {
        fault("Klipper is not ready (" + klipper_not_ready_ + "); after a shutdown it needs FIRMWARE_RESTART");
        return;
    }
    spdlog::warn("firmware: Klipper is not ready ({}); asking again in {:.1f} s", klipper_not_ready_, opt_.boot_wait);
    --greetings_;
    m115_.clear();
    greet_ = Greet::Quiet;
    quiet_deadline_ = now + seconds(std::max(opt_.boot_wait, opt_.settle));
}

void FirmwareProtocol::on_klipper_line(const proto::Reply& r, std::string_view line, Time now) {
    klipper_silence_ = 0;
    if (reply_deadline_ && r.kind == proto::ReplyKind::Ok) reply_deadline_ = now + seconds(opt_.reply_timeout);
    const bool asking_position = !in_flight_.empty() && in_flight_.front().command == "GET_POSITION";
    if (r.kind == proto::ReplyKind::Ok) {
        if (in_flight_.empty()) {
            // Every line xlate5 sent is answered: another writer on Klipper's pty, or its own output.
            ++stats_.stray_oks;
            spdlog::warn("firmware: an ok with no line in flight (another host writing to Klipper's pty?)");
            return;
        }
        if (asking_position) {
            if (!klipper_gcode_.empty()) emit(Action::Kind::Message, klipper_report(klipper_gcode_, klipper_base_));
            klipper_gcode_.clear();
            klipper_base_.clear();
        }
        credit_front(r.payload);
        transmit(now);
        emit(Action::Kind::Progress);
        return;
    }
    if (asking_position && starts(line, "// ")) {
        // GET_POSITION's lines: "gcode:" and "gcode base:" make the report; the rest is kept from senders.
        if (starts(line, "// gcode: ")) klipper_gcode_ = std::string(line.substr(10));
        else if (starts(line, "// gcode base: ")) klipper_base_ = std::string(line.substr(15));
        else spdlog::debug("firmware: {}", line);
        return;
    }
    if (starts(line, "// Klipper state: Shutdown") || starts(line, "// Klipper state: Disconnect")) {
        emit(Action::Kind::Message, std::string(line));
        fault("Klipper stopped (" + std::string(line.substr(3)) + "): nothing more runs until FIRMWARE_RESTART");
        return;
    }
    if (starts(line, "!!")) {
        // The error of the line in front (its ok follows). Klipper would run on with the next
        // line from a position the translator did not plan; the print stops here instead.
        if (in_flight_.empty()) {
            emit(Action::Kind::Message, std::string(line));
            return;
        }
        const std::string& command = in_flight_.front().command;
        std::string why = "Klipper refused '" + command + "': " + std::string(line.substr(std::min<std::size_t>(3, line.size())));
        if (line.find("Move out of range") != std::string_view::npos) {
            const std::string others = other_axis_words(command);
            if (!others.empty()) why += " (its message leaves out " + others + ": check those axes' position_min/max against the machine file)";
        }
        emit(Action::Kind::Message, std::string(line));
        fault(why);
        return;
    }
    emit(Action::Kind::Message, std::string(line));
}

bool FirmwareProtocol::own_fragment(std::string_view line) const {
    // Marlin echoes what it could not run: `echo:Unknown command: "<text>"`. A command of the
    // sender's begins with a letter; the tail of a line xlate5 sent in two parts begins with a
    // digit (head_within), and one that a resync cut elsewhere is part of a line in flight.
    constexpr std::string_view kUnknown = "echo:Unknown command:";
    if (line.rfind(kUnknown, 0) != 0) return false;
    std::string_view text = line.substr(kUnknown.size());
    while (!text.empty() && (text.front() == ' ' || text.front() == '"')) text.remove_prefix(1);
    if (!text.empty() && text.back() == '"') text.remove_suffix(1);
    if (text.empty()) return true;
    const char c = text.front();
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'))) return true;
    if (sync_ == Sync::None) return false;
    for (const auto& e : in_flight_)
        if (e.n >= 0 && proto::numbered(e.n, e.command).find(text) != std::string::npos) return true;
    return false;
}

std::size_t FirmwareProtocol::sender_lines_queued() const {
    // Lines of the sender's, not the firmware lines they became nor xlate5's probes: one sender
    // line may be many moves, queued in order, so its pieces are neighbours.
    std::size_t n = 0;
    std::uint64_t last = 0;
    const auto count = [&](std::uint64_t origin) {
        if (origin != 0 && origin != last) ++n;
        if (origin != 0) last = origin;
    };
    for (const auto& e : in_flight_) count(e.origin);
    for (const auto& i : unsent_) count(i.origin);
    return n;
}

void FirmwareProtocol::fault(const std::string& why) {
    if (state_ == State::Faulted) return;
    const std::size_t lost = sender_lines_queued();
    // A line half sent stays so: ending it now would draw a refusal the sender would be shown;
    // restart() ends it before M999.
    state_ = State::Faulted;
    unsent_.clear();
    in_flight_.clear();
    bytes_in_flight_ = tagged_in_flight_ = 0;
    sync_ = Sync::None;
    boot_deadline_.reset();
    quiet_deadline_.reset();
    reply_deadline_.reset();
    nudge_deadline_.reset();
    spdlog::error("firmware: {} ({} of the sender's lines not executed or not confirmed)", why, lost);
    emit(Action::Kind::Fault, why, 0, lost);
}

}  // namespace xlate5
