// SPDX-License-Identifier: GPL-3.0-or-later
// The sender side's protocol on its own, with no link and no pseudo-terminal: scripted sender
// lines in, the replies and the commands handed to the service checked. Then the service's
// policy (ServeSteps: what is refused, acknowledged, held and released) on its own, against
// offline translation. The reference for what
// must be refused is Marlin's own receive code (queue.cpp, bugfix-2.1.x, as the project's
// protocol notes quote it), written out below independently of the line checker.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "daemon/line_checker.hpp"
#include "daemon/line_protocol.hpp"
#include "daemon/position_report.hpp"
#include "daemon/sender_protocol.hpp"
#include "daemon/serve_steps.hpp"
#include "daemon/service.hpp"
#include "helpers.hpp"

using namespace xlate5;

namespace {

using Kind = SenderProtocol::Action::Kind;

// What one sender line made the protocol do: the lines written back, the commands taken.
struct Outcome {
    std::vector<std::string> written;
    std::vector<SenderProtocol::Action> handed;  // everything but Write
    bool took() const {
        for (const auto& a : handed)
            if (a.kind == Kind::Command) return true;
        return false;
    }
};

Outcome feed(SenderProtocol& p, std::string_view line, bool cut = false, std::size_t max_line = 0) {
    p.on_line(line, cut, max_line);
    Outcome o;
    for (auto& a : p.take_actions()) {
        if (a.kind == Kind::Write) o.written.push_back(a.text);
        else o.handed.push_back(std::move(a));
    }
    return o;
}

std::vector<std::string> triple(std::string_view why, long last) {
    return {"Error:" + std::string(why) + ", Last Line: " + std::to_string(last), "Resend: " + std::to_string(last + 1), "ok"};
}

// Marlin's gcode_line_error path (queue.cpp) for one line, given last_N, written from its
// source: a line is checked only when it starts with N (leading blanks skipped); a line that
// contains "M110" takes its second N as the number and skips the sequence check; the number is
// checked before the checksum; last_N or last_N-1 is dropped without a word; the checksum is
// strtol of what follows the last '*' against the XOR of everything before it.
struct MarlinVerdict {
    enum { Take, Drop, Refuse } what;
    std::string why;
    long n = 0;
};
MarlinVerdict marlin_receives(std::string line, long last_n) {
    // Marlin's reader stops a line at ';' (a comment) before these checks.
    if (const auto c = line.find(';'); c != std::string::npos) line.erase(c);
    std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string::npos || line[start] != 'N') return {MarlinVerdict::Take, {}, last_n};
    const char* command = line.c_str() + start;
    const char* npos = command;
    const bool m110 = std::string(command).find("M110") != std::string::npos;
    if (m110)
        if (const char* n2 = std::strchr(command + 4, 'N')) npos = n2;
    const long n = std::strtol(npos + 1, nullptr, 10);
    if (n != last_n + 1 && !m110) {
        if (n == last_n || n == last_n - 1) return {MarlinVerdict::Drop, {}, last_n};
        return {MarlinVerdict::Refuse, std::string(proto::kErrLineNumber), last_n};
    }
    const char* star = std::strrchr(command, '*');
    if (!star) return {MarlinVerdict::Refuse, std::string(proto::kErrNoChecksum), last_n};
    unsigned char cs = 0;
    for (const char* c = command; c < star; ++c) cs ^= static_cast<unsigned char>(*c);
    if (std::strtol(star + 1, nullptr, 10) != cs) return {MarlinVerdict::Refuse, std::string(proto::kErrChecksumMismatch), last_n};
    return {MarlinVerdict::Take, {}, n};
}

}  // namespace

