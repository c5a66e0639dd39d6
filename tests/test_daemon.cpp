// The service end to end on real pseudo-terminals: a sender streams tool-space G-code into
// xlate5, xlate5 drives the virtual printer, and what the printer executed must equal the
// offline translation of the same lines: nothing lost, duplicated or reordered, under every
// fault the virtual printer can inject.
#include <doctest/doctest.h>

#include <algorithm>
#include <cctype>
#include <map>

#include "tests/daemon_rig.hpp"
#include "translators/error.hpp"

using namespace xlate5;
using namespace xlate5::test;


TEST_CASE("a clean print executes exactly the offline translation, numbered or bare sender") {
    const auto lines = rw2_print(3000);
    {
        Rig rig("rw2");
        stream_and_compare(rig, lines, 60);
        CHECK(rig.service().firmware()->stats().resend_requests == 0);
    }
    {
        Rig rig("rw2");
        stream_and_compare(rig, lines, 60, /*numbered=*/false);  // a cncjs-style sender
    }
}

TEST_CASE("fault classes: dropped bytes, spurious resends with and without ok, garbled replies, busy, slow planner") {
    const auto lines = rw2_print(4000, 3);
    SUBCASE("dropped bytes (a lost newline merges two lines)") {
        Rig rig("rw2", [](ServeConfig& c) { c.sim.faults.drop = 0.02; });
        stream_and_compare(rig, lines, 120);
        CHECK(rig.sim().stats().corrupted > 20);
    }
    SUBCASE("resend requests followed by ok") {
        Rig rig("rw2", [](ServeConfig& c) { c.sim.faults.spurious_resend = 0.03; });
        stream_and_compare(rig, lines, 120);
        CHECK(rig.sim().stats().refused > 50);
    }
    SUBCASE("resend requests without the ok after them") {
        Rig rig("rw2", [](ServeConfig& c) {
            c.sim.faults.spurious_resend = 0.03;
            c.sim.faults.no_ok_after_resend = true;
        });
        stream_and_compare(rig, lines, 120);
        CHECK(rig.sim().stats().refused > 50);
    }
    SUBCASE("garbled replies (lost oks recovered by timeout, never run twice)") {
        Rig rig("rw2", [](ServeConfig& c) {
            c.sim.faults.garble_reply = 0.005;
            c.firmware.reply_timeout = 0.1;
        });
        stream_and_compare(rig, lines, 240);
        CHECK(rig.sim().stats().garbled > 10);
    }
    SUBCASE("busy periods with keepalives") {
        Rig rig("rw2", [](ServeConfig& c) {
            c.sim.faults.busy = 0.002;
            c.sim.faults.busy_seconds = 0.4;
            c.sim.faults.busy_interval = 0.1;
            c.firmware.reply_timeout = 0.25;  // shorter than the busy period: keepalives must hold it off
        });
        stream_and_compare(rig, lines, 120);
        CHECK(rig.service().firmware()->stats().busy > 5);
        CHECK(rig.service().firmware()->stats().timeouts == 0);
    }
    SUBCASE("slow planner with ADVANCED_OK: the window is learned, oks held back") {
        const auto few = rw2_print(600, 4);
        Rig rig("rw2", [](ServeConfig& c) {
            c.sim.faults.move_ms = 2;
            c.sim.advanced_ok = true;
            c.firmware.reply_timeout = 2;
        });
        stream_and_compare(rig, few, 120);
        CHECK(rig.service().firmware()->window() == rig.config.sim.buffer);
    }
}

TEST_CASE("RepRapFirmware drops bad lines silently: recovered by timeout") {
    const auto lines = rw2_print(3000, 9);
    Rig rig("rw2", [](ServeConfig& c) {
        c.firmware.reprap = true;
        c.sim.reprap = true;
        c.sim.faults.corrupt = 0.01;
        c.firmware.reply_timeout = 0.05;
    });
    stream_and_compare(rig, lines, 120);
    CHECK(rig.sim().stats().dropped > 10);
    // Each damaged line costs one timeout; a flipped bit that makes a '\r' splits one line into
    // two dropped halves, so the count to compare with is the damaged lines, not the drops.
    CHECK(rig.service().firmware()->stats().timeouts >= rig.sim().stats().corrupted);
}

