// SPDX-License-Identifier: GPL-3.0-or-later
// The firmware protocol core on its own, with no port and no pseudo-terminal: a scripted clock
// and scripted firmware replies, written the way Marlin answers (docs/service.md,
// "Marlin's receive rules"), and what the core writes checked line by line.
#include <doctest/doctest.h>

#include <algorithm>
#include <optional>
#include <utility>
#include <spdlog/spdlog.h>

#include "daemon/firmware_protocol.hpp"
#include "daemon/line_checker.hpp"
#include "daemon/line_protocol.hpp"

using namespace xlate5;

namespace {

using Kind = FirmwareProtocol::Action::Kind;

struct Script {
    FirmwareOptions opt;
    FirmwareProtocol p;
    FirmwareProtocol::Time t = FirmwareProtocol::Clock::now();
    std::vector<std::string> writes;             // every line written, in order (blank ones counted apart)
    std::vector<std::string> raw;                // every write as it was made
    std::string stream;                          // bytes written after the last newline
    std::size_t blank_lines = 0;
    std::vector<std::pair<std::uint64_t, std::string>> acked;
    std::vector<std::string> faults, messages;
    std::vector<std::size_t> lost;
    bool ready = false;

    // The nudge (one empty line after a short silence) is off unless a test asks for it: the
    // other tests count the writes of their own mechanism; the nudge's are tested on their own.
    // `timing`: reply_timeout and settle, when a test needs its own.
    static FirmwareOptions defaults(FirmwareOptions o, bool nudge, std::optional<std::pair<double, double>> timing) {
        spdlog::set_level(spdlog::level::off);
        o.boot_wait = 1;
        o.reply_timeout = timing ? timing->first : 2;
        o.settle = timing ? timing->second : 0.1;
        if (!nudge) o.nudge = 0;
        return o;
    }
    explicit Script(FirmwareOptions o = {}, bool nudge = false, std::optional<std::pair<double, double>> timing = {})
        : opt(defaults(o, nudge, timing)), p(opt) {}

    void collect() {
        for (auto& a : p.take_actions()) {
            switch (a.kind) {
                case Kind::Write: {
                    // The bytes as the firmware receives them: a write may end mid-line (a line
                    // sent in two parts) or hold several lines.
                    raw.push_back(a.text);
                    stream += a.text;
                    std::size_t e;
                    while ((e = stream.find('\n')) != std::string::npos) {
                        if (e == 0) ++blank_lines;  // the newline before a probe
                        else writes.push_back(stream.substr(0, e));
                        stream.erase(0, e + 1);
                    }
                    break;
                }
                case Kind::Ready: ready = true; break;
                case Kind::Acked: acked.emplace_back(a.tag, a.text); break;
                case Kind::Message: messages.push_back(a.text); break;
                case Kind::Fault: faults.push_back(a.text), lost.push_back(a.lost); break;
                case Kind::Progress: break;
            }
        }
    }
    // Lets `s` seconds pass, firing deadlines as they come.
    void pass(double s) {
        const auto end = t + std::chrono::duration_cast<FirmwareProtocol::Clock::duration>(std::chrono::duration<double>(s));
        for (;;) {
            const auto d = p.deadline();
            if (!d || *d > end) break;
            t = std::max(t, *d);
            p.on_time(t);
            collect();
        }
        t = end;
    }
    void reply(std::string_view line) {
        p.on_line(line, t);
        collect();
    }
    std::uint64_t origin = 0;  // each command enqueued is a sender's line of its own
    void enqueue(const std::string& c, std::uint64_t tag = 0) {
        p.enqueue(c, tag, t, ++origin);
        collect();
    }
    std::vector<std::string> take_writes() { return std::exchange(writes, {}); }

    // Up to Ready, as a virtual Marlin answers: start, the greeting, its M115.
    void greet(std::string_view name = "FIRMWARE_NAME:Marlin 2.1.2 PROTOCOL_VERSION:1.0") {
        p.open(t);
        reply("start");
        pass(opt.settle + std::min(0.1, opt.reply_timeout / 2));  // quiet (0.2 s with the defaults)
        const auto w = take_writes();
        REQUIRE(w.size() == 2);
        CHECK(w[0] == proto::numbered(0, "M110 N1"));
        CHECK(w[1] == "M115");
        reply("ok");
        reply(name);
        reply("Cap:EMERGENCY_PARSER:1");
        reply("ok");
        pass(opt.settle + std::min(0.1, opt.reply_timeout / 2));  // quiet again
    }
};

// A scripted Marlin for the lines the core writes after the greeting: its line checker (the
// virtual printer's), a receive buffer emptied by every refusal, and one line damaged on the
// way. Everything written since the last call arrived together, in order.
struct ScriptedMarlin {
    proto::LineChecker checker;
    std::string damage;               // the first line carrying this command arrives damaged
    std::vector<std::string> taken;   // commands taken, in order
    std::size_t refusals = 0;
    ScriptedMarlin() { checker.set_last_line(1); }  // the greeting's M110 N0 and M115
    void answer(Script& s) {
        const auto w = s.take_writes();
        for (const auto& line : w) {
            auto r = checker.check(line);
            if (!damage.empty() && r.verdict == proto::LineChecker::Verdict::Take && r.command == damage) {
                damage.clear();
                checker.set_last_line(*r.number - 1);
                r.verdict = proto::LineChecker::Verdict::Refuse;
                r.why = proto::kErrChecksumMismatch;
            }
            if (r.verdict == proto::LineChecker::Verdict::Duplicate) continue;
            if (r.verdict == proto::LineChecker::Verdict::Refuse) {
                ++refusals;
                s.reply(checker.error_line(r.why));
                s.reply(checker.resend_line());
                s.reply("ok");
                return;  // the rest of the receive buffer is flushed
            }
            taken.emplace_back(r.command);
            s.reply(r.command == "M105" ? "ok T:20.0 /0.0" : "ok");
        }
    }
};

// The number a written line carries.
std::int64_t number_of(const std::string& line) { return *proto::parse_received(line).number; }
std::string command_of(const std::string& line) { return std::string(proto::parse_received(line).command); }

}  // namespace