TEST_CASE("sender protocol: numbered lines go to the service in order; the ok is the service's") {
    SenderProtocol p;
    auto o = feed(p, proto::numbered(1, "G28"));
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].kind == Kind::Command);
    CHECK(o.handed[0].text == "G28");
    CHECK(o.handed[0].line_no == 1);
    CHECK(o.handed[0].numbered);
    CHECK(o.handed[0].code.is('G', 28));
    CHECK(o.written.empty());  // no ok until the service has queued it
    p.ok(" T:20.0 /0.0");
    const auto a = p.take_actions();
    REQUIRE(a.size() == 1);
    CHECK(a[0].text == "ok T:20.0 /0.0");
    // Unnumbered lines (a terminal) are counted among the lines received.
    o = feed(p, "G1 X5 ; move");
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].text == "G1 X5 ; move");  // the comment kept: the translator reads it as a file's
    CHECK(o.handed[0].line_no == 2);
    CHECK_FALSE(o.handed[0].numbered);
    CHECK(p.last_line() == 1);
}

TEST_CASE("sender protocol: Marlin's refusals, in Marlin's words, and nothing run") {
    SenderProtocol p;
    REQUIRE(feed(p, proto::numbered(1, "G28")).took());
    // A bad checksum.
    std::string bad = proto::numbered(2, "G1 X1");
    bad.back() = bad.back() == '9' ? '8' : '9';
    auto o = feed(p, bad);
    CHECK(o.written == triple(proto::kErrChecksumMismatch, 1));
    CHECK(o.handed.empty());
    // Lines sent after the refusal, before the resend is satisfied, each get the same triple.
    o = feed(p, proto::numbered(3, "G1 X2"));
    CHECK(o.written == triple(proto::kErrLineNumber, 1));
    CHECK(o.handed.empty());
    // A number without a checksum; a checksum without a number (older Marlin's rule, kept).
    CHECK(feed(p, "N2 G1 X1").written == triple(proto::kErrNoChecksum, 1));
    CHECK(feed(p, "G1 X1*" + std::to_string(proto::checksum("G1 X1"))).written == triple(proto::kErrNoLineNumber, 1));
    // An N whose number was damaged is a numbered line, never a command "N".
    o = feed(p, "N;2 G1 X1*99");
    CHECK(o.written == triple(proto::kErrLineNumber, 1));
    // The resend is taken.
    o = feed(p, proto::numbered(2, "G1 X1"));
    REQUIRE(o.took());
    CHECK(p.last_line() == 2);
}

TEST_CASE("sender protocol: a repeat is not run again but answered, unlike Marlin's silence") {
    SenderProtocol p;
    REQUIRE(feed(p, proto::numbered(1, "G1 X1")).took());
    REQUIRE(feed(p, proto::numbered(2, "G1 X2")).took());
    for (int n : {2, 1}) {
        const auto o = feed(p, proto::numbered(n, "G1 X9"));
        CHECK_FALSE(o.took());
        CHECK(o.written == std::vector<std::string>{"ok"});
    }
    CHECK(p.last_line() == 2);
}

TEST_CASE("sender protocol: M110 numbers the lines anew, and only within Marlin's long") {
    SenderProtocol p;
    REQUIRE(feed(p, proto::numbered(1, "G28")).took());
    // "N101 M110 N100" sets 100 (the M110's own N is the number checked).
    auto o = feed(p, proto::numbered(101, "M110 N100"));
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].kind == Kind::Reset);
    CHECK(o.written == std::vector<std::string>{"ok"});
    CHECK(p.last_line() == 100);
    CHECK(feed(p, proto::numbered(101, "G1 X1")).took());
    // Printrun's "N-1 M110*15" on connecting: M110 without its own N sets the line's number.
    o = feed(p, "N-1 M110*15");
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].kind == Kind::Reset);
    CHECK(p.last_line() == -1);
    CHECK(feed(p, proto::numbered(0, "G1 X1")).took());
    // Past a 32-bit board's long: refused, and the numbering left alone.
    o = feed(p, proto::numbered(1, "M110 N2147483648"));
    CHECK(o.written == triple(proto::kErrLineNumber, 0));
    CHECK(o.handed.empty());
    CHECK(p.last_line() == 0);
    // Unnumbered, from a terminal: sets the next number as well.
    o = feed(p, "M110 N500");
    CHECK(o.handed.at(0).kind == Kind::Reset);
    CHECK(p.last_line() == 500);
}