TEST_CASE("RepRapFirmware homing and heating in silence: waited for, not resent, not a fault") {
    const std::vector<std::string> lines = {"G28", "G92 A-168", "M109 S200", "G1 A0 B0 F3000", "G1 X50 Y50 Z5", "M400", "G1 X60"};
    Rig rig("rw2", [](ServeConfig& c) {
        c.firmware.reprap = true;
        c.sim.reprap = true;
        c.sim.faults.slow_seconds = 1.0;   // five times the reply timeout, without a word
        c.firmware.reply_timeout = 0.2;
        c.firmware.long_timeout = 10;
    });
    stream_and_compare(rig, lines, 30);
    CHECK(rig.service().firmware()->stats().resent == 0);
}

TEST_CASE("a firmware that resets, halts or vanishes stops the print: sender told, nothing replayed") {
    const auto lines = rw2_print(2000, 5);
    struct Case {
        const char* name;
        std::function<void(SimFaults&)> set;
        const char* says;
    };
    const Case cases[] = {
        {"reset", [](SimFaults& f) { f.reset_after = 700; }, "restarted"},
        {"kill", [](SimFaults& f) { f.kill_after = 700; }, "halted"},
        {"unplug", [](SimFaults& f) { f.unplug_after = 700; }, "closed"},
    };
    for (const auto& k : cases) {
        CAPTURE(k.name);
        Rig rig("rw2", [&](ServeConfig& c) { k.set(c.sim.faults); });
        REQUIRE(rig.ready());
        const auto expected = offline(rig.machine, lines);
        TestSender sender(rig.io, rig.config.pty);
        sender.stream(lines);
        REQUIRE(rig.run_until([&] { return rig.service().stopped(); }, 30));
        // The sender goes on sending (printcore does): every further line is refused, not run.
        // (With the look-back it may have had all its oks already: wait for the news to reach it.)
        const auto told_now = [&] {
            for (const auto& r : sender.received)
                if (r.rfind("Error:", 0) == 0 && r.find(k.says) != std::string::npos) return true;
            return false;
        };
        rig.run_until([&] { return sender.done() && told_now(); }, 30);
        const auto executed = rig.executed_after_hello();
        // What ran is exactly a prefix of the translation: in order, nothing twice, and nothing
        // after the fault (the greeting counts as two executed commands).
        CHECK(executed.size() == 700 - 2);
        REQUIRE(executed.size() <= expected.size());
        CHECK(std::equal(executed.begin(), executed.end(), expected.begin()));
        CHECK_MESSAGE(told_now(), "the sender was not told why");
        CHECK(rig.service().firmware()->queued() == 0);

        // M999 starts over: the firmware is greeted again (a vanished port is opened again: here
        // a fresh virtual printer is plugged in) and a new print runs from a clean state.
        const std::vector<std::string> again = {"G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X50 Y50 Z5"};
        std::vector<std::string> with_m999 = {"M999"};
        with_m999.insert(with_m999.end(), again.begin(), again.end());
        const auto before = rig.sim().executed().size();
        sender.stream(with_m999);
        REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 20));
        const auto& e = rig.sim().executed();
        if (std::string(k.name) == "kill") {
            // After kill() only a reset brings Marlin back: the greeting goes unanswered, the
            // print stays stopped and nothing runs.
            CHECK(rig.service().stopped());
            CHECK(e.size() == before);
            continue;
        }
        CHECK_FALSE(rig.service().stopped());
        const auto expect_again = offline(rig.machine, again);
        REQUIRE(e.size() >= expect_again.size());
        CHECK(std::vector<std::string>(e.end() - std::ptrdiff_t(expect_again.size()), e.end()) == expect_again);
        if (std::string(k.name) == "unplug") CHECK(e.size() == 2 + expect_again.size());  // a new printer
        else CHECK(e.size() == before + 3 + expect_again.size());                         // M999, greeted again
    }
}