TEST_CASE("protocol: the greeting waits for quiet, takes M115's word only from FIRMWARE_NAME on, then is ready") {
    Script s;
    s.p.open(s.t);
    s.reply("start");
    // Stale replies of an earlier session keep the greeting waiting: nothing is written meanwhile.
    s.pass(0.05);
    s.reply("ok");
    s.pass(0.05);
    s.reply("Resend: 77");
    s.pass(0.05);
    CHECK(s.writes.empty());
    s.pass(0.2);
    REQUIRE(s.writes.size() == 2);
    s.take_writes();
    s.reply("ok");  // M110's, or a stale one: not the M115's answer
    s.pass(0.05);
    CHECK_FALSE(s.ready);
    s.reply("FIRMWARE_NAME:Marlin 2.1.2");
    s.reply("Cap:AUTOREPORT_POS:0");
    s.reply("ok");
    CHECK_FALSE(s.ready);  // not before the settle
    s.pass(0.2);
    CHECK(s.ready);
    CHECK(s.p.m115() == std::vector<std::string>{"FIRMWARE_NAME:Marlin 2.1.2", "Cap:AUTOREPORT_POS:0"});
    s.enqueue("G28");
    REQUIRE(s.writes.size() == 1);
    CHECK(s.writes[0] == proto::numbered(2, "G28"));
}

TEST_CASE("protocol: a Resend during the greeting greets again; it never becomes ready without its own M115 answer") {
    Script s;
    s.p.open(s.t);
    s.reply("start");
    s.pass(0.2);
    REQUIRE(s.take_writes().size() == 2);
    // The firmware still had an old number and answered something with a refusal.
    s.reply("Error:Line Number is not Last Line Number+1, Last Line: 1000");
    s.reply("Resend: 1001");
    s.reply("ok");
    s.pass(0.05);
    CHECK(s.writes.empty());
    s.pass(0.2);
    const auto w = s.take_writes();
    REQUIRE(w.size() == 2);  // greeted again from the start
    CHECK(w[0] == proto::numbered(0, "M110 N1"));
    CHECK(w[1] == "M115");
    s.reply("ok");
    s.reply("FIRMWARE_NAME:Marlin 2.1.2");
    s.reply("ok");
    s.pass(0.2);
    CHECK(s.ready);
    CHECK(s.faults.empty());
}

TEST_CASE("protocol: the flavour is checked against M115") {
    SUBCASE("RepRapFirmware answering a host set for Marlin") {
        Script s;
        s.greet("FIRMWARE_NAME: RepRapFirmware for Duet 3 FIRMWARE_VERSION: 3.5.0");
        CHECK_FALSE(s.ready);
        REQUIRE(s.faults.size() == 1);
        CHECK(s.faults[0].find("flavour mismatch") != std::string::npos);
        CHECK(s.faults[0].find("RepRapFirmware for Duet 3") != std::string::npos);
    }
    SUBCASE("Marlin answering a host set for RepRapFirmware") {
        FirmwareOptions o;
        o.reprap = true;
        Script s(o);
        s.greet();
        REQUIRE(s.faults.size() == 1);
        CHECK(s.faults[0].find("flavour mismatch") != std::string::npos);
    }
    SUBCASE("no FIRMWARE_NAME at all") {
        Script s;
        s.p.open(s.t);
        s.reply("start");
        s.pass(0.2);
        s.reply("ok");
        s.reply("ok");
        s.pass(5);  // no report: greeted again until it gives up
        CHECK_FALSE(s.ready);
    }
}

TEST_CASE("protocol: one lost ok is recovered by a probe under a fresh number, never by repeating a line") {
    Script s;
    s.greet();
    REQUIRE(s.ready);
    s.enqueue("G1 X1");
    s.enqueue("G1 X2");
    auto w = s.take_writes();
    REQUIRE(w.size() == 2);  // the window is 2
    CHECK(number_of(w[0]) == 2);
    CHECK(number_of(w[1]) == 3);
    s.enqueue("G1 X3", 7);   // a line a sender waits on: it goes alone
    s.reply("ok");           // for line 2; the ok of line 3 is lost
    w = s.take_writes();
    CHECK(w.empty());        // line 3 still counts as in flight: the tagged line waits
    s.pass(2.5);             // silence: the reply timeout
    w = s.take_writes();
    REQUIRE(w.size() == 1);
    // Not a repeat of line 3 (Marlin would drop it without a word): a probe under number 4.
    CHECK(number_of(w[0]) == 4);
    CHECK(command_of(w[0]) == "M105");
    CHECK(s.blank_lines == 1);  // a newline ahead of it ends any line whose own newline was lost
    s.reply("ok T:21.5 /0.0");
    // Everything before the probe is in; the tagged line goes next, alone, under the next number.
    w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(5, "G1 X3"));
    CHECK(s.acked.empty());
    s.reply("ok");
    REQUIRE(s.acked.size() == 1);
    CHECK(s.acked[0].first == 7);
    CHECK(s.p.idle());
    CHECK(s.faults.empty());
    CHECK(s.p.stats().probes == 1);
}

TEST_CASE("protocol: a refused line with another behind it (flushed without a reply): resync from the named line") {
    FirmwareOptions o;
    o.window = 3;
    Script s(o);
    s.greet();
    for (int i = 1; i <= 5; ++i) s.enqueue("G1 X" + std::to_string(i));
    auto w = s.take_writes();
    REQUIRE(w.size() == 3);  // lines 2, 3, 4
    // Marlin: line 2 runs; line 3 fails its checksum; the receive buffer held line 4: flushed.
    s.reply("ok");
    CHECK(s.take_writes() == std::vector<std::string>{proto::numbered(5, "G1 X4")});  // room for one more
    s.reply("Error:checksum mismatch, Last Line: 2");
    s.reply("Resend: 3");
    s.reply("ok");
    CHECK(s.take_writes().empty());  // nothing is sent until the firmware is quiet
    s.pass(0.2);
    w = s.take_writes();
    // A probe under the named number: the firmware takes it, and its "ok T:" is the fence.
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(3, "M105"));
    s.reply("ok T:20.0 /0.0");
    w = s.take_writes();
    REQUIRE(w.size() == 3);
    CHECK(w[0] == proto::numbered(4, "G1 X2"));
    CHECK(w[1] == proto::numbered(5, "G1 X3"));
    CHECK(w[2] == proto::numbered(6, "G1 X4"));
    s.reply("ok");
    s.reply("ok");
    s.reply("ok");
    w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(7, "G1 X5"));
    s.reply("ok");
    CHECK(s.p.idle());
    CHECK(s.p.stats().acked == 5);
}

