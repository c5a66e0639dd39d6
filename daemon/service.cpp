#include "daemon/service.hpp"

#include <cstdio>
#include <cstdlib>
#include <spdlog/spdlog.h>

#include "daemon/line_protocol.hpp"
#include "translators/error.hpp"

namespace xlate5 {
namespace {

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
bool split_for_firmware(const FirmwareLink& fw, const std::string& cmd, std::vector<std::string>& parts) {
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

}  // namespace

std::vector<std::string> firmware_commands(const Machine& machine, const std::vector<std::string>& lines, const TranslatorOptions& options) {
    const Kinematics kin(machine);
    TranslatorOptions o = options;
    o.input_name = "sender";
    Translator t(kin, o);
    std::vector<std::string> out;
    std::string text;
    std::uint64_t n = 0;
    for (const auto& l : lines) {
        text.clear();
        t.feed(l, ++n, text);
        proto::append_commands(text, out);
    }
    return out;
}

Service::Service(asio::io_context& io, const Machine& machine, ServiceOptions options)
    : io_(io), machine_(machine), opt_(std::move(options)), busy_timer_(io), drain_timer_(io) {
    kin_ = std::make_unique<Kinematics>(machine_);
    reset_translator();
}

Service::~Service() {
    for (auto& s : sessions_) s->close();
}

void Service::reset_translator() {
    // A fresh interpreter: modal state from the machine file, position unknown until homed or placed.
    translator_ = std::make_unique<Translator>(*kin_, opt_.translator);
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

void Service::add_sender(std::shared_ptr<Link> link, const std::string& name) {
    auto s = std::make_shared<SenderSession>(std::move(link), *this, name);
    sessions_.push_back(s);
    s->start();
    spdlog::info("sender connected: {}", name);
}

void Service::sender_gone(SenderSession& s) {
    spdlog::info("sender gone: {}", s.name());
    asio::post(io_, [this, p = &s] {
        std::erase_if(sessions_, [p](const auto& x) { return x.get() == p; });
    });
}

bool Service::idle() const { return pending_.empty() && (!firmware_ || firmware_->idle()); }

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
    if (firmware_) firmware_->send_now(command);
    if (proto::command_code(command).is('M', 112)) {
        // Whether or not the firmware acts on it at once (EMERGENCY_PARSER), nothing queued behind it may run.
        const auto dropped = firmware_ ? firmware_->drop_unsent() : 0;
        stop("emergency stop (M112) from " + s.name() + "; " + std::to_string(dropped) + " queued lines dropped");
    }
}

void Service::sender_command(SenderSession& s, std::string_view command, proto::Code code, std::uint64_t line_no) {
    if (code.is('M', 999)) {
        // Restart after a stop: the queue is empty, the firmware is greeted again, and the
        // translator starts over (the position is unknown until the program homes or places it).
        if (!stopped()) {
            s.ok();
            return;
        }
        spdlog::info("{}: M999, restarting after: {}", s.name(), stop_reason_);
        if (firmware_ && !firmware_->link().open()) {
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
        } else if (firmware_) {
            firmware_->restart();
        }
        stop_reason_.clear();
        pending_.clear();
        deferred_.clear();
        reset_translator();
        s.ok();
        return;
    }
    pending_.push_back({s.weak_from_this(), std::string(command), code, line_no});
    pump();
}

void Service::pump() {
    // While draining for a stop, lines not yet acknowledged stay with the sender, unsent.
    while (!pending_.empty() && !draining_) {
        if (!stopped() && firmware_ && (firmware_->state() != FirmwareLink::State::Ready || firmware_->queued() >= opt_.queue_lines)) {
            arm_busy();  // the sender waits for its ok: keep it from timing out
            return;
        }
        const Pending p = std::move(pending_.front());
        pending_.pop_front();
        process(p);
    }
    check_drained();
}

void Service::process(const Pending& p) {
    auto session = p.session.lock();
    if (stopped() || !firmware_) {
        if (session) {
            session->send_line("Error:Printer stopped (xlate5): " + (stopped() ? stop_reason_ : std::string("no firmware")) +
                               ". Fix the cause and send M999 to restart.");
            session->ok();
        }
        ++stats_.rejected;
        return;
    }
    ++stats_.lines_in;
    out_.clear();
    try {
        translator_->feed(p.command, p.line_no, out_);
    } catch (const InputError& e) {
        if (session) session->send_line(std::string("Error:xlate5: ") + e.what());
        stop(std::string("line ") + std::to_string(p.line_no) + " cannot be translated: " + e.message());
        if (session) session->ok();
        return;
    }
    const bool wait_for_firmware = answered_by_firmware(p.code);
    std::uint64_t tag = 0;
    std::vector<std::string> parts, commands, lines;
    proto::append_commands(out_, commands);
    for (const auto& cmd : commands) {
        if (!split_for_firmware(*firmware_, cmd, parts)) {
            if (session) session->send_line("Error:xlate5: line " + std::to_string(p.line_no) + ": '" + cmd +
                                            "' is longer than the firmware's line buffer");
            stop("line " + std::to_string(p.line_no) + " is too long for the firmware");
            if (session) session->ok();
            return;
        }
        if (parts.size() > 1) ++stats_.split_long;
        for (auto& part : parts) lines.push_back(std::move(part));
    }
    // All or nothing: a line that fails above leaves nothing of itself in the queue.
    for (std::size_t i = 0; i < lines.size(); ++i) {
        if (wait_for_firmware && i + 1 == lines.size()) {
            tag = next_tag_++;
            deferred_[tag] = p.session;
        }
        firmware_->enqueue(std::move(lines[i]), tag);
        ++stats_.lines_out;
    }
    if (session && tag == 0) session->ok();
}

void Service::stop(const std::string& why) {
    if (stopped()) return;
    stop_reason_ = why;
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
    busy_timer_.async_wait([this](boost::system::error_code ec) {
        busy_armed_ = false;
        if (ec || pending_.empty()) return;
        if (auto s = pending_.front().session.lock()) s->send_line("echo:busy: processing");
        arm_busy();
    });
}

void Service::firmware_ready(const std::vector<std::string>&) {
    pump();
}

void Service::firmware_acked(std::uint64_t tag, std::string_view ok_payload) {
    auto it = deferred_.find(tag);
    if (it == deferred_.end()) return;
    if (auto s = it->second.lock()) s->ok(ok_payload);
    deferred_.erase(it);
}

void Service::firmware_progress() { pump(); }

void Service::firmware_fault(const std::string& why, std::size_t lines_not_executed) {
    broadcast("Error:xlate5: " + why + "; print stopped, " + std::to_string(lines_not_executed) +
              " queued lines were not sent (nothing is replayed). Send M999 to restart.");
    stop(why);
    reset_translator();
    check_drained();
}

std::string Service::tool_space_position(std::string_view report) const {
    // "X:7.00 Y:0.00 Z:0.00 A:10.00 B:5.00 E:0.00 Count X:560 …": the joints as the firmware
    // knows them (compensated) -> nominal joints -> tip and angles in the part frame.
    std::vector<double> q = translator_->joints();
    double e = 0;
    bool have_e = false;
    const auto count = report.find("Count");
    std::string_view words = report.substr(0, count);
    for (std::size_t i = 0; i + 1 < words.size(); ++i) {
        if (words[i + 1] != ':' || (i > 0 && words[i - 1] != ' ')) continue;
        const double v = std::strtod(std::string(words.substr(i + 2, 24)).c_str(), nullptr);
        if (words[i] == 'E') {
            e = v, have_e = true;
            continue;
        }
        for (std::size_t j = 0; j < machine_.joints.size(); ++j)
            if (machine_.joints[j].output == words[i]) q[j] = v;
    }
    machine_.compensation.undo(q);
    const Pose pose = kin_->forward(q);
    const Eigen::Vector3d tip = pose.tip - translator_->program_offset();
    char buf[96];
    std::snprintf(buf, sizeof buf, "X:%.2f Y:%.2f Z:%.2f", tip.x(), tip.y(), tip.z());
    std::string out = buf;
    for (std::size_t j = 0; j < machine_.joints.size(); ++j) {
        if (!machine_.joints[j].rotary) continue;
        std::snprintf(buf, sizeof buf, " %c:%.2f", machine_.joints[j].name, q[j]);
        out += buf;
    }
    if (have_e) {
        std::snprintf(buf, sizeof buf, " E:%.2f", e);
        out += buf;
    }
    return out;
}

void Service::firmware_message(std::string_view line) {
    if (line.rfind("X:", 0) == 0 && line.find(" Y:") != std::string_view::npos) {
        broadcast(tool_space_position(line));
        return;
    }
    broadcast(line);
}

void Service::drain(double timeout, std::function<void(const std::string&)> done) {
    draining_ = true;
    drained_ = std::move(done);
    drain_timer_.expires_after(std::chrono::milliseconds(std::int64_t(timeout * 1000)));
    drain_timer_.async_wait([this](boost::system::error_code ec) {
        if (ec || !drained_) return;
        const auto left = firmware_ ? firmware_->queued() : 0;
        auto done = std::move(drained_);
        drained_ = nullptr;
        done("not drained after the timeout: " + std::to_string(left) + " lines not sent; the print is stopped between lines");
    });
    check_drained();
}

void Service::check_drained() {
    if (!draining_ || !drained_) return;
    const bool fw_done = !firmware_ || firmware_->idle() || firmware_->state() == FirmwareLink::State::Faulted;
    if (!fw_done) return;
    drain_timer_.cancel();
    auto done = std::move(drained_);
    drained_ = nullptr;
    done(stopped() ? "stopped: " + stop_reason_ : std::string("drained: every accepted line was executed"));
}

}  // namespace xlate5