TEST_CASE("reset_every: the virtual printer reboots each time its executed commands reach a multiple; each cut print is a prefix") {
    const auto lines = rw2_print(600, 6);
    Rig rig("rw2", [](ServeConfig& c) { c.sim.faults.reset_every = 400; });
    REQUIRE(rig.ready());
    const auto expected = offline(rig.machine, lines);
    REQUIRE(expected.size() > 400);  // each attempt is cut by the next reset
    std::size_t seen = 0;
    for (std::uint64_t attempt = 1; attempt <= 3; ++attempt) {
        CAPTURE(attempt);
        TestSender sender(rig.io, rig.config.pty);
        std::vector<std::string> print = lines;
        if (attempt > 1) print.insert(print.begin(), "M999");
        sender.stream(print);
        if (attempt > 1) REQUIRE(rig.run_until([&] { return !rig.service().stopped(); }, 30));  // M999 took
        REQUIRE(rig.run_until([&] { return rig.service().stopped(); }, 30));
        CHECK(rig.service().stop_reason().find("restarted") != std::string::npos);
        CHECK(rig.sim().stats().resets == attempt);
        CHECK(rig.sim().stats().executed == 400 * attempt);
        // What ran since the last reset: the greeting (M999 first, after a stop), then a prefix of the print.
        const auto& e = rig.sim().executed();
        std::vector<std::string> part(e.begin() + std::ptrdiff_t(seen), e.end());
        seen = e.size();
        std::size_t skip = 0;
        while (skip < part.size() && (part[skip] == "M999" || part[skip] == "M110 N0" || part[skip] == "M115")) ++skip;
        part.erase(part.begin(), part.begin() + std::ptrdiff_t(skip));
        CHECK(!part.empty());
        REQUIRE(part.size() <= expected.size());
        CHECK(std::equal(part.begin(), part.end(), expected.begin()));
        rig.run_until([&] { return sender.done(); }, 10);
    }
}

TEST_CASE("M112 reaches the firmware at once while the queue is full") {
    Rig rig("rw2", [](ServeConfig& c) {
        c.sim.faults.move_ms = 200;  // a slow printer: the queue fills and the sender is held
        c.queue_lines = 32;
        c.firmware.reply_timeout = 5;
    });
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty);
    sender.stream(rw2_print(500, 2));
    REQUIRE(rig.run_until([&] { return rig.service().firmware()->queued() >= 32; }, 20));
    // The look-back releases its held lines in one burst: wait until the firmware's planner is
    // full, so that from here on it takes one move per 200 ms.
    const auto full = 2 + std::size_t(rig.config.sim.planner) + 2;  // greeting, planner, the next lines
    REQUIRE(rig.run_until([&] { return rig.sim().executed().size() >= full; }, 20));
    rig.run_until([] { return false; }, 0.05);
    const auto before = rig.sim().executed().size();
    sender.send_now("M112");
    REQUIRE(rig.run_until([&] { return rig.sim().halted(); }, 2));
    const auto& e = rig.sim().executed();
    CHECK(e.back() == "M112");
    CHECK(e.size() <= before + 2);                // nothing from the queue went ahead of it
    CHECK(rig.service().stopped());
    CHECK(rig.service().firmware()->queued() == 0);  // the rest of the queue is dropped, not sent later
}

TEST_CASE("a sender held by a full queue gets busy keepalives, as from Marlin, and every line still runs once") {
    // More lines than the look-back window holds, so the sender meets a full queue.
    const auto lines = rw2_print(Translator::kDefaultLookback + 200, 6);
    Rig rig("rw2", [](ServeConfig& c) {
        c.sim.faults.move_ms = 2;  // a slow printer: 2200 moves take over 4 s, the queue holds 8
        c.queue_lines = 8;
        c.busy_interval = 0.2;
        c.firmware.reply_timeout = 5;
    });
    const auto received = stream_and_compare(rig, lines, 60);
    const auto busy = std::count(received.begin(), received.end(), std::string("echo:busy: processing"));
    CHECK(busy >= 3);
}