TEST_CASE("protocol: stale Resends of lines sent before the resync do not rewind again") {
    FirmwareOptions o;
    o.window = 3;
    Script s(o);
    s.greet();
    for (int i = 1; i <= 3; ++i) s.enqueue("G1 X" + std::to_string(i));
    s.take_writes();
    // Line 2 refused; lines 3 and 4 arrived after the flush: each draws its own triple.
    for (int i = 0; i < 3; ++i) {
        s.reply("Error:checksum mismatch, Last Line: 1");
        s.reply("Resend: 2");
        s.reply("ok");
        s.pass(0.05);
    }
    s.pass(0.2);
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(2, "M105"));
    s.reply("ok T:20.0 /0.0");
    w = s.take_writes();
    REQUIRE(w.size() == 3);
    CHECK(w[0] == proto::numbered(3, "G1 X1"));
    CHECK(w[2] == proto::numbered(5, "G1 X3"));
}

TEST_CASE("protocol: silence while the firmware's planner is full marks nothing done; a wait is answered only after its ok") {
    Script s;
    s.greet();
    s.enqueue("G1 X1");
    s.enqueue("G1 X2");
    s.enqueue("M400", 9);
    s.take_writes();
    s.pass(2.5);  // a busy planner, no keepalives: the reply timeout passes
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(command_of(w[0]) == "M105");
    CHECK(s.p.stats().acked == 0);
    CHECK_FALSE(s.p.idle());
    // The moves finish; their oks and then the probe's come.
    s.reply("ok");
    s.reply("ok");
    CHECK(s.acked.empty());
    s.reply("ok T:20.0 /0.0");
    w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(command_of(w[0]) == "M400");
    CHECK(s.acked.empty());  // M400 is answered by its own ok only
    CHECK_FALSE(s.p.idle());
    s.reply("ok");
    REQUIRE(s.acked.size() == 1);
    CHECK(s.acked[0].first == 9);
    CHECK(s.p.idle());
}

TEST_CASE("protocol: a garbled Resend number does not rewind to lines already acknowledged") {
    Script s;
    s.greet();
    for (int i = 1; i <= 4; ++i) s.enqueue("G1 X" + std::to_string(i));
    s.reply("ok");
    s.reply("ok");  // lines 2 and 3 acknowledged; 4 and 5 in flight
    s.take_writes();
    s.reply("Resend: 1");  // damaged on the way ("Resend: 4" -> "Resend: 1")
    s.pass(0.2);
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    // Not a rewind to line 1: a probe under a fresh number asks where the firmware is.
    CHECK(w[0] == proto::numbered(6, "M105"));
    s.reply("Error:Line Number is not Last Line Number+1, Last Line: 3");
    s.reply("Resend: 4");
    s.reply("ok");
    s.pass(0.2);
    w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(4, "M105"));
    s.reply("ok T:20.0 /0.0");
    w = s.take_writes();
    REQUIRE(w.size() == 2);
    CHECK(w[0] == proto::numbered(5, "G1 X3"));
    CHECK(w[1] == proto::numbered(6, "G1 X4"));
}

TEST_CASE("protocol: ADVANCED_OK ties each ok to its line; after a Resend it continues without a probe") {
    FirmwareOptions o;
    o.window = 3;
    Script s(o);
    s.greet();
    for (int i = 1; i <= 4; ++i) s.enqueue("G1 X" + std::to_string(i), std::uint64_t(100 + i));
    // With ADVANCED_OK unknown, tagged lines go alone.
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    s.reply("ok N2 P15 B3");
    CHECK(s.p.advanced_ok());
    w = s.take_writes();
    REQUIRE(w.size() == 3);  // lines 3, 4, 5
    s.reply("Error:checksum mismatch, Last Line: 3");  // line 4 refused, 5 flushed
    s.reply("Resend: 4");
    s.reply("ok P15 B3");
    s.reply("ok N3 P15 B3");  // line 3 ran: the ok names it
    s.pass(0.2);
    w = s.take_writes();
    REQUIRE(w.size() == 2);
    CHECK(w[0] == proto::numbered(4, "G1 X3"));
    CHECK(w[1] == proto::numbered(5, "G1 X4"));
    s.reply("ok N4 P15 B3");
    s.reply("ok N5 P15 B3");
    REQUIRE(s.acked.size() == 4);
    for (std::size_t i = 0; i < 4; ++i) CHECK(s.acked[i].first == 101 + i);
    CHECK(s.p.stats().probes == 0);
}

TEST_CASE("protocol: a firmware that says nothing at all is declared gone after max_timeouts probes, each a fresh number") {
    Script s;
    s.greet();
    s.enqueue("G1 X1");
    s.take_writes();
    s.pass(2.0 * (s.opt.max_timeouts + 2));
    const auto w = s.take_writes();
    REQUIRE(w.size() == std::size_t(s.opt.max_timeouts));
    for (std::size_t i = 0; i < w.size(); ++i) CHECK(number_of(w[i]) == std::int64_t(3 + i));
    REQUIRE(s.faults.size() == 1);
    CHECK(s.faults[0].find("has not answered") != std::string::npos);
}

TEST_CASE("protocol: M112 goes out ahead of everything, and the count of lines not executed is told once") {
    Script s;
    s.greet();
    for (int i = 1; i <= 10; ++i) s.enqueue("G1 X" + std::to_string(i));
    s.take_writes();
    s.p.emergency_stop("M112", s.t);
    s.collect();
    REQUIRE(s.writes.size() == 1);
    CHECK(s.writes[0] == "M112");
    REQUIRE(s.faults.size() == 1);
    CHECK(s.lost[0] == 10);
    s.reply("echo:M112 Shutdown");
    s.reply("Error:Printer halted. kill() called!");
    CHECK(s.faults.size() == 1);  // the firmware's own word adds no second count
    CHECK(s.p.queued() == 0);
}

namespace {
// Twenty printing moves of about 42 bytes each as numbered lines: two do not fit a 64-byte
// receive buffer together.
std::vector<std::string> long_moves(Script& s, std::int64_t first_n) {
    std::vector<std::string> lines;
    for (int i = 0; i < 20; ++i) {
        const std::string c = "G1 X" + std::to_string(10 + i) + ".125 Y20.250 Z0.300 E0.0" + std::to_string(1000 + i);
        lines.push_back(proto::numbered(first_n + i, c) + "\n");
        s.enqueue(c);
    }
    return lines;
}
std::string joined(const std::vector<std::string>& v, std::size_t from = 0) {
    std::string out;
    for (std::size_t i = from; i < v.size(); ++i) out += v[i];
    return out;
}
// A ready link with a 64-byte receive buffer and a window of 4, given the twenty long moves:
// line 2 goes whole, line 3 in two parts.
struct HalfSent {
    static FirmwareOptions options() {
        FirmwareOptions o;
        o.window = 4;
        o.rx_bytes = 64;
        return o;
    }
    Script s{options()};
    std::size_t first = 0;            // the first write after the greeting
    std::vector<std::string> expect;  // the lines as the firmware must receive them
    HalfSent() {
        s.greet();
        first = s.raw.size();
        expect = long_moves(s, 2);
    }
};
}  // namespace

