#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""End to end with a real sender (Printrun's printcore) against `xlate5 serve` and its virtual
printer: the service's two guarantees (docs/service.md).

  jog:      a sender homes and places the tool, leaves; a second sender asks M114 and jogs as
            OctoPrint's buttons do (G91, G1 X10, G90). The tip must move 10 mm in X from where the
            first left it, nothing else (b1037f8 sent Z to 300: the translator started from home).
  too-long: after a travel move, two printing moves, an M23 whose line no firmware buffer holds,
            and one more move. The M23 must be refused naming itself, the two moves before it must
            run and the one after it must not (b1037f8 dropped the acknowledged X60 and ran X65).
  double-sigterm: a second SIGTERM stops between lines and logs how many acknowledged lines never ran.

What ran is read from the virtual printer's record and taken back to tool space with
`xlate5 --inverse`, an independent path through the machine's forward kinematics.

Usage: position_e2e.py XLATE5 jog|too-long|double-sigterm
"""
import os
import signal
import subprocess
import sys
import tempfile
import time

from printrun import gcoder
from printrun.printcore import printcore

import common


def start_serve(xlate5, tmp, extra_config=""):
    pty = os.path.join(tmp, "printer")
    record = os.path.join(tmp, "executed.gcode")
    log = open(os.path.join(tmp, "serve.log"), "w+")
    config = common.sim_config(tmp, "rw2", record, "[sender]\nhold_seconds = 0.3\n" + extra_config)
    return common.start_serve(xlate5, ["--config", config], pty, log), pty, record, log


def connect(pty):
    received = []
    p = printcore()
    p.recvcb = lambda line: received.append(line.strip())
    p.connect(pty, 115200)
    deadline = time.time() + 30
    while not p.online:
        if time.time() > deadline:
            raise SystemExit("printcore: xlate5 never came online")
        time.sleep(0.05)
    return p, received


def print_lines(p, lines):
    p.startprint(gcoder.LightGCode(lines))
    deadline = time.time() + 60
    while p.printing:
        if time.time() > deadline:
            raise SystemExit("printcore: the print did not finish")
        time.sleep(0.05)


def send_and_wait(p, received, command, until, seconds=20):
    """send_now, as OctoPrint's terminal and jog buttons do; waits for a reply that satisfies `until`."""
    start = len(received)
    p.send_now(command)
    deadline = time.time() + seconds
    while not any(until(r) for r in received[start:]):
        if time.time() > deadline:
            raise SystemExit("no answer to %s; received %r" % (command, received[start:]))
        time.sleep(0.02)
    return received[start:]


def stop(serve, log):
    serve.send_signal(signal.SIGTERM)
    code = serve.wait(timeout=120)
    if code != 0:
        log.seek(0)
        raise SystemExit("xlate5 serve exited with %d:\n%s" % (code, log.read()))


def tool_space_moves(xlate5, record):
    """Each executed move's tip (X, Y, Z), through `xlate5 --inverse` (modal words carried)."""
    out = subprocess.run([xlate5, "--machine", "rw2", "--inverse", "-i", record], capture_output=True, text=True, check=True).stdout
    pos, moves = {}, []
    for line in out.splitlines():
        words = line.split(";", 1)[0].split()
        if not words or words[0] not in ("G0", "G1"):
            continue
        for w in words[1:]:
            if w[0] in "XYZE":
                pos[w[0]] = float(w[1:])
        moves.append((pos.get("X"), pos.get("Y"), pos.get("Z"), "E" in "".join(words[1:])))
    return moves


def near(a, b):
    return all(abs(x - y) < 0.02 for x, y in zip(a, b))


