#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Soak: millions of lines through `xlate5 serve` and its virtual printer under faults (a bit
flipped in 1 % of the lines, a byte lost in 1 %, a firmware reset every so many commands),
with a sender that numbers its lines, follows Resend, restarts a print with M999 after
the reset, and disconnects and starts its numbering again (M110 N0) between prints. At the end, what the printer executed is compared with the offline
translation (`xlate5 --machine M -i FILE`): each print complete and identical, each print a
reset cut short a prefix of it. The service's resident memory is sampled every few seconds.
Figures only; not run in CI (docs/limits.md).

Usage: soak.py XLATE5 TOTAL_LINES [PRINT_LINES] [MACHINE]

Settings from the environment (defaults in brackets): SOAK_SETTLE [0.25] and SOAK_TIMEOUT [0.5],
the service's settle and reply_timeout in seconds; SOAK_CORRUPT [0.01] and SOAK_DROP [0.01],
the fault rates per line; SOAK_RESET_EVERY, commands between firmware resets [a third of the
run, at most 2,000,000, at least one and a half prints]; SOAK_NUDGE, the service's firmware.nudge [its default]; SOAK_SEED [5];
SOAK_MAX_SECONDS, no print started after it [none].
"""
import contextlib
import os
import random
import re
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import termios
import time
import tty

# The end-to-end tests' serve start-up and comment stripping: one rule for both.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "e2e"))
from common import start_serve, strip  # noqa: E402


def checksum(text):
    cs = 0
    for ch in text.encode():
        cs ^= ch
    return cs


def numbered(n, command):
    line = "N%d %s" % (n, command)
    return "%s*%d\n" % (line, checksum(line))


def make_print(moves, seed):
    """An rw2 print: start code, then short printing moves turning both rotaries, with a travel
    move every 200 moves (so the look-back holds and releases), fan commands between."""
    rng = random.Random(seed)
    lines = ["G28", "G92 A-168", "G1 A0 B0 F3000", "M83", "G1 X100 Y100 Z10 A0 B0 F1200"]
    x, y, z, a, b = 100.0, 100.0, 10.0, 0.0, 0.0
    for i in range(moves):
        x = min(140, max(60, x + rng.uniform(-0.8, 0.8)))
        y = min(140, max(60, y + rng.uniform(-0.8, 0.8)))
        z = min(60, max(5, z + 0.002))
        a = min(90, max(-90, a + rng.uniform(-1.5, 1.5)))
        b = min(30, max(-30, b + rng.uniform(-1.5, 1.5)))
        if i % 500 == 250:
            lines.append("M106 S%d" % (i % 255))
        elif i % 200 == 100 and not os.environ.get("SOAK_NO_TRAVEL"):
            lines.append("G0 X%.3f Y%.3f Z%.3f" % (x, y, z))
        else:
            lines.append("G1 X%.3f Y%.3f Z%.3f A%.2f B%.2f E%.4f" % (x, y, z, a, b, 0.02 + 0.001 * (i % 7)))
    return lines


class Sender:
    """Ping-pong like OctoPrint: one line in flight, Resend followed, M999 after a stop."""

    def __init__(self, path):
        self.path = path
        self.fd = None
        self.buf = b""

    def connect(self):
        self.fd = os.open(self.path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)

    def close(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
            self.buf = b""

    def write(self, text):
        data = text.encode()
        while data:
            n = os.write(self.fd, data)
            data = data[n:]

    def reply(self, timeout=60):
        end = time.time() + timeout
        while b"\n" not in self.buf:
            left = end - time.time()
            if left <= 0:
                raise SystemExit("soak: no reply from xlate5 for %d s" % timeout)
            r, _, _ = select.select([self.fd], [], [], left)
            if r:
                self.buf += os.read(self.fd, 65536)
        line, self.buf = self.buf.split(b"\n", 1)
        return line.decode(errors="replace").strip()

    def command(self, n, text):
        """Sends line n; returns ('ok', None), ('resend', k) or ('stopped', None)."""
        self.write(numbered(n, text))
        resend, stopped = None, False
        while True:
            r = self.reply()
            if r.startswith("ok"):
                if stopped:
                    return "stopped", None
                return ("resend", resend) if resend is not None else ("ok", None)
            m = re.match(r"(?:Resend:|rs)\s*(\d+)", r)
            if m:
                resend = int(m.group(1))
            elif r.startswith("Error:xlate5") or r.startswith("Error:Printer stopped") or "not run" in r:
                if os.environ.get("SOAK_DEBUG"):
                    print("soak: line %d: %s" % (n, r), file=sys.stderr)
                stopped = True


def stream(sender, lines):
    """One print from M110 N0; returns (True when every line was answered ok, lines written)."""
    n = sent = 0
    while sender.command(0, "M110 N0")[0] != "ok":
        pass
    i = 0
    while i < len(lines):
        n = i + 1
        what, k = sender.command(n, lines[i])
        sent += 1
        if what == "stopped":
            return False, sent
        if what == "resend":
            i = k - 1
            continue
        i += 1
    return True, sent


def rss_kib(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for l in f:
                if l.startswith("VmRSS:"):
                    return int(l.split()[1])
    except OSError:
        pass
    return None


@contextlib.contextmanager
def workdir():
    """A temporary directory, kept when the soak fails: its record and log are the evidence."""
    tmp = tempfile.mkdtemp(prefix="xlate5-soak-")
    try:
        yield tmp
    except BaseException:
        print("soak: its files are kept in %s" % tmp, file=sys.stderr, flush=True)
        raise
    shutil.rmtree(tmp, ignore_errors=True)


def setting(name, default, kind=float, low=0.0, high=None):
    """A number from the environment, range-checked."""
    text = os.environ.get(name)
    if text is None:
        return default
    try:
        v = kind(text)
    except ValueError:
        raise SystemExit("soak: %s=%r is not a number" % (name, text))
    if not (v >= low and (high is None or v <= high)):
        raise SystemExit("soak: %s=%r is outside [%s, %s]" % (name, text, low, high))
    return v


def main():
    settle = setting("SOAK_SETTLE", 0.25, float, 0.001, 60)
    reply_timeout = setting("SOAK_TIMEOUT", 0.5, float, 0.05, 600)
    corrupt = setting("SOAK_CORRUPT", 0.01, float, 0, 1)
    drop = setting("SOAK_DROP", 0.01, float, 0, 1)
    seed = setting("SOAK_SEED", 5, int, 0, 2**53)
    nudge = setting("SOAK_NUDGE", None, float, 0, 60)
    xlate5 = sys.argv[1]
    total = int(sys.argv[2])
    print_lines = int(sys.argv[3]) if len(sys.argv) > 3 else 100000
    machine = sys.argv[4] if len(sys.argv) > 4 else "rw2"
    prints = max(1, total // print_lines)
    with workdir() as tmp:
        program = make_print(print_lines - 5, 17)
        path = os.path.join(tmp, "print.gcode")
        with open(path, "w") as f:
            f.write("\n".join(program) + "\n")
        offline = subprocess.run([xlate5, "--machine", machine, "-i", path], capture_output=True, text=True, check=True).stdout
        expected = [c for c in (strip(l) for l in offline.splitlines()) if c and c != "M105"]
        pty = os.path.join(tmp, "printer")
        record = os.path.join(tmp, "executed.gcode")
        log = open(os.path.join(tmp, "serve.log"), "w+")
        # The virtual printer resets each time it has executed a multiple of this many commands;
        # each reset cuts one print short (it is streamed again from its start).
        # A print streamed again after a reset must fit before the next one: more than a print's
        # commands (and the greeting's and M999) between two resets.
        commands = prints * len(expected)
        fits = len(expected) + 16
        reset_every = setting("SOAK_RESET_EVERY", max(fits + len(expected) // 2, min(2000000, commands // 3)), int, fits, 2**53)
        knobs = ("settle %g s, reply_timeout %g s, nudge %s, corrupt %g, drop %g, a reset every %d commands, seed %d"
                 % (settle, reply_timeout, "default" if nudge is None else "%g s" % nudge, corrupt, drop, reset_every, seed))
        print("soak: %d lines in %d prints of %d on %s; %s" % (prints * print_lines, prints, print_lines, machine, knobs), flush=True)
        serve = start_serve(xlate5, ["--machine", machine, "--printer", "sim",
                                     "--record", record, "--reply-timeout", repr(reply_timeout), "--settle", repr(settle),
                                     "--boot-wait", "0.2",
                                     "--sim-fault", "corrupt=%r" % corrupt, "--sim-fault", "drop=%r" % drop,
                                     "--sim-fault", "reset_every=%d" % reset_every, "--sim-fault", "seed=%d" % seed,
                                     "--log-level", "warn"] + ([] if nudge is None else ["--nudge", repr(nudge)]), pty, log)
        samples = []
        start = time.time()
        try:
            sender = Sender(pty)
            sent = complete = cut = 0
            last_sample = 0
            p = 0
            # SOAK_MAX_SECONDS: no print is started after it (the comparison still runs).
            max_seconds = setting("SOAK_MAX_SECONDS", 1e12, float, 1, 1e12)
            while p < prints and time.time() - start < max_seconds:
                sender.connect()
                ok, n = stream(sender, program)
                sent += n
                if not ok:
                    # A stop other than a reset is a failure at once.
                    with open(log.name) as f:  # a reader of its own: the service shares `log`'s offset
                        other = [l for l in f.read().splitlines() if "print stopped:" in l and "restarted" not in l]
                    if other:
                        raise SystemExit("soak: FAILED: %s" % other[0])
                    # Each cut print is one reset; resets come with the commands executed (cut prints included).
                    if cut + 1 > (complete + cut + 1) * (len(expected) + 8) // reset_every + 1:
                        raise SystemExit("soak: FAILED: the print stopped %d times, with resets every %d of %d commands "
                                         "(the service's log says why)" % (cut + 1, reset_every, commands))
                    # The firmware reset: M999 (answered ok), then the print again from its start.
                    cut += 1
                    sender.write("M999\n")
                    while not sender.reply().startswith("ok"):
                        pass
                else:
                    complete += 1
                    p += 1
                sender.close()  # a sender that leaves between prints, as OctoPrint's disconnect
                now = time.time()
                if now - last_sample > 2:
                    samples.append((now - start, rss_kib(serve.pid)))
                    last_sample = now
                print("soak: %d lines sent, %d prints complete, %d cut by a reset, %.0f s, RSS %s KiB"
                      % (sent, complete, cut, now - start, rss_kib(serve.pid)), flush=True)
            samples.append((time.time() - start, rss_kib(serve.pid)))
        finally:
            serve.send_signal(signal.SIGTERM)
            code = serve.wait(timeout=300)
        elapsed = time.time() - start
        if code != 0:
            log.seek(0)
            raise SystemExit("xlate5 serve exited with %d:\n%s" % (code, log.read()[-3000:]))
        with open(record, "rb") as f:
            raw = f.read()
        if b"\0" in raw:
            at = raw.index(b"\0")
            raise SystemExit("the record file holds NUL bytes (the first at byte %d, after %r)" % (at, raw[max(0, at - 80):at]))
        # xlate5's own greeting (M110, M115), its question of where the machine is (M114), probes
        # (M105) and the M999 after the reset are not part of the print.
        own = ("M115", "M105", "M999") + (() if "M114" in expected else ("M114",))
        executed = [l for l in raw.decode().splitlines() if l not in own and not l.startswith("M110 ")]
        # Split at each print's first command (G28 appears once a print); compare each part.
        parts, cur = [], None
        for c in executed:
            if c == expected[0]:
                if cur is not None:
                    parts.append(cur)
                cur = []
            if cur is None:
                raise SystemExit("the record starts with '%s', not the print's first command" % c)
            cur.append(c)
        if cur is not None:
            parts.append(cur)
        whole = sum(1 for q in parts if q == expected)
        prefixes = sum(1 for q in parts if q != expected and q == expected[:len(q)])
        bad = [i for i, q in enumerate(parts) if q != expected[:len(q)]]
        rss = [s[1] for s in samples if s[1]]
        print("soak: %d lines sent in %.0f s (%.0f lines/s); %d prints identical to the offline translation "
              "(%d commands each), %d cut short by a firmware reset, each a prefix of it; %d wrong"
              % (sent, elapsed, sent / elapsed, whole, len(expected), prefixes, len(bad)))
        print("soak: " + knobs)
        if rss:
            print("soak: RSS of xlate5 serve: first %d KiB, min %d, max %d, last %d (%d samples)"
                  % (rss[0], min(rss), max(rss), rss[-1], len(rss)))
        log.seek(0)
        warnings = log.read()
        print("soak: service log: %d lines (resyncs, resets); %d reply timeouts"
              % (warnings.count("\n"), warnings.count("no reply for")))
        for i in bad[:3]:
            q = parts[i]
            j = next((k for k in range(min(len(q), len(expected))) if q[k] != expected[k]), min(len(q), len(expected)))
            print("soak: print %d differs at command %d: executed %r, offline %r" % (i, j, q[j] if j < len(q) else None,
                                                                                expected[j] if j < len(expected) else None))
        if bad or whole != complete:
            raise SystemExit("soak: FAILED (parts %s wrong, %d whole of %d complete)" % (bad[:5], whole, complete))


if __name__ == "__main__":
    main()