TEST_CASE("sender protocol: the protocol's own commands never reach the queue") {
    SenderProtocol p;
    for (const std::string c : {"M112", "M108", "M410"}) {
        const auto o = feed(p, c + " ; now");
        REQUIRE(o.handed.size() == 1);
        CHECK(o.handed[0].kind == Kind::Emergency);
        CHECK(o.handed[0].text == c);  // comment stripped: it goes to the firmware's emergency parser
        CHECK(o.written == std::vector<std::string>{"ok"});
    }
    auto o = feed(p, "M115");
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].kind == Kind::Identify);
    CHECK(o.written == std::vector<std::string>{"ok"});
    // A numbered comment still counts (ok), an unnumbered blank line is ignored.
    o = feed(p, proto::numbered(1, "(layer 2)"));
    CHECK(o.handed.empty());
    CHECK(o.written == std::vector<std::string>{"ok"});
    CHECK(p.last_line() == 1);
    o = feed(p, "   ");
    CHECK(o.handed.empty());
    CHECK(o.written.empty());
}

TEST_CASE("sender protocol: a cut line is refused in its turn, never run cut") {
    SenderProtocol p;
    REQUIRE(feed(p, proto::numbered(1, "G28")).took());
    const std::string head = "N2 M117 " + std::string(200, 'x');
    auto o = feed(p, head.substr(0, 96), /*cut=*/true, 96);
    REQUIRE(o.handed.size() == 1);
    CHECK(o.handed[0].kind == Kind::Refused);
    CHECK(o.handed[0].numbered);  // the next number: the print ends there
    CHECK(o.handed[0].line_no == 2);
    CHECK(o.handed[0].text == "M117 " + std::string(35, 'x') + "...");
    CHECK(o.handed[0].cause == "longer than 96 bytes (the line-length bound)");
    CHECK(o.written.empty());  // the service answers it in its turn
    CHECK(p.last_line() == 2);
    // An unnumbered (or out-of-sequence) one is a terminal's: counted by lines received.
    o = feed(p, "N9 M117 yyyy", true, 96);
    CHECK_FALSE(o.handed.at(0).numbered);
    CHECK(o.handed[0].line_no == 3);
    CHECK(p.last_line() == 2);
}

TEST_CASE("sender protocol: the service's answers in the sender's words") {
    SenderProtocol p;
    p.refused("line 5 'G1 X10 Q5': no Q", false);
    auto a = p.take_actions();
    REQUIRE(a.size() == 3);
    CHECK(a[0].text == "echo:xlate5: refused line 5 'G1 X10 Q5': no Q");
    CHECK(a[1].text == "//action:notification xlate5: refused line 5 'G1 X10 Q5': no Q");
    CHECK(a[2].text == "ok");
    p.refused("line 9 'G1 X10 Q5': no Q", true);
    a = p.take_actions();
    REQUIRE(a.size() == 4);
    CHECK(a[0].text == "//action:cancel");
    CHECK(a[1].text == "echo:xlate5: print cancelled at line 9 'G1 X10 Q5': no Q");
    CHECK(a[3].text == "ok");
    // After a cancel the printer is fine: never an Error: (OctoPrint answers one with M112).
    p.not_run("G1 X1", "print cancelled at line 9", true);
    a = p.take_actions();
    REQUIRE(a.size() == 2);
    CHECK(a[0].text.rfind("echo:xlate5: not run: 'G1 X1'", 0) == 0);
    p.not_run("G1 X1", "the firmware reset", false);
    a = p.take_actions();
    REQUIRE(a.size() == 2);
    CHECK(a[0].text == "Error:Printer stopped (xlate5): the firmware reset. Fix the cause and send M999 to restart.");
    p.busy();
    CHECK(p.take_actions().at(0).text == "echo:busy: processing");
}