def jog(xlate5, tmp):
    serve, pty, record, log = start_serve(xlate5, tmp)
    try:
        p1, _ = connect(pty)
        print_lines(p1, ["G28", "G92 A-168", "G1 A0 B0 F3000", "G1 X50 Y50 Z10 A0 B0 F3000"])
        p1.disconnect()
        p2, received = connect(pty)
        replies = send_and_wait(p2, received, "M114", lambda r: r.startswith("X:"))
        report = [r for r in replies if r.startswith("X:")][0]
        if not report.startswith("X:50.00 Y:50.00 Z:10.00"):
            raise SystemExit("M114 after the reconnect: " + report)
        for c in ("G91", "G1 X10 F6000", "G90"):
            send_and_wait(p2, received, c, lambda r: r.startswith("ok"))
        send_and_wait(p2, received, "M400", lambda r: r.startswith("ok"))
        p2.disconnect()
    finally:
        stop(serve, log)
    moves = tool_space_moves(xlate5, record)
    last = moves[-1][:3]
    if not near(last, (60, 50, 10)):
        raise SystemExit("the jog ended at %r, not at X60 Y50 Z10" % (last,))
    highest = max(m[2] for m in moves[moves.index(next(m for m in moves if near(m[:3], (50, 50, 10)))):])
    if highest > 10.02:
        raise SystemExit("the jog rose to Z %.2f" % highest)
    print("jog: M114 '%s', then the tip went from X50 to X%.2f at Z%.2f" % (report, last[0], last[2]))


def too_long(xlate5, tmp):
    serve, pty, record, log = start_serve(xlate5, tmp)
    name = "M23 " + "a" * 87 + ".gco"  # 95 characters: no room for a line number and checksum
    lines = ["G28", "G92 A-168", "G1 A0 B0 F3000", "M83", "G0 X50 Y50 Z5 F3000",
             "G1 X55 Y50 Z5 E1 F1200", "G1 X60 Y50 Z5 E1", name, "G1 X65 Y50 Z5 E1"]
    try:
        p, received = connect(pty)
        print_lines(p, lines)
        time.sleep(0.5)
        p.disconnect()
    finally:
        stop(serve, log)
    cancelled = [r for r in received if r.startswith("echo:xlate5: print cancelled at")]
    if not cancelled or "'M23 " not in cancelled[0] or "line buffer" not in cancelled[0]:
        raise SystemExit("the M23 was not refused naming itself: %r" % received)
    if any(r.startswith("Error") for r in received):
        raise SystemExit("an Error: reached the sender (OctoPrint would send M112): %r" % received)
    printed = [m[0] for m in tool_space_moves(xlate5, record) if m[3]]
    if not any(abs(x - 55) < 0.02 for x in printed) or not any(abs(x - 60) < 0.02 for x in printed):
        raise SystemExit("an acknowledged move did not run: printed at X %r" % printed)
    if any(x > 60.02 for x in printed):
        raise SystemExit("a move after the refused line ran: printed at X %r" % printed)
    print("too-long: %s; the moves before it ran (X %s), none after it" % (cancelled[0][:60], ", ".join("%.0f" % x for x in printed)))


def double_sigterm(xlate5, tmp):
    """A second SIGTERM stops at once: the log says how many acknowledged lines never ran."""
    serve, pty, record, log = start_serve(xlate5, tmp, "[sim.faults]\nmove_ms = 300\n")
    lines = ["G28", "G92 A-168", "G1 A0 B0 F3000", "M83", "G1 X50 Y50 Z5 F1200"]
    lines += ["G1 X%.1f Y50 Z5 E0.1" % (50 + 0.5 * i) for i in range(1, 200)]
    p, received = connect(pty)
    p.startprint(gcoder.LightGCode(lines))
    deadline = time.time() + 30
    while sum(1 for r in received if r.startswith("ok")) < 40:
        if time.time() > deadline:
            raise SystemExit("the print never got going: %r" % received[-5:])
        time.sleep(0.05)
    serve.send_signal(signal.SIGTERM)
    time.sleep(0.3)
    serve.send_signal(signal.SIGTERM)
    serve.wait(timeout=60)
    p.disconnect()
    log.seek(0)
    text = log.read()
    import re
    m = re.search(r"second signal: stopping now, between lines: (\d+) acknowledged lines of the senders not executed", text)
    if not m or int(m.group(1)) == 0:
        raise SystemExit("the second SIGTERM did not say what was left:\n" + text[-2000:])
    print("double SIGTERM: %s acknowledged lines not executed, logged" % m.group(1))


def main():
    xlate5, case = sys.argv[1:3]
    with tempfile.TemporaryDirectory(prefix="xlate5-pos-") as tmp:
        {"jog": jog, "too-long": too_long, "double-sigterm": double_sigterm}[case](xlate5, tmp)


if __name__ == "__main__":
    main()