TEST_CASE("protocol: a line that does not fit the receive buffer whole goes in two parts, cut before a digit, never over the budget") {
    HalfSent h;
    auto& s = h.s;
    const std::size_t first = h.first;
    const auto& expect = h.expect;
    const FirmwareOptions o = HalfSent::options();
    // The firmware answers each whole line it has received, in order. What it holds unanswered
    // (received, not yet answered) must never exceed the budget.
    std::size_t answered = 0, answered_bytes = 0;
    while (answered < expect.size()) {
        const std::string sent = joined(s.raw, first);
        CHECK(sent.size() - answered_bytes <= o.rx_bytes);
        const auto whole = std::size_t(std::count(sent.begin(), sent.end(), '\n'));
        REQUIRE(whole > answered);  // the link never waits on a line it has only half sent
        answered_bytes += expect[answered++].size();
        s.reply("ok");
    }
    // Every byte once, in order; no line lost, cut short or sent twice.
    CHECK(joined(s.raw, first) == joined(expect));
    CHECK(s.p.idle());
    CHECK(s.faults.empty());
    // Lines did go in two parts, and each first part ends where a digit follows: should the
    // firmware empty its buffer between the parts, the rest is no command to it.
    std::size_t heads = 0;
    for (std::size_t i = first; i + 1 < s.raw.size(); ++i) {
        if (s.raw[i].back() == '\n') continue;
        ++heads;
        CHECK(std::isdigit(static_cast<unsigned char>(s.raw[i + 1].front())));
        CHECK(proto::command_code(s.raw[i + 1]).letter == 0);
    }
    CHECK(heads >= 10);
}

TEST_CASE("protocol: with two_parts off, a line that does not fit the receive buffer whole waits whole for room") {
    FirmwareOptions o = HalfSent::options();
    o.two_parts = false;
    Script s(o);
    s.greet();
    const std::size_t first = s.raw.size();
    const auto expect = long_moves(s, 2);
    std::size_t answered = 0, answered_bytes = 0;
    while (answered < expect.size()) {
        const std::string sent = joined(s.raw, first);
        CHECK(sent.size() - answered_bytes <= o.rx_bytes);
        REQUIRE(sent.size() > answered_bytes);  // something is in flight: the link never stalls
        answered_bytes += expect[answered++].size();
        s.reply("ok");
    }
    CHECK(joined(s.raw, first) == joined(expect));
    // Every write is a whole line: one line in flight at a time, as two never fit 64 bytes.
    for (std::size_t i = first; i < s.raw.size(); ++i) CHECK(s.raw[i].back() == '\n');
    CHECK(s.raw.size() - first == expect.size());
    CHECK(s.p.idle());
}

TEST_CASE("protocol: a refusal while a line is half sent: its rest is never sent; the first part ends as a line Marlin refuses") {
    HalfSent h;
    auto& s = h.s;
    const std::size_t first = h.first;
    const auto& expect = h.expect;
    REQUIRE(s.raw.size() == first + 2);  // line 2 whole, then the first part of line 3
    const std::string head = s.raw.back();
    REQUIRE(head.back() != '\n');
    // Line 2 failed its checksum; Marlin emptied its buffer, the first part of line 3 with it, or not.
    s.reply("Error:checksum mismatch, Last Line: 1");
    s.reply("Resend: 2");
    s.reply("ok");
    // The first part ends at once, so that its refusal, if Marlin still holds it, comes within
    // the wait for quiet; its rest is never sent.
    REQUIRE(s.raw.size() == first + 3);
    CHECK(s.raw[first + 2] == "\n");
    // Marlin refuses it (a number without a checksum): never run.
    proto::LineChecker marlin;
    marlin.set_last_line(1);
    CHECK(marlin.check(head).verdict == proto::LineChecker::Verdict::Refuse);
    s.reply("Error:No Checksum with line number, Last Line: 1");
    s.reply("Resend: 2");
    s.reply("ok");
    CHECK(s.raw.size() == first + 3);  // nothing goes into a resync
    s.pass(0.2);
    // The probe, then every move again, whole and in order.
    REQUIRE(!s.writes.empty());
    CHECK(s.writes.back() == proto::numbered(2, "M105"));
    s.reply("ok T:20.0 /0.0");
    const std::size_t resumed = s.raw.size() - 2;  // line 3 whole, then the first part of line 4
    REQUIRE(s.raw[resumed].substr(0, 3) == "N3 ");
    std::size_t answered = 0;
    while (answered < expect.size() && answered < 100) {
        ++answered;
        s.reply("ok");
    }
    std::string again;
    for (std::size_t i = 0; i < expect.size(); ++i) {
        const auto c = proto::parse_received(std::string_view(expect[i]).substr(0, expect[i].size() - 1)).command;
        again += proto::numbered(std::int64_t(3 + i), c) + "\n";
    }
    CHECK(joined(s.raw, resumed) == again);
    CHECK(s.p.idle());
    CHECK(s.faults.empty());
}

TEST_CASE("protocol: M999 after a stop with a line half sent: the line is ended, M999 waits until its refusal is over") {
    HalfSent h;
    auto& s = h.s;
    const std::size_t first = h.first;
    REQUIRE(s.raw.back().back() != '\n');
    s.reply("Error:Printer stopped due to errors. Fix the error and use M999 to restart.");
    REQUIRE(s.faults.size() == 1);
    CHECK(s.raw.size() == first + 2);  // nothing ends the line while stopped: its refusal would reach the sender
    s.p.restart(s.t);
    s.collect();
    REQUIRE(s.raw.size() == first + 3);
    CHECK(s.raw.back() == "\n");
    // Marlin refuses the first part and empties its buffer: M999 must not be in it yet.
    s.reply("Error:No Checksum with line number, Last Line: 2");
    s.reply("Resend: 3");
    s.reply("ok");
    CHECK(s.raw.size() == first + 3);
    s.pass(0.15);  // quiet (settle 0.1 s), not yet the second wait
    REQUIRE(s.raw.size() == first + 4);
    CHECK(s.raw.back() == "M999\n");
    s.reply("Resend: 3");  // a revived Marlin's stale answer
    s.reply("ok");
    s.pass(0.2);
    const auto w = s.take_writes();
    REQUIRE(w.size() >= 2);
    CHECK(w[w.size() - 2] == proto::numbered(0, "M110 N1"));
    CHECK(w.back() == "M115");
}