TEST_CASE("sender protocol: at least as strict as Marlin's receive code on damaged streams") {
    // A sender that follows Resend, over a link that flips bits, loses bytes, loses newlines
    // (joined lines) and drops checksums. Every line Marlin refuses is refused with Marlin's
    // words; every line Marlin drops or refuses is not run; what Marlin takes is taken unless
    // the sender side is stricter (a checksum without a number).
    std::mt19937 rng(34);
    std::uniform_int_distribution<int> pick(0, 99);
    SenderProtocol p;
    std::vector<std::string> program;
    for (int i = 0; i < 400; ++i) program.push_back("G1 X" + std::to_string(i % 37) + " Y" + std::to_string(i % 11) + " E" + std::to_string(i));
    std::size_t next = 0, refused = 0, dropped = 0, stricter = 0, taken = 0;
    std::vector<std::string> run;
    long guard = 0;
    while (next < program.size() && ++guard < 20000) {
        std::string line = proto::numbered(long(next) + 1, program[next]);
        const int r = pick(rng);
        if (r < 6) {  // a flipped bit (not into a NUL or a newline: the link frames those)
            char& c = line[std::size_t(pick(rng)) % line.size()];
            const char flipped = char(c ^ (1 << (pick(rng) % 7)));
            if (flipped != 0 && flipped != '\n' && flipped != '\r') c = flipped;
        }
        else if (r < 10) line.erase(std::size_t(pick(rng)) % line.size(), 1);                 // a lost byte
        else if (r < 13 && next + 1 < program.size()) line += proto::numbered(long(next) + 2, program[next + 1]);  // a lost newline
        else if (r < 15) line.erase(line.rfind('*'));                                          // no checksum
        else if (r < 17) line = proto::numbered(long(next) + 3, program[next]);                // a skipped number
        else if (r < 19 && next > 0) line = proto::numbered(long(next), program[next - 1]);    // a repeat
        const auto marlin = marlin_receives(line, p.last_line());
        const auto o = feed(p, line);
        switch (marlin.what) {
            case MarlinVerdict::Refuse: {
                ++refused;
                INFO(line, " -> ", o.written.empty() ? std::string("nothing") : o.written[0]);
                CHECK(o.written == triple(marlin.why, marlin.n));
                CHECK(o.handed.empty());
                break;
            }
            case MarlinVerdict::Drop:
                ++dropped;
                CHECK_FALSE(o.took());
                break;
            case MarlinVerdict::Take:
                if (o.took()) {
                    ++taken;
                    CHECK(p.last_line() == marlin.n);
                } else {
                    ++stricter;
                    CHECK(o.handed.empty());
                    REQUIRE(o.written.size() == 3);
                    CHECK(o.written[0].rfind("Error:", 0) == 0);
                }
                break;
        }
        for (const auto& a : o.handed)
            if (a.kind == Kind::Command) run.push_back(proto::strip_comment(a.text));
        // The sender: on Resend it goes back to the number named; otherwise on.
        for (const auto& w : o.written)
            if (w.rfind("Resend: ", 0) == 0) next = std::size_t(std::stol(w.substr(8)) - 1);
        if (o.took()) next = std::size_t(p.last_line());
    }
    CHECK(next == program.size());
    CHECK(refused > 20);
    CHECK(taken >= program.size());
    // What ran is the program, each line once, in order: no damaged line got through.
    REQUIRE(run.size() == program.size());
    for (std::size_t i = 0; i < run.size(); ++i) CHECK(run[i] == proto::strip_comment(program[i]));
    MESSAGE("refused " << refused << ", dropped " << dropped << ", refused where Marlin takes " << stricter);
}

namespace {

Machine rw2() { return load_machine(std::string(XLATE5_MACHINE_DIR_FOR_TESTS) + "/rw2.toml"); }

// ServeSteps as Service sets it up: a translator for `machine`, Marlin's 96-byte line buffer.
struct Steps {
    Machine machine;
    Kinematics kin;
    ServeSteps steps;
    explicit Steps(Machine m, ServeSteps::Position start = ServeSteps::Position::Unknown, std::size_t max_line = marlin::kMaxCmdSize)
        : machine(std::move(m)), kin(machine), steps(machine, TranslatorOptions{}, start) {
        steps.reset(kin);
        FirmwareOptions f;
        f.max_line = max_line;
        steps.set_room({FirmwareProtocol(f).max_command()});
    }
    ServeSteps::Step line(const std::string& l, std::uint64_t n) { return steps.line(l, proto::command_code(proto::strip_comment(l)), n); }
};

void append(std::vector<std::string>& to, const ServeSteps::Batch& b) { to.insert(to.end(), b.lines.begin(), b.lines.end()); }

}  // namespace