TEST_CASE("M114 answers in tool space; M105 gets the firmware's report on its ok; M115 adds xlate5") {
    Rig rig("rw2");
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty);
    sender.stream({"G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X10.5 Y20.25 Z5 A30 B10 F1200", "M114", "M105", "M115"});
    REQUIRE(rig.run_until([&] { return sender.done(); }, 10));
    bool position = false, xlate5_line = false, firmware_name = false;
    for (const auto& r : sender.received) {
        if (r.rfind("X:", 0) == 0) {
            position = true;
            // The tip the program asked for, not the joints (X is offset by la sin A + ... on rw2).
            // E directly after Z, as OctoPrint's M114 pattern needs.
            CHECK(r == "X:10.50 Y:20.25 Z:5.00 E:0.00 A:30.00 B:10.00");
        }
        xlate5_line = xlate5_line || r.rfind("XLATE5:", 0) == 0;
        firmware_name = firmware_name || r.rfind("FIRMWARE_NAME:Marlin", 0) == 0;
    }
    CHECK(position);
    CHECK(xlate5_line);
    CHECK(firmware_name);
    bool temps = false;
    for (const auto& ok : sender.oks) temps = temps || ok.find("T:21.50") != std::string::npos;
    CHECK(temps);
}

TEST_CASE("sender side: Marlin's answers to bad checksums, skipped numbers and missing checksums") {
    Rig rig("rw2");
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty);
    sender.send_raw(proto::numbered(0, "M110 N0"));
    sender.send_raw("N1 G28*99");                     // wrong checksum
    sender.send_raw(proto::numbered(3, "G28"));       // skips 1 and 2
    sender.send_raw("N1 G28");                        // no checksum
    sender.send_raw(proto::numbered(1, "G28"));       // right
    REQUIRE(rig.run_until([&] { return sender.oks.size() >= 5; }, 5));
    REQUIRE(sender.received.size() == 3);
    CHECK(sender.received[0] == "Error:checksum mismatch, Last Line: 0");
    CHECK(sender.received[1] == "Error:Line Number is not Last Line Number+1, Last Line: 0");
    CHECK(sender.received[2] == "Error:No Checksum with line number, Last Line: 0");
    CHECK(sender.resends == 3);
    rig.run_until([&] { return rig.service().idle(); }, 5);
    CHECK(rig.executed_after_hello() == std::vector<std::string>{"G28"});
}

TEST_CASE("lines longer than the firmware's buffer are split, never sent long") {
    const auto lines = rw2_print(500, 8);
    // A buffer just long enough for every move without its F: the longest moves with F must be split.
    std::size_t longest_without_f = 0, longest = 0;
    {
        Rig probe("rw2");
        for (const auto& l : offline(probe.machine, lines)) {
            longest = std::max(longest, l.size());
            std::string without_f = l;
            if (const auto f = l.find(" F"); f != std::string::npos) {
                const auto end = l.find(' ', f + 1);
                without_f = l.substr(0, f) + (end == std::string::npos ? "" : l.substr(end));
            }
            longest_without_f = std::max(longest_without_f, without_f.size());
        }
    }
    REQUIRE(longest > longest_without_f);
    const std::size_t max_line = longest_without_f + 15;
    Rig rig("rw2", [&](ServeConfig& c) {
        c.firmware.max_line = max_line;
        c.sim.max_line = max_line;
    });
    REQUIRE(rig.ready());
    auto expected = offline(rig.machine, lines);
    TestSender sender(rig.io, rig.config.pty);
    sender.stream(lines);
    REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 60));
    // Put the F that was moved to a line of its own back on its move: the result is the translation.
    std::vector<std::string> joined;
    const auto& e = rig.executed_after_hello();
    for (std::size_t i = 0; i < e.size(); ++i) {
        CHECK(proto::numbered(99999999, e[i]).size() + 1 <= max_line);
        if (e[i].rfind("G1 F", 0) == 0 && e[i].find(' ', 3) == std::string::npos && i + 1 < e.size()) {
            joined.push_back(e[i + 1] + " " + e[i].substr(3));
            ++i;
        } else {
            joined.push_back(e[i]);
        }
    }
    CHECK(rig.service().stats().split_long > 0);
    REQUIRE(joined.size() == expected.size());
    for (std::size_t i = 0; i < joined.size(); ++i) REQUIRE(joined[i] == expected[i]);
}