TEST_CASE("protocol: M108 or M112 while a line is half sent: the line is finished first, never ended early") {
    // Ended early, the first part would be refused, and a refusal empties Marlin's buffer: the
    // command behind it with it, on a Marlin without EMERGENCY_PARSER.
    for (const std::string command : {"M108", "M112"}) {
        HalfSent h;
        auto& s = h.s;
        const std::size_t first = h.first;
        const auto& expect = h.expect;
        REQUIRE(s.raw.back().back() != '\n');
        if (command == "M108") s.p.send_unnumbered(command, s.t);
        else s.p.emergency_stop(command, s.t);
        s.collect();
        CHECK(joined(s.raw, first) == expect[0] + expect[1] + command + "\n");
        CHECK(s.blank_lines == 0);
    }
}

TEST_CASE("protocol: M999 greets again and discards the stale oks still coming") {
    Script s;
    s.greet();
    s.enqueue("G1 X1");
    s.reply("Error:Printer stopped due to errors. Fix the error and use M999 to restart.");
    REQUIRE(s.faults.size() == 1);
    s.take_writes();
    s.ready = false;
    s.p.restart(s.t);
    s.collect();
    REQUIRE(s.take_writes() == std::vector<std::string>{"M999"});  // revives a stopped Marlin
    s.reply("Resend: 3");  // M999's own answer
    s.reply("ok");
    s.reply("ok");  // oks of lines from before the stop
    s.reply("ok");
    s.pass(0.05);
    CHECK(s.writes.empty());
    s.pass(0.2);
    REQUIRE(s.take_writes().size() == 2);
    s.reply("ok");  // a stale one again: not M115's answer
    CHECK_FALSE(s.ready);
    s.reply("FIRMWARE_NAME:Marlin 2.1.2");
    s.reply("ok");
    s.pass(0.2);
    CHECK(s.ready);
}

TEST_CASE("protocol: a lost newline on the last line in flight is ended by one empty line after a short silence, not by a timeout") {
    FirmwareOptions o;
    o.nudge = 0.1;
    Script s(o, true);
    s.greet();
    REQUIRE(s.ready);
    s.enqueue("G1 X1");
    REQUIRE(s.take_writes() == std::vector<std::string>{proto::numbered(2, "G1 X1")});
    // The firmware got the line without its newline (Marlin rule 5: it waits for more bytes).
    s.pass(0.09);
    CHECK(s.blank_lines == 0);
    s.pass(0.02);
    CHECK(s.blank_lines == 1);  // one "\n": Marlin ends the half line with it, or skips it as empty
    CHECK(s.take_writes().empty());
    CHECK(s.p.stats().nudges == 1);
    s.reply("ok");  // the line, completed, runs
    CHECK(s.p.idle());
    s.pass(5);      // nothing in flight: no more nudges, no timeout
    CHECK(s.blank_lines == 1);
    CHECK(s.p.stats().timeouts == 0);
    CHECK(s.p.stats().probes == 0);
    CHECK(s.p.stats().acked == 1);
}

TEST_CASE("protocol: the nudge comes once per line sent, counts from the last reply, and a silence after it still ends in a probe") {
    FirmwareOptions o;
    o.nudge = 0.1;
    Script s(o, true);
    s.greet();
    s.enqueue("G1 X1");
    s.enqueue("G1 X2");
    REQUIRE(s.take_writes().size() == 2);
    s.pass(0.08);
    s.reply("ok");   // line 2: the silence starts again
    s.pass(0.08);    // 0.16 s after the lines were sent, 0.08 s after the reply
    CHECK(s.blank_lines == 0);
    s.pass(0.03);
    CHECK(s.blank_lines == 1);
    s.reply("echo:busy: processing");  // a reply after the nudge does not bring another
    s.pass(0.5);
    CHECK(s.blank_lines == 1);
    CHECK(s.p.stats().nudges == 1);
    // Still nothing for line 3: the reply timeout's probe, under a fresh number, with its own newline.
    s.pass(1.55);  // the busy: reply put the timeout at 2.19 s; now 2.24 s
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(4, "M105"));
    CHECK(s.blank_lines == 2);
    CHECK(s.p.stats().timeouts == 1);
    // The probe is a line sent: if its own newline were lost, one nudge more.
    s.pass(0.1);
    CHECK(s.blank_lines == 3);
    s.reply("ok T:20.0 /0.0");
    CHECK(s.p.idle());
    CHECK(s.p.stats().acked == 2);
}

TEST_CASE("protocol: the nudge's byte counts in the receive buffer's budget until its line is answered; RepRapFirmware gets none") {
    const std::string first = proto::numbered(2, "G1 X1") + "\n";
    const std::string second = "G1 X2";
    FirmwareOptions o;
    o.nudge = 0.1;
    // Room for both lines as written, but not for one byte more.
    const std::string line3 = proto::numbered(3, second) + "\n";
    o.rx_bytes = first.size() + line3.size();
    Script s(o, true);
    s.greet();
    const std::size_t from = s.raw.size();
    s.enqueue("G1 X1");
    s.pass(0.15);
    CHECK(s.blank_lines == 1);
    s.take_writes();
    s.enqueue(second);
    // The nudge's byte leaves no room for line 3 whole: only its first part goes, and what is
    // unanswered stays within the budget.
    CHECK(s.take_writes().empty());
    CHECK(!s.stream.empty());
    CHECK(line3.rfind(s.stream, 0) == 0);
    CHECK(joined(s.raw, from).size() <= o.rx_bytes);
    s.reply("ok");                   // line 2 answered: its bytes and the nudge's leave the budget
    CHECK(s.take_writes() == std::vector<std::string>{proto::numbered(3, second)});
    CHECK(joined(s.raw, from) == first + "\n" + line3);
    // Without the byte in flight, the same two lines go together.
    Script t(o, true);
    t.greet();
    t.enqueue("G1 X1");
    t.enqueue(second);
    CHECK(t.take_writes().size() == 2);
    // A full budget: no nudge (its byte would be lost in the firmware's receive buffer anyway).
    o.rx_bytes = first.size();
    Script v(o, true);
    v.greet();
    v.enqueue("G1 X1");
    v.pass(0.15);
    CHECK(v.blank_lines == 0);
    CHECK(v.p.stats().nudges == 0);

    FirmwareOptions r;
    r.reprap = true;
    r.nudge = 0.1;
    Script u(r, true);
    u.greet("FIRMWARE_NAME: RepRapFirmware for Duet 3 FIRMWARE_VERSION: 3.5.0");
    REQUIRE(u.ready);
    u.enqueue("G1 X1");
    u.pass(1);
    CHECK(u.blank_lines == 0);
    CHECK(u.p.stats().nudges == 0);
}