TEST_CASE("serve steps: a print without waits is translated exactly as offline") {
    const auto lines = test::unwinding_print(false);
    Steps s(rw2(), ServeSteps::Position::Known);
    std::vector<std::string> out;
    std::uint64_t n = 0;
    for (const auto& l : lines) {
        const auto step = s.line(l, ++n);
        REQUIRE(step.refused.empty());
        CHECK(step.released.lines.empty());  // nothing released early: no wait or report came
        CHECK_FALSE(step.firmware_answers);
        append(out, step.own);
    }
    CHECK(s.steps.holding());  // the last window is open until the end
    ServeSteps::Batch rest;
    std::string bad;
    REQUIRE(s.steps.release(rest, bad));
    append(out, rest);
    CHECK_FALSE(s.steps.holding());
    CHECK(s.steps.lines_in() == lines.size());
    CHECK(out == firmware_commands(s.machine, lines));
}

TEST_CASE("serve steps: a wait releases the held output first and is answered by the firmware") {
    const auto lines = test::unwinding_print(true);
    Steps s(rw2(), ServeSteps::Position::Known);
    std::uint64_t n = 0;
    bool released = false;
    std::vector<std::string> out;
    for (const auto& l : lines) {
        const auto step = s.line(l, ++n);
        if (!step.refused.empty()) {
            // The turn back the look-back would have found lies behind the release: serve refuses
            // a later line (serve --check says so), where offline translation unwinds.
            CHECK(released);
            CHECK_FALSE(step.too_long);
            CHECK(step.refused.find("outside its limits") != std::string::npos);
            break;
        }
        append(out, step.released);
        if (l != "M400") {
            CHECK(step.released.lines.empty());
            append(out, step.own);
            continue;
        }
        CHECK(step.firmware_answers);
        REQUIRE_FALSE(step.released.lines.empty());
        released = true;
        // The window opened before it and reaches the M400 (the serials its output stands for).
        CHECK(step.released.first < n);
        CHECK(step.released.first + step.released.span - 1 == n);
        CHECK_FALSE(s.steps.holding());
        // Everything before the M400 is out, as offline translation of the lines before it
        // gives them when it finishes there.
        CHECK(out == firmware_commands(s.machine, std::vector<std::string>(lines.begin(), lines.begin() + std::ptrdiff_t(n - 1))));
        CHECK(step.own.lines == std::vector<std::string>{"M400"});
        append(out, step.own);
    }
    CHECK(released);
    // Temperatures are answered by the firmware but never end a window.
    Steps t(rw2(), ServeSteps::Position::Known);
    n = 0;
    for (const auto& l : test::unwinding_print(false)) t.line(l, ++n);
    REQUIRE(t.steps.holding());
    const auto m105 = t.line("M105", ++n);
    CHECK(m105.firmware_answers);
    CHECK(m105.released.lines.empty());
    CHECK(m105.own.lines == std::vector<std::string>{"M105"});
    CHECK(t.steps.holding());
}

TEST_CASE("serve steps: while the position is unknown only homing moves the machine") {
    Steps s(rw2());
    auto step = s.line("G1 X10 Y10 Z5", 1);
    CHECK(step.refused.find("the printer's position is not known (the firmware has not reported it yet): home it (G28) first") == 0);
    CHECK(step.own.lines.empty());
    CHECK(s.steps.lines_in() == 0);  // refused before it is translated or counted
    CHECK(s.line("M105", 2).refused.empty());
    // Homing some axes leaves the others unknown; a G28 naming none homes them all.
    CHECK(s.line("G28 A", 3).refused.empty());
    CHECK(s.steps.position() == ServeSteps::Position::Unknown);
    CHECK_FALSE(s.line("G0 X1", 4).refused.empty());
    CHECK(s.line("G28 ; all", 5).refused.empty());
    CHECK(s.steps.position() == ServeSteps::Position::Known);
    CHECK(s.line("G1 X10 Y10 Z5", 6).refused.empty());
    // The firmware stopped: unknown again, and said why.
    s.steps.position_lost("it reset");
    step = s.line("G1 X11", 7);
    CHECK(step.refused.find("(the firmware stopped: it reset)") != std::string::npos);
}