TEST_CASE("a refused print line cancels the print with OctoPrint's action command, quoting the line; never Error:") {
    Rig rig("rw2");
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty);
    sender.stream({"G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X10 Y10 Z5", "G1 X10 Q5", "G1 X20"});
    REQUIRE(rig.run_until([&] { return sender.done(); }, 10));
    rig.run_until([&] { return rig.service().idle(); }, 5);
    bool cancel = false, quoted = false;
    for (const auto& r : sender.received) {
        CHECK_MESSAGE(r.rfind("Error", 0) != 0, "OctoPrint would send M112 on: " << r);
        cancel = cancel || r == "//action:cancel";
        quoted = quoted || (r.rfind("echo:xlate5: print cancelled at line 5 'G1 X10 Q5': ", 0) == 0 && r.find("Q") != std::string::npos);
    }
    CHECK(cancel);
    CHECK(quoted);
    const auto e = rig.executed_after_hello();
    REQUIRE(!e.empty());
    CHECK(e.back().find("X10") != std::string::npos);  // G1 X20 (line 6) never ran
    CHECK(rig.service().stopped());
    // A new print (the sender numbers from M110 N0 again) runs without M999.
    const std::vector<std::string> again = {"G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X30 Y10 Z5"};
    sender.stream(again);
    REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 10));
    CHECK_FALSE(rig.service().stopped());
    const auto e2 = rig.executed_after_hello();
    const auto expect_again = offline(rig.machine, again);
    REQUIRE(e2.size() >= expect_again.size());
    CHECK(std::vector<std::string>(e2.end() - std::ptrdiff_t(expect_again.size()), e2.end()) == expect_again);
}

TEST_CASE("a typo in a terminal (an unnumbered line) is refused with echo: and a notification; the rest runs") {
    Rig rig("rw2");
    const std::vector<std::string> good = {"G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X10 Y10 Z5", "G1 X20 Y10 Z5"};
    std::vector<std::string> typed = good;
    typed.insert(typed.begin() + 4, "G1 X10 Q5");
    REQUIRE(rig.ready());
    TestSender sender(rig.io, rig.config.pty, /*numbered=*/false);
    sender.stream(typed);
    REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 10));
    bool echo = false, notification = false;
    for (const auto& r : sender.received) {
        CHECK_MESSAGE(r.rfind("Error", 0) != 0, "OctoPrint would send M112 on: " << r);
        echo = echo || r.rfind("echo:xlate5: refused line 5 'G1 X10 Q5': ", 0) == 0;
        notification = notification || r.rfind("//action:notification xlate5: refused line 5 'G1 X10 Q5'", 0) == 0;
    }
    CHECK(echo);
    CHECK(notification);
    CHECK_FALSE(rig.service().stopped());
    // The same motion as the file without the typo. (The text may differ in words repeated
    // with unchanged values: the translator's memory of what it wrote last is not kept across
    // a line it refused; see the translator's feed().)
    const auto state_after_each = [](const std::vector<std::string>& cmds) {
        std::vector<std::map<char, double>> states;
        std::map<char, double> st;
        for (const auto& c : cmds) {
            st['#'] = double(proto::command_code(c).code10);
            for (std::size_t i = 1; i + 1 < c.size(); ++i)
                if (c[i - 1] == ' ' && std::isalpha(static_cast<unsigned char>(c[i]))) st[c[i]] = std::strtod(c.c_str() + i + 1, nullptr);
            states.push_back(st);
        }
        return states;
    };
    CHECK(state_after_each(rig.executed_after_hello()) == state_after_each(offline(rig.machine, good)));
}