TEST_CASE("protocol: a resync waits for quiet even when settle is longer than the reply timeout; the print goes on") {
    // settle 0.25 s, reply_timeout 0.1 s: the quiet a resync waits for used to end in a reply
    // timeout, whose probe under a fresh number the firmware refused (it wants the named line),
    // which began another resync, until "20 resyncs without progress" stopped the print.
    Script s({}, false, std::pair{0.1, 0.25});
    s.greet();
    REQUIRE(s.ready);
    ScriptedMarlin fw;
    fw.damage = "G1 X3";
    std::vector<std::string> print;
    for (int i = 1; i <= 12; ++i) print.push_back("G1 X" + std::to_string(i));
    for (const auto& c : print) s.enqueue(c);
    for (int step = 0; step < 400 && !(s.p.idle() && s.writes.empty()) && s.faults.empty(); ++step) {
        fw.answer(s);
        s.pass(0.01);
    }
    CHECK(s.faults.empty());
    CHECK(s.p.idle());
    CHECK(fw.refusals == 1);
    CHECK(s.p.stats().timeouts == 0);
    CHECK(s.p.stats().resyncs == 1);
    CHECK(s.p.stats().probes == 1);
    // Every line ran once, in order; the probe's M105 between them.
    std::vector<std::string> ran;
    for (const auto& c : fw.taken)
        if (c != "M105") ran.push_back(c);
    CHECK(ran == print);
}

TEST_CASE("protocol: a host that wakes late past both the quiet and the reply timeout sends one probe, under the named number") {
    FirmwareOptions o;
    o.window = 3;
    Script s(o, false, std::pair{0.1, 0.05});
    s.greet();
    for (int i = 1; i <= 3; ++i) s.enqueue("G1 X" + std::to_string(i));
    REQUIRE(s.take_writes().size() == 3);
    s.reply("ok");
    s.reply("Error:checksum mismatch, Last Line: 2");
    s.reply("Resend: 3");
    s.reply("ok");
    // One wake-up a second later: the quiet ended long ago, and so would a reply timeout have.
    s.t += std::chrono::seconds(1);
    s.p.on_time(s.t);
    s.collect();
    auto w = s.take_writes();
    REQUIRE(w.size() == 1);
    CHECK(w[0] == proto::numbered(3, "M105"));
    CHECK(s.p.stats().timeouts == 0);
    s.reply("ok T:20.0 /0.0");
    w = s.take_writes();
    REQUIRE(w.size() == 2);
    CHECK(w[0] == proto::numbered(4, "G1 X2"));
    CHECK(w[1] == proto::numbered(5, "G1 X3"));
    CHECK(s.faults.empty());
}

TEST_CASE("line checker: Marlin's order of checks and its silent drop of repeats") {
    proto::LineChecker c;
    using V = proto::LineChecker::Verdict;
    CHECK(c.check(proto::numbered(0, "M110 N0")).verdict == V::Take);
    CHECK(c.check(proto::numbered(1, "G28")).verdict == V::Take);
    CHECK(c.check(proto::numbered(1, "G28")).verdict == V::Duplicate);  // last_N
    CHECK(c.check(proto::numbered(0, "G28")).verdict == V::Duplicate);  // last_N - 1
    CHECK(c.check("N1 G28*0").verdict == V::Duplicate);                 // the number is read before the checksum
    auto r = c.check(proto::numbered(5, "G1 X1"));
    CHECK(r.verdict == V::Refuse);
    CHECK(r.why == proto::kErrLineNumber);
    r = c.check("N2 G1 X1*1");
    CHECK(r.verdict == V::Refuse);
    CHECK(r.why == proto::kErrChecksumMismatch);
    r = c.check("N2 G1 X1");
    CHECK(r.why == proto::kErrNoChecksum);
    CHECK(c.error_line(r.why) == "Error:No Checksum with line number, Last Line: 1");
    CHECK(c.resend_line() == "Resend: 2");
    CHECK(c.check(proto::numbered(101, "M110 N100")).verdict == V::Take);
    CHECK(c.last_line() == 100);
    CHECK(c.check("G1 X5*12").verdict == V::Take);  // Marlin 2.1 takes an unnumbered line as it is
    // Marlin reads the checksum with strtol: digits up to the first non-digit (a joined line).
    const std::string first = proto::numbered(101, "G1 X1");
    CHECK(c.check(first + "N102 G1 X").verdict == V::Take);
    CHECK(c.last_line() == 101);
    CHECK(proto::LineChecker(true).check("G1 X5*12").why == proto::kErrNoLineNumber);
}

// Marlin as its source has it (queue.cpp, gcode/host/M110.cpp): every line waiting in its receive
// buffer is taken into the command queue before the command in front runs, and M110 sets the
// line number a second time when it runs. `answer` takes everything written since its last call
// as one read (a native-USB packet), then runs the queue.
struct MarlinRunsM110 {
    proto::LineChecker checker;
    std::vector<std::string> queue, ran;
    void answer(Script& s) {
        for (const auto& line : s.take_writes()) {
            const auto r = checker.check(line);
            if (r.verdict == proto::LineChecker::Verdict::Duplicate) continue;
            if (r.verdict == proto::LineChecker::Verdict::Refuse) {
                s.reply(checker.error_line(r.why));
                s.reply(checker.resend_line());
                s.reply("ok");
                break;  // the receive buffer is emptied
            }
            queue.emplace_back(proto::strip_comment(r.command));
        }
        for (const auto& c : std::exchange(queue, {})) {
            ran.push_back(c);
            if (proto::command_code(c).is('M', 110))
                if (const auto n = proto::m110_line(c)) checker.set_last_line(*n);
            if (c == "M115") {
                s.reply("FIRMWARE_NAME:Marlin bugfix-2.1.x PROTOCOL_VERSION:1.0");
                s.reply("Cap:EMERGENCY_PARSER:1");
            }
            s.reply(c == "M105" ? "ok T:20.0 /0.0" : "ok");
        }
    }
};