TEST_CASE("serve steps: the position asked of the firmware, answered or not") {
    Steps s(rw2());
    REQUIRE(s.steps.ask_position());
    CHECK(s.steps.position() == ServeSteps::Position::Asking);
    // Nothing is taken from the senders while the question is out.
    ServeSteps::QueueState q;
    q.firmware = q.firmware_ready = true;
    q.queue_lines = 64;
    CHECK(s.steps.gate(q) == ServeSteps::Gate::Wait);
    s.steps.position_unanswered();
    CHECK(s.steps.position() == ServeSteps::Position::Unknown);
    CHECK(s.steps.position_why() == "the firmware did not answer M114 with a position");
    CHECK(s.steps.gate(q) == ServeSteps::Gate::Take);
    // A report places the translator where the firmware is.
    REQUIRE(s.steps.ask_position());
    std::vector<double> q0(s.machine.joints.size(), 0.0);
    q0[0] = 7;
    s.steps.position_read(&q0, 2.5, "");
    CHECK(s.steps.position() == ServeSteps::Position::Known);
    CHECK(s.steps.translator().joints()[0] == doctest::Approx(7));
    REQUIRE(s.steps.ask_position());
    s.steps.position_read(nullptr, std::nullopt, "it has no B");
    CHECK(s.steps.position_why() == "the firmware's M114 answer could not be read: it has no B");
    // Not asked while the look-back holds output: the translator is ahead of the firmware.
    Steps h(rw2(), ServeSteps::Position::Known);
    std::uint64_t n = 0;
    for (const auto& l : test::unwinding_print(false)) h.line(l, ++n);
    REQUIRE(h.steps.holding());
    CHECK_FALSE(h.steps.ask_position());
    CHECK(h.steps.position() == ServeSteps::Position::Known);
}

TEST_CASE("serve steps: the firmware's line buffer decides before the ok") {
    // A 40-byte buffer, of which N and the checksum take their room.
    Steps s(rw2(), ServeSteps::Position::Known, 40);
    FirmwareOptions f;
    f.max_line = 40;
    const std::size_t room = FirmwareProtocol(f).max_command();
    REQUIRE(room == 25);
    REQUIRE(s.steps.gate({}) == ServeSteps::Gate::Take);
    // A command passed on as written that no line holds: refused before it is counted.
    auto step = s.line("M23 /sd/a_very_long_file_name_indeed.gcode", 1);
    CHECK(step.too_long);
    CHECK(step.refused == "'M23 /sd/a_very_long_file_name_indeed.gcode' is longer than the firmware's line buffer (25 characters with "
                          "its line number and checksum)");
    CHECK(s.steps.lines_in() == 0);
    // A message is shortened to fit, and said so.
    step = s.line("M117 printing the second layer now", 2);
    REQUIRE(step.refused.empty());
    REQUIRE(step.own.lines.size() == 1);
    CHECK(step.own.lines[0] == std::string("M117 printing the second layer now").substr(0, room));
    CHECK(step.own.changed);
    CHECK(step.own.split == 0);
    // A move's F goes to a line of its own.
    std::vector<std::string> parts;
    CHECK(split_for_firmware({room}, "G1 X100.5 Y100.25 Z5.5 F1200", parts));
    CHECK(parts == std::vector<std::string>{"G1 F1200", "G1 X100.5 Y100.25 Z5.5"});
    CHECK_FALSE(split_for_firmware({room}, "G1 X100.5 Y100.25 Z5.5 A12.5 F1200", parts));
}

TEST_CASE("serve steps: a line the translator refuses leaves nothing queued") {
    Steps s(rw2(), ServeSteps::Position::Known);
    CHECK(s.line("G28", 1).refused.empty());
    const auto step = s.line("G1 X10 Q5", 2);
    CHECK_FALSE(step.refused.empty());
    CHECK_FALSE(step.too_long);
    CHECK(step.own.lines.empty());
    CHECK(s.steps.lines_in() == 2);  // translated (and refused by the translator)
}