TEST_CASE("senders: a second one may read and stop but not print; one that leaves mid-print ends it; one that never reads is bounded") {
    Rig rig("rw2", [](ServeConfig& c) {
        c.tcp = "127.0.0.1:0";
        c.sim.faults.move_ms = 20;  // slow enough that the first print is still going
        c.max_pending = 64;
    });
    REQUIRE(rig.ready());
    const auto port = rig.parts.acceptor->local_endpoint().port();
    auto connect = [&](const char* name, std::vector<std::string>& got) {
        asio::ip::tcp::socket sock(rig.io);
        sock.connect({asio::ip::make_address("127.0.0.1"), port});
        auto link = std::make_shared<TcpLink>(std::move(sock), name);
        link->start([&got](std::string_view l) { got.emplace_back(l); }, [](const std::string&) {});
        return link;
    };
    SUBCASE("a second sender during a print") {
        TestSender printer(rig.io, rig.config.pty);
        printer.stream(rw2_print(300, 3));
        REQUIRE(rig.run_until([&] { return rig.executed_after_hello().size() > 20; }, 10));
        std::vector<std::string> got;
        auto other = connect("second", got);
        other->send("G1 X5\nM105\n");
        REQUIRE(rig.run_until([&] { return std::count_if(got.begin(), got.end(), [](const std::string& l) { return l.rfind("ok", 0) == 0; }) >= 2; }, 10));
        bool busy = false, temps = false;
        for (const auto& l : got) {
            CHECK(l.rfind("Error", 0) != 0);
            busy = busy || (l.rfind("echo:xlate5: busy: ", 0) == 0 && l.find("'G1 X5' was not run") != std::string::npos);
            temps = temps || l.rfind("ok T:", 0) == 0;
        }
        CHECK(busy);
        CHECK(temps);  // reading is allowed
        REQUIRE(rig.run_until([&] { return printer.done() && rig.service().idle(); }, 60));
        CHECK(rig.executed_after_hello() == offline(rig.machine, rw2_print(300, 3)));  // nothing of the second sender ran
        other->close();
    }
    SUBCASE("a sender that leaves mid-print: the lines it was answered for run, the rest are dropped") {
        const auto lines = rw2_print(6000, 4);
        std::vector<std::string> got;
        auto s = connect("leaver", got);
        std::string all;
        for (const auto& l : lines) all += l + "\n";
        s->send(all);  // writes ahead without waiting, then goes
        REQUIRE(rig.run_until([&] { return rig.executed_after_hello().size() > 30; }, 10));
        const auto answered = rig.service().stats().lines_in;  // lines it was sent ok for
        const auto pending = rig.service().pending_lines();
        s->close();
        REQUIRE(rig.run_until([&] { return rig.service().idle(); }, 120));
        CHECK(pending > 0);  // it had written lines not yet answered
        REQUIRE(answered < lines.size());
        const auto ran = rig.executed_after_hello();
        // Exactly the translation of the answered lines: nothing of the rest, nothing for nobody.
        CHECK(ran == offline(rig.machine, std::vector<std::string>(lines.begin(), lines.begin() + std::ptrdiff_t(answered))));
        CHECK_FALSE(rig.service().stopped());
    }
    SUBCASE("a sender that writes and never reads: the service reads it no further than its bound") {
        std::vector<std::string> ignored;
        asio::ip::tcp::socket sock(rig.io);
        sock.connect({asio::ip::make_address("127.0.0.1"), port});
        auto s = std::make_shared<TcpLink>(std::move(sock), "flood");  // never started: reads nothing
        std::string all;
        for (const auto& l : rw2_print(50000, 5)) all += l + "\n";
        s->send(all);
        std::size_t most = 0;
        rig.run_until([&] {
            most = std::max(most, rig.service().pending_lines());
            return false;
        }, 3);
        CHECK(most > 0);
        // At most its bound, plus the lines of the one read that hit it (4 kB).
        CHECK(most <= rig.config.max_pending + 4096 / 8);
        s->close();
    }
}