TEST_CASE("protocol: the greeting survives a Marlin that takes both its lines before M110 runs") {
    // On b1037f8 the greeting was "N0 M110 N0" and "N1 M115": taken together, M110 then set the
    // count back to 0 and every later line was refused (Last Line: 0, Resend: 1) until the
    // service gave up. Nothing numbered may follow an M110 before a command behind it is answered.
    Script s;
    MarlinRunsM110 marlin;
    s.p.open(s.t);
    s.reply("start");
    s.pass(0.2);
    marlin.answer(s);
    s.pass(0.2);
    REQUIRE(s.ready);
    for (int i = 1; i <= 20; ++i) {
        s.enqueue("G1 X" + std::to_string(i));
        marlin.answer(s);
    }
    s.pass(0.2);
    marlin.answer(s);
    CHECK(s.faults.empty());
    CHECK(s.p.idle());
    CHECK(s.p.stats().resend_requests == 0);
    std::vector<std::string> moves;
    for (const auto& c : marlin.ran)
        if (c.rfind("G1", 0) == 0) moves.push_back(c);
    REQUIRE(moves.size() == 20);
    for (int i = 1; i <= 20; ++i) CHECK(moves[std::size_t(i - 1)] == "G1 X" + std::to_string(i));
}

TEST_CASE("protocol: a Resend that names the line after a re-numbering re-numbers the firmware instead of probing") {
    // A firmware that ran xlate5's M110 again after it had taken later lines asks for the line
    // after it (Last Line: 1, Resend: 2) though that line was taken long ago. Probing under a
    // fresh number is refused for ever; the count is set back to xlate5's with an unnumbered
    // M110, and an M105 behind it shows it ran before anything numbered goes.
    FirmwareOptions o;
    o.history = 4;
    Script s(o);
    s.greet();
    ScriptedMarlin marlin;
    for (int i = 1; i <= 10; ++i) {
        s.enqueue("G1 X" + std::to_string(i));
        marlin.answer(s);
    }
    REQUIRE(s.p.idle());
    marlin.checker.set_last_line(1);  // the firmware ran M110 N1 again
    s.enqueue("G1 X11");
    marlin.answer(s);  // refused: Last Line: 1, Resend: 2
    s.pass(0.2);       // quiet, then the re-numbering
    const auto w = s.take_writes();
    REQUIRE(w.size() == 2);
    CHECK(w[0] == "M110 N11");
    CHECK(w[1] == "M105");
    CHECK(s.p.stats().renumbers == 1);
    marlin.checker.set_last_line(11);  // it runs the M110 (the scripted checker takes unnumbered lines as they are)
    s.reply("ok");
    s.reply("ok T:20.0 /0.0");
    REQUIRE(s.writes.size() == 1);
    CHECK(s.writes[0] == proto::numbered(12, "G1 X11"));
    marlin.answer(s);
    CHECK(s.p.idle());
    CHECK(s.faults.empty());
    CHECK(marlin.taken.back() == "G1 X11");
    CHECK(std::count(marlin.taken.begin(), marlin.taken.end(), "G1 X10") == 1);
}

TEST_CASE("protocol: after a fault the firmware's numbering never reaches the sender; the count is the sender's lines") {
    Script s;
    s.greet();
    // Sender line 7 became three firmware lines, line 8 two; xlate5's probe is no line of theirs.
    for (int i = 0; i < 3; ++i) s.p.enqueue("G1 X" + std::to_string(i), 0, s.t, 7);
    for (int i = 0; i < 2; ++i) s.p.enqueue("G1 Y" + std::to_string(i), 0, s.t, 8);
    s.collect();
    s.reply("Error:Line Number is not Last Line Number+1, Last Line: 0");
    s.reply("Resend: 1");
    s.reply("ok");
    s.pass(0.2);  // a probe goes
    s.p.port_closed("the port closed");
    s.collect();
    REQUIRE(s.faults.size() == 1);
    CHECK(s.lost.back() == 2);
    s.messages.clear();
    s.reply("Error:Line Number is not Last Line Number+1, Last Line: 0");
    s.reply("Resend: 1");
    s.reply("ok");
    s.reply("echo:busy: processing");
    CHECK(s.messages == std::vector<std::string>{"echo:busy: processing"});
}

TEST_CASE("protocol: Marlin's echo of a piece of a line xlate5 cut is logged, not shown as the sender's command refused") {
    Script s;
    s.greet();
    s.reply("echo:Unknown command: \"5.250 Y12.5*77\"");  // the tail of a line sent in two parts
    s.reply("echo:Unknown command: \"\"");
    CHECK(s.messages.empty());
    s.reply("echo:Unknown command: \"M9999\"");  // the sender's own
    CHECK(s.messages == std::vector<std::string>{"echo:Unknown command: \"M9999\""});
}

TEST_CASE("protocol: a firmware that answers lines twice cannot make xlate5 overfill its buffer") {
    // b1037f8 credited every ok in order: with two per line it sent on as fast as the oks came,
    // 8,785 bytes in flight against a 127-byte receive buffer. Now a plain ok with an M105 first
    // in flight (a sender's temperature poll, as OctoPrint's every few seconds) tells it, and from
    // then on only M105's "ok T:" (which names itself) credits lines.
    Script s;
    s.greet();
    proto::LineChecker checker;
    checker.set_last_line(1);
    std::deque<std::string> buffer;  // taken by the firmware, not yet run
    std::size_t most_bytes = 0, ran = 0;
    for (int i = 1; i <= 60; ++i) {
        if (i % 10 == 5) s.enqueue("M105");
        s.enqueue("G1 X" + std::to_string(i) + " Y" + std::to_string(i) + " Z0.2 E0.05 F1800");
    }
    std::size_t most_after = 0;  // after the first poll
    bool polled = false;
    for (int step = 0; step < 2000 && ran < 60; ++step) {
        for (const auto& line : s.take_writes()) {
            const auto r = checker.check(line);
            REQUIRE(r.verdict == proto::LineChecker::Verdict::Take);
            buffer.emplace_back(line + "\n");
        }
        std::size_t bytes = 0;
        for (const auto& b : buffer) bytes += b.size();
        most_bytes = std::max(most_bytes, bytes);
        if (polled) most_after = std::max(most_after, bytes);
        if (buffer.empty()) {
            s.pass(0.01);
            continue;
        }
        // Runs the oldest line; answers it twice.
        const std::string command(proto::parse_received(std::string_view(buffer.front()).substr(0, buffer.front().size() - 1)).command);
        buffer.pop_front();
        if (command == "M105") {
            s.reply("ok T:20.0 /0.0");
            s.reply("ok");
            polled = true;
        } else {
            ++ran;
            s.reply("ok");
            s.reply("ok");
        }
    }
    CHECK(ran == 60);
    CHECK(s.faults.empty());
    CHECK(most_after <= s.opt.rx_bytes);
    CHECK(s.p.stats().stray_oks > 0);
    MESSAGE("most bytes in the firmware's buffer: " << most_bytes << " before the first poll, " << most_after << " after");
}