TEST_CASE("serve steps: which lines are taken from the senders, and when") {
    Steps s(rw2(), ServeSteps::Position::Known);
    using G = ServeSteps::Gate;
    ServeSteps::QueueState q;
    q.firmware = q.firmware_ready = true;
    q.queue_lines = 4;
    CHECK(s.steps.gate(q) == G::Take);
    q.queued = 4;  // the queue is full: the sender waits for its ok (busy)
    CHECK(s.steps.gate(q) == G::Wait);
    q.queued = 0;
    q.firmware_ready = false;  // greeting or resyncing
    CHECK(s.steps.gate(q) == G::Wait);
    q.stopped = true;  // stopped: answered at once (not run)
    CHECK(s.steps.gate(q) == G::Take);
    q.draining = true;  // draining: lines not yet acknowledged stay with the sender
    CHECK(s.steps.gate(q) == G::Keep);
    CHECK(s.steps.gate(ServeSteps::QueueState{}) == G::Take);  // no firmware: answered at once (not run)
}

TEST_CASE("serve steps: G28 reads axis letters as the interpreter does") {
    const Machine m = rw2();
    CHECK(homes_all(m, "G28"));
    CHECK(homes_all(m, "G28 ; X"));
    CHECK_FALSE(homes_all(m, "G28 X"));
    CHECK_FALSE(homes_all(m, "G28 a"));
    for (const auto& j : m.joints) {
        CHECK(is_axis_letter(m, j.name));
        CHECK_FALSE(homes_all(m, std::string("G28 ") + j.name));
    }
    CHECK_FALSE(is_axis_letter(m, 'E'));
    CHECK(homes_all(m, "G28 E"));  // not an axis: the translator refuses the word, no position is claimed
}

TEST_CASE("position report: the firmware's joints read, and told in tool space") {
    const Machine m = rw2();
    const Kinematics kin(m);
    std::string why;
    // Marlin's shape: the joints by their firmware letters, E, then the step counts (ignored).
    const auto at = read_position(m, "X:7.00 Y:-3.50 Z:12.25 A:10.00 B:5.00 E:1.50 Count X:560 Y:0 Z:0 A:-28000 B:-6800", why);
    REQUIRE(at);
    REQUIRE(at->q.size() == m.joints.size());
    std::vector<double> expected(m.joints.size(), 0.0);
    for (std::size_t j = 0; j < m.joints.size(); ++j) {
        const std::map<char, double> words = {{'X', 7}, {'Y', -3.5}, {'Z', 12.25}, {'A', 10}, {'B', 5}};
        expected[j] = words.at(m.joints[j].output);
    }
    m.compensation.undo(expected);
    for (std::size_t j = 0; j < m.joints.size(); ++j) CHECK(at->q[j] == doctest::Approx(expected[j]));
    REQUIRE(at->e);
    CHECK(*at->e == doctest::Approx(1.5));
    // Refused whole: a joint missing, or not a number.
    CHECK_FALSE(read_position(m, "X:7.00 Y:0.00 Z:0.00 A:10.00 E:0.00 Count X:1 Y:0 Z:0 A:0 B:0", why));
    CHECK(why == "it has no B");
    CHECK_FALSE(read_position(m, "X:7.00 Y:0.00 Z:0.00 A:nan B:5.00", why));
    CHECK(why == "its A is 'nan', not a number");
    // Told in tool space: the tip by the forward kinematics (in the program frame), E right after
    // Z, then the rotary joints.
    const Eigen::Vector3d offset(1, 2, 3);
    const std::string told = tool_space_position(m, kin, offset, *at);
    const Eigen::Vector3d tip = kin.forward(at->q).tip - offset;
    double x = 0, y = 0, z = 0, e = 0, a = 0, b = 0;
    REQUIRE(std::sscanf(told.c_str(), "X:%lf Y:%lf Z:%lf E:%lf A:%lf B:%lf", &x, &y, &z, &e, &a, &b) == 6);
    CHECK(std::abs(x - tip.x()) <= 0.005);
    CHECK(std::abs(y - tip.y()) <= 0.005);
    CHECK(std::abs(z - tip.z()) <= 0.005);
    CHECK(e == doctest::Approx(1.5));
    CHECK(a == doctest::Approx(at->q[3]));
    CHECK(b == doctest::Approx(at->q[4]));
}