TEST_CASE("serve translates exactly like offline: a travel move unwound by look-back prints the same joint moves") {
    // Azimuth printing A 0 -> 300 on rw2 (A is limited to +-168): the layer change at A = 150 is
    // a travel move the look-back turns onto the other branch, as `xlate5 translate` does.
    Rig probe("rw2");
    const Kinematics k(probe.machine);
    const std::vector<std::string> lines = unwinding_print(false);
    // Without look-back the file cannot be translated: it needs the unwind.
    {
        Translator t(k, {});
        std::string out;
        bool failed = false;
        std::uint64_t n = 0;
        try {
            for (const auto& l : lines) t.feed(l, ++n, out);
        } catch (const InputError&) {
            failed = true;
        }
        REQUIRE(failed);
    }
    Rig rig("rw2");
    stream_and_compare(rig, lines, 30);
}

TEST_CASE("TCP senders on loopback; a remote address needs allow_remote") {
    Rig rig("rw2", [](ServeConfig& c) { c.tcp = "127.0.0.1:0"; });
    REQUIRE(rig.ready());
    const auto port = rig.parts.acceptor->local_endpoint().port();
    asio::ip::tcp::socket sock(rig.io);
    sock.connect({asio::ip::make_address("127.0.0.1"), port});
    auto link = std::make_shared<TcpLink>(std::move(sock), "client");
    std::vector<std::string> got;
    link->start([&](std::string_view l) { got.emplace_back(l); }, [](const std::string&) {});
    link->send("M115\n");
    REQUIRE(rig.run_until([&] { return !got.empty() && got.back() == "ok"; }, 5));
    CHECK(got.front().rfind("FIRMWARE_NAME:", 0) == 0);
    link->close();

    ServeConfig c;
    c.port = "sim";
    c.pty.clear();
    c.tcp = "0.0.0.0:0";
    asio::io_context io;
    Assembly a;
    CHECK_THROWS_WITH_AS(assemble(io, c, rig.machine, a), doctest::Contains("allow_remote"), IoError);
}

TEST_CASE("the shipped configuration loads with its documented defaults; a broken one names file, line and key") {
    const auto dir = std::filesystem::path(XLATE5_MACHINE_DIR_FOR_TESTS).parent_path();
    const auto c = load_serve_config((dir / "config" / "xlate5.toml").string());
    const ServeConfig defaults;
    CHECK(c.machine == defaults.machine);
    CHECK(c.port == defaults.port);
    CHECK(c.baud == defaults.baud);
    CHECK(c.firmware.max_line == defaults.firmware.max_line);
    CHECK(c.firmware.reply_timeout == defaults.firmware.reply_timeout);
    CHECK(c.firmware.settle == defaults.firmware.settle);
    CHECK(c.firmware.nudge == defaults.firmware.nudge);
    CHECK(c.queue_lines == defaults.queue_lines);
    CHECK(c.pty == defaults.pty);

    TempDir tmp;
    const auto write = [&](const std::string& text) {
        const auto p = (tmp.path / "bad.toml").string();
        FILE* f = std::fopen(p.c_str(), "w");
        std::fputs(text.c_str(), f);
        std::fclose(f);
        return p;
    };
    CHECK_THROWS_WITH_AS(load_serve_config(write("machine = \"rw2\"\n[firmware]\nbaud = \"fast\"\n")),
                         doctest::Contains("bad.toml:3: firmware.baud: expected a whole number"), MachineError);
    CHECK_THROWS_WITH_AS(load_serve_config(write("[sender]\nqueue = 5\n")), doctest::Contains("bad.toml:2: sender.queue: unknown setting"),
                         MachineError);
    CHECK_THROWS_WITH_AS(load_serve_config(write("[sim.faults]\ncorupt = 0.1\n")), doctest::Contains("sim.faults.corupt"), MachineError);
    CHECK_THROWS_WITH_AS(load_serve_config(write("[firmware\n")), doctest::Contains("bad.toml:1:"), MachineError);
    CHECK_THROWS_WITH_AS(load_serve_config(write("machine = \"rw2\"\nmode = \"G44\"\n")), doctest::Contains("bad.toml:2: mode: expected"), MachineError);
    const auto v = load_serve_config(write("mode = \"G43.5\"\nextruder_letter = \"a\"\n"));
    CHECK(v.mode == OrientationMode::Vector);
    CHECK(v.extruder_letter == 'A');
}


