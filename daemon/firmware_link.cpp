#include "daemon/firmware_link.hpp"

#include <algorithm>
#include <chrono>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"

namespace xlate5 {
namespace {
std::chrono::milliseconds seconds(double s) { return std::chrono::milliseconds(std::int64_t(s * 1000)); }

// Commands a firmware may take minutes over without a word (RepRapFirmware sends no busy:
// keepalives): silence after them is not a lost line.
bool may_wait_long(std::string_view numbered_line) {
    const auto c = proto::command_code(proto::parse_received(numbered_line).command);
    if (c.letter == 'G') return c.code10 == 40 || c.code10 == 280 || c.code10 == 290;                  // G4, G28, G29
    if (c.letter != 'M' || c.code10 % 10) return false;
    switch (c.code10 / 10) {
        case 0: case 1: case 109: case 116: case 190: case 191: case 303: case 400: case 600: return true;
        default: return false;
    }
}
}  // namespace

FirmwareLink::FirmwareLink(std::shared_ptr<Link> link, FirmwareOptions options, Listener& listener)
    : link_(std::move(link)), opt_(options), listener_(listener),
      boot_timer_(link_->stream_executor()), reply_timer_(link_->stream_executor()), grace_timer_(link_->stream_executor()) {}

FirmwareLink::~FirmwareLink() {
    *alive_ = false;
    link_->close();
}

int FirmwareLink::window() const {
    if (opt_.reprap) return 1;  // a dropped line is never reported: anything sent after it would run out of order
    if (opt_.window > 0) return opt_.window;
    return learned_window_ > 0 ? learned_window_ : 2;
}

bool FirmwareLink::fits(std::string_view command) const {
    // "N<n> " + command + "*<cs>" + '\n', with room for line numbers up to 8 digits.
    return command.size() + 10 + 4 + 1 <= opt_.max_line;
}

void FirmwareLink::start() {
    auto alive = alive_;
    link_->start([this, alive](std::string_view line) { if (*alive) on_line(line); },
                 [this, alive](const std::string& why) {
                     if (*alive && !why.empty()) fault("the port " + link_->name() + " closed: " + why);
                 });
    state_ = State::Booting;
    // A board resets when its port opens and says "start" when it is up; one that does not
    // reset stays quiet, so after boot_wait xlate5 says hello anyway.
    boot_timer_.expires_after(seconds(opt_.boot_wait));
    boot_timer_.async_wait([this, alive](boost::system::error_code ec) {
        if (!ec && *alive && state_ == State::Booting) hello();
    });
}

void FirmwareLink::restart() {
    if (!link_->open()) return;
    hello();
}

void FirmwareLink::hello() {
    boot_timer_.cancel();
    waiting_.clear();
    sent_.clear();
    in_flight_.clear();
    after_resend_ = probing_ = false;
    grace_timer_.cancel();
    timeouts_in_row_ = 0;
    m115_.clear();
    state_ = State::Hello;
    first_n_ = 0;
    last_n_ = -1;
    next_tx_ = 0;
    ++epoch_;
    // Line 0 sets the numbering; M115 tells what the firmware is and can do.
    sent_.push_back({proto::numbered(0, "M110 N0") + "\n", 0});
    sent_.push_back({proto::numbered(1, "M115") + "\n", 0});
    last_n_ = 1;
    hello_m115_ = 1;
    transmit();
}

void FirmwareLink::enqueue(std::string command, std::uint64_t tag) {
    waiting_.push_back({std::move(command), tag});
    transmit();
}

void FirmwareLink::send_now(std::string_view command) {
    if (!link_->open()) return;
    std::string line(command);
    line += '\n';
    link_->send(line);
    // Marlin also runs it through its queue and answers ok in turn: an unnumbered flight keeps
    // the ok count straight. A halted firmware never answers, which the fault clears.
    if (state_ == State::Ready || state_ == State::Hello) in_flight_.push_back({-1, epoch_, line.size()});
    arm_timer();
}

std::size_t FirmwareLink::bytes_in_flight() const {
    std::size_t b = 0;
    for (const auto& f : in_flight_) b += f.bytes;
    return b;
}

void FirmwareLink::transmit() {
    if ((state_ != State::Ready && state_ != State::Hello) || after_resend_) return;
    const std::size_t limit = state_ == State::Hello ? 1 : std::size_t(window());
    std::size_t bytes = bytes_in_flight();
    while (in_flight_.size() < limit) {
        if (next_tx_ > last_n_) {
            if (state_ != State::Ready || waiting_.empty()) break;
            auto& w = waiting_.front();
            ++last_n_;
            sent_.push_back({proto::numbered(last_n_, w.command) + "\n", w.tag});
            waiting_.pop_front();
        }
        const auto& s = sent_[std::size_t(next_tx_ - first_n_)];
        if (!in_flight_.empty() && bytes + s.text.size() > opt_.rx_bytes) break;  // the firmware's buffer is full
        link_->send(s.text);
        in_flight_.push_back({next_tx_, epoch_, s.text.size()});
        bytes += s.text.size();
        ++next_tx_;
        ++stats_.sent;
    }
    arm_timer();
}

void FirmwareLink::arm_timer() {
    if (in_flight_.empty() || state_ == State::Faulted) {
        reply_timer_.cancel();
        return;
    }
    auto alive = alive_;
    reply_timer_.expires_after(seconds(opt_.reply_timeout));
    reply_timer_.async_wait([this, alive](boost::system::error_code ec) {
        if (!ec && *alive) on_timeout();
    });
}

void FirmwareLink::on_timeout() {
    if (in_flight_.empty() || state_ == State::Faulted) return;
    ++stats_.timeouts;
    if (++timeouts_in_row_ > opt_.max_timeouts) {
        fault("the firmware has not answered for " + std::to_string(int(opt_.reply_timeout * opt_.max_timeouts)) + " s");
        return;
    }
    // Nothing came back: the oldest line, or its ok, was lost. Send it again under the same
    // number: Marlin runs it if it never arrived and refuses it ("Line Number is not Last Line
    // Number+1") if it did, so it never runs twice; RepRapFirmware dropped it (bad checksum).
    auto it = std::find_if(in_flight_.begin(), in_flight_.end(), [](const Flight& f) { return f.n >= 0; });
    if (it == in_flight_.end()) {
        in_flight_.clear();  // only unnumbered emergency lines: nothing to recover
        transmit();
        return;
    }
    const Flight f = *it;
    if (may_wait_long(sent_[std::size_t(f.n - first_n_)].text) && ++long_waits_ * opt_.reply_timeout < opt_.long_timeout) {
        // Heating, homing, dwelling: wait on (up to long_timeout) before taking silence for a lost line.
        --stats_.timeouts;
        --timeouts_in_row_;
        arm_timer();
        return;
    }
    long_waits_ = 0;
    spdlog::warn("firmware: no reply for {:.1f} s, resending line {}", opt_.reply_timeout, f.n);
    in_flight_.erase(in_flight_.begin(), it + 1);  // anything before it was unnumbered
    in_flight_.push_front({f.n, epoch_, f.bytes});
    link_->send(sent_[std::size_t(f.n - first_n_)].text);
    ++stats_.resent;
    probing_ = !opt_.reprap;
    arm_timer();
}

void FirmwareLink::on_line(std::string_view line) {
    const auto reply = proto::classify(line);
    timeouts_in_row_ = 0;  // any sign of life
    long_waits_ = 0;
    if (!in_flight_.empty()) arm_timer();
    if (after_resend_) {
        after_resend_ = false;
        grace_timer_.cancel();
        if (reply.kind == proto::ReplyKind::Ok) {
            resend_ok_ = ResendOk::Yes;  // the ok that follows Resend belongs to the refused line
            transmit();
            return;
        }
        if (resend_ok_ == ResendOk::Unknown) resend_ok_ = ResendOk::No;
        transmit();
    }
    switch (reply.kind) {
        case proto::ReplyKind::Ok:
            on_ok(reply);
            return;
        case proto::ReplyKind::Resend:
            on_resend(reply.resend_line);
            return;
        case proto::ReplyKind::LineError:
            spdlog::debug("firmware: {}", line);
            return;
        case proto::ReplyKind::Busy:
            ++stats_.busy;
            listener_.firmware_message(line);
            return;
        case proto::ReplyKind::Wait:
            return;
        case proto::ReplyKind::Start:
            if (state_ == State::Booting) {
                hello();
            } else if (state_ != State::Faulted) {
                fault("the firmware restarted (it sent 'start'): its position and temperatures are lost");
            }
            return;
        case proto::ReplyKind::Halted:
            listener_.firmware_message(line);
            fault("the firmware stopped: " + std::string(line));
            return;
        case proto::ReplyKind::Error:
        case proto::ReplyKind::Other:
            if (state_ == State::Hello && (line.rfind("FIRMWARE_NAME", 0) == 0 || line.rfind("Cap:", 0) == 0)) {
                m115_.emplace_back(line);
                return;
            }
            if (state_ == State::Booting || state_ == State::Hello) {
                spdlog::info("firmware: {}", line);  // its boot messages are for xlate5, not the sender
                return;
            }
            listener_.firmware_message(line);
            return;
    }
}

void FirmwareLink::on_ok(const proto::Reply& reply) {
    if (reply.buffer_free && opt_.window == 0) {
        // ADVANCED_OK: B is the free command-buffer slots; one more is being executed.
        learned_window_ = std::clamp(std::max(learned_window_, *reply.buffer_free + 1), 1, 32);
    }
    if (in_flight_.empty()) return;  // an ok nobody waits for (e.g. after a timeout probe was answered twice)
    if (reply.ok_line) {
        // ADVANCED_OK names the line: everything up to it is done.
        const std::int64_t n = *reply.ok_line;
        while (!in_flight_.empty() && (in_flight_.front().n < 0 || in_flight_.front().n <= n)) {
            const auto f = in_flight_.front();
            in_flight_.pop_front();
            if (f.n >= 0) acknowledge(f.n, f.n == n ? reply.payload : std::string_view());
        }
    } else {
        const auto f = in_flight_.front();
        in_flight_.pop_front();
        if (f.n >= 0) acknowledge(f.n, reply.payload);
    }
    probing_ = false;
    // Old history is dropped once acknowledged.
    while (sent_.size() > opt_.history && first_n_ < next_tx_ &&
           (in_flight_.empty() || std::all_of(in_flight_.begin(), in_flight_.end(), [&](const Flight& f) { return f.n < 0 || f.n > first_n_; }))) {
        sent_.pop_front();
        ++first_n_;
    }
    transmit();
    listener_.firmware_progress();
}

void FirmwareLink::acknowledge(std::int64_t n, std::string_view payload) {
    ++stats_.acked;
    if (state_ == State::Hello && n == hello_m115_) {
        state_ = State::Ready;
        spdlog::info("firmware ready: {}", m115_.empty() ? std::string("(no M115 report)") : m115_.front());
        listener_.firmware_ready(m115_);
        return;
    }
    const auto& s = sent_[std::size_t(n - first_n_)];
    if (s.tag) listener_.firmware_acked(s.tag, payload);
}

void FirmwareLink::on_resend(std::int64_t n) {
    ++stats_.resend_requests;
    if (resend_ok_ != ResendOk::No) {
        after_resend_ = true;
        auto alive = alive_;
        grace_timer_.expires_after(std::chrono::milliseconds(100));
        grace_timer_.async_wait([this, alive](boost::system::error_code ec) {
            if (ec || !*alive || !after_resend_) return;
            after_resend_ = false;  // no ok came with the Resend
            if (resend_ok_ == ResendOk::Unknown) resend_ok_ = ResendOk::No;
            transmit();
        });
    }
    if (n < first_n_ || n > last_n_ + 1) {
        fault("the firmware asked for line " + std::to_string(n) + ", which xlate5 " +
              (n < first_n_ ? "no longer keeps" : "never sent") + " (it restarted or lost its place)");
        return;
    }
    if (probing_) {
        // Answer to a resent line after a timeout: every line before n arrived; their oks were lost.
        probing_ = false;
        while (!in_flight_.empty() && in_flight_.front().n < n) {
            const auto f = in_flight_.front();
            in_flight_.pop_front();
            if (f.n >= 0) acknowledge(f.n, {});
        }
    }
    // Each line sent after the refused one is refused in turn with the same "Resend: n": one
    // flight from before the rewind is consumed per request, and only a fresh refusal rewinds.
    auto it = std::find_if(in_flight_.begin(), in_flight_.end(), [&](const Flight& f) { return f.n >= n; });
    const bool stale = it != in_flight_.end() && it->epoch < epoch_;
    if (it != in_flight_.end()) in_flight_.erase(it);
    if (!stale) {
        ++epoch_;
        next_tx_ = n;
        spdlog::debug("firmware: resend from line {}", n);
    }
    transmit();
    listener_.firmware_progress();
}

void FirmwareLink::fault(const std::string& why) {
    if (state_ == State::Faulted) return;
    const std::size_t lost = queued();
    state_ = State::Faulted;
    waiting_.clear();
    in_flight_.clear();
    next_tx_ = last_n_ + 1;
    reply_timer_.cancel();
    boot_timer_.cancel();
    grace_timer_.cancel();
    after_resend_ = false;
    spdlog::error("firmware: {} ({} lines not executed)", why, lost);
    listener_.firmware_fault(why, lost);
}

}  // namespace xlate5