// Klipper (klippy/gcode.py): M115's report rides on its ok line, STATUS says whether it is ready,
// every line draws exactly one ok in order, errors are "!! …" before that ok.
namespace {
FirmwareOptions klipper_options() {
    FirmwareOptions o;
    o.klipper = true;
    return o;
}
void klipper_greet(Script& s, bool ready_first = true) {
    s.p.open(s.t);
    s.pass(s.opt.boot_wait + s.opt.settle + 0.05);  // no "start": boot_wait, then quiet
    auto w = s.take_writes();
    REQUIRE(w == std::vector<std::string>{"M115", "STATUS"});
    s.reply("ok FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.13.0");
    if (!ready_first) {
        s.reply("// Printer is not ready");
        s.reply("!! Printer is not ready");
        s.reply("ok");
        CHECK(!s.ready);
        s.pass(s.opt.boot_wait + s.opt.settle + 0.05);
        w = s.take_writes();
        REQUIRE(w == std::vector<std::string>{"M115", "STATUS"});
        s.reply("ok FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.13.0");
    }
    s.reply("// Klipper state: Ready");
    s.reply("ok");
    s.pass(s.opt.settle + 0.05);
}
}  // namespace

TEST_CASE("protocol, Klipper: the greeting reads M115's ok line and waits for STATUS to say ready") {
    Script s(klipper_options());
    klipper_greet(s, false);
    CHECK(s.ready);
    CHECK(s.faults.empty());
    REQUIRE(s.p.m115().size() == 1);
    CHECK(s.p.m115()[0] == "FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.13.0");
}

TEST_CASE("protocol, Klipper: a Marlin answering is a flavour mismatch, and a Klipper for --flavor marlin too") {
    Script s(klipper_options());
    s.p.open(s.t);
    s.pass(s.opt.boot_wait + s.opt.settle + 0.05);
    s.take_writes();
    s.reply("ok FIRMWARE_NAME:Marlin 2.1.2");
    s.reply("// Klipper state: Ready");
    s.reply("ok");
    s.pass(s.opt.settle + 0.05);
    REQUIRE(s.faults.size() == 1);
    CHECK(s.faults[0].find("flavour mismatch") != std::string::npos);

    Script m;  // Marlin's greeting answered by a Klipper: M110 and M115 each get an ok
    m.p.open(m.t);
    m.reply("start");
    m.pass(m.opt.settle + 0.1);
    m.take_writes();
    m.reply("ok");
    m.reply("FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.13.0");
    m.reply("ok");
    m.pass(m.opt.settle + 0.1);
    REQUIRE(m.faults.size() == 1);
    CHECK(m.faults[0].find("flavour mismatch") != std::string::npos);
}

TEST_CASE("protocol, Klipper: plain lines up to the window, each ok credits the oldest, never an empty line") {
    Script s(klipper_options());
    klipper_greet(s);
    for (int i = 0; i < 40; ++i) s.enqueue("G1 X" + std::to_string(i), std::uint64_t(i + 1));
    auto w = s.take_writes();
    REQUIRE(w.size() == std::size_t(klipper::kWindow));
    for (int i = 0; i < klipper::kWindow; ++i) CHECK(w[std::size_t(i)] == "G1 X" + std::to_string(i));  // no N, no checksum
    for (int i = 0; i < 40; ++i) {
        s.pass(3);  // a long silence (a full toolhead queue): nothing is probed or repeated
        s.reply("ok");
    }
    w = s.take_writes();
    CHECK(w.size() == 40 - std::size_t(klipper::kWindow));
    CHECK(s.blank_lines == 0);
    REQUIRE(s.acked.size() == 40);
    for (std::size_t i = 0; i < 40; ++i) CHECK(s.acked[i].first == i + 1);
    CHECK(s.faults.empty());
}

TEST_CASE("protocol, Klipper: M114 goes as GET_POSITION and comes back as a report with every axis") {
    Script s(klipper_options());
    klipper_greet(s);
    s.enqueue("M114", 7);
    REQUIRE(s.take_writes() == std::vector<std::string>{"GET_POSITION"});
    for (const char* l : {"// mcu: stepper_x:0 stepper_y:0 stepper_z:0", "// toolhead: X:10.000000 Y:0.000000 Z:300.000000 E:5.000000 A:-100.000000",
                          "// gcode: X:10.000000 Y:0.000000 Z:300.000000 E:5.000000 A:-100.000000",
                          "// gcode base: X:0.000000 Y:0.000000 Z:0.000000 E:4.000000 A:-268.000000",
                          "// gcode homing: X:0.000000 Y:0.000000 Z:0.000000"})
        s.reply(l);
    CHECK(s.messages.empty());
    s.reply("ok");
    REQUIRE(s.messages.size() == 1);
    CHECK(s.messages[0] == "X:10.000000 Y:0.000000 Z:300.000000 E:1.000000 A:168.000000");
    REQUIRE(s.acked.size() == 1);
    CHECK(s.acked[0].first == 7);
}

TEST_CASE("protocol, Klipper: an !! error stops the print and names the line and the axes its message leaves out") {
    Script s(klipper_options());
    klipper_greet(s);
    s.enqueue("G1 X20 F600", 1);
    s.enqueue("G1 A200", 2);
    s.enqueue("G1 X30", 3);
    s.reply("ok");
    s.reply("!! Move out of range: 20.000 0.000 300.000 [5.000]");
    REQUIRE(s.faults.size() == 1);
    CHECK(s.faults[0].find("'G1 A200'") != std::string::npos);
    CHECK(s.faults[0].find("leaves out A200") != std::string::npos);
    CHECK(s.lost[0] == 2);  // G1 A200 and G1 X30: not known to have run
    REQUIRE(!s.messages.empty());
    CHECK(s.messages[0].rfind("!! Move out of range", 0) == 0);
}