TEST_CASE("a refused line leaves nothing behind: later lines print as if it never came (look-back on)") {
    // "F0" is refused while the move runs, after the interpreter took the line apart: the
    // translator's state, and what its emitter remembers of the firmware, must be as before it.
    std::vector<std::string> good = {"G28", "G92 A-168", "G1 A0 B0 F3000", "M83", "G0 X100 Y100 Z10 A0 B0 F1200"};
    for (int i = 1; i <= 40; ++i) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "G1 X%.1f Y100 Z10 A%.1f B0 E0.02", 100 + 0.5 * i, 0.5 * (i % 7));
        good.emplace_back(buf);
    }
    std::vector<std::string> with_bad = good;
    with_bad.insert(with_bad.begin() + 20, "G1 X95 Y101 Z10 A3 B2 F0");     // refused: F must be positive
    with_bad.insert(with_bad.begin() + 30, "G1 X95 Y101 Z10 A3 B2 E-1 Q4");  // refused: Q is not a word of rw2
    Rig rig("rw2");
    REQUIRE(rig.ready());
    const auto expected = offline(rig.machine, good);
    TestSender sender(rig.io, rig.config.pty, /*numbered=*/false);  // typed: refused, and the print goes on
    sender.stream(with_bad);
    REQUIRE(rig.run_until([&] { return sender.done() && rig.service().idle(); }, 30));
    CHECK(rig.service().stats().rejected == 2);
    CHECK(rig.service().stop_reason().empty());
    CHECK(rig.executed_after_hello() == expected);
}

TEST_CASE("M73 progress from the sender passes through to the firmware in its place") {
    auto lines = rw2_print(200);
    lines.insert(lines.begin() + 6, "M73 P0 R12");
    lines.insert(lines.begin() + 100, "M73 P50 R6");
    lines.emplace_back("M73 P100 R0");
    Rig rig("rw2");
    stream_and_compare(rig, lines, 30);
    const auto executed = rig.executed_after_hello();
    for (const char* m : {"M73 P0 R12", "M73 P50 R6", "M73 P100 R0"}) CHECK(std::count(executed.begin(), executed.end(), m) == 1);
    const auto at = [&](const char* m) { return std::find(executed.begin(), executed.end(), m) - executed.begin(); };
    CHECK(at("M73 P0 R12") < at("M73 P50 R6"));
    CHECK(at("M73 P100 R0") == std::ptrdiff_t(executed.size()) - 1);
}

TEST_CASE("output is held only while a look-back window is open: a print whose last window closed is done without hold_seconds") {
    // rw2_print's travel move at line 5 opens a window of 2000 lines; 2100 moves close it, so
    // nothing is undecided at the end. Ending on a travel move and a few printing moves leaves a
    // window open: that output waits for hold_seconds of silence, as before.
    const auto run = [](const std::vector<std::string>& lines) {
        Rig rig("rw2", [](ServeConfig& c) { c.hold_seconds = 4; });
        REQUIRE(rig.ready());
        TestSender sender(rig.io, rig.config.pty, true);
        sender.stream(lines);
        REQUIRE(rig.run_until([&] { return sender.done(); }, 120));
        const auto t0 = std::chrono::steady_clock::now();
        REQUIRE(rig.run_until([&] { return rig.service().idle(); }, 20));
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        CHECK(rig.executed_after_hello() == offline(rig.machine, lines));
        return s;
    };
    auto lines = rw2_print(2100);
    CHECK(run(lines) < 2.5);  // draining the last lines; held output would take hold_seconds (4)
    lines.push_back("G1 X110 Y110 Z20 A10 B5");  // a travel move: a new window opens
    for (int i = 0; i < 5; ++i) lines.push_back("G1 X" + std::to_string(111 + i) + " Y110 Z20 A10 B5 E0.02");
    CHECK(run(lines) >= 3.5);
}
