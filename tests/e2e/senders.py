#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Real senders for the end-to-end test: Printrun's printcore (numbered, checksummed, ping-pong,
replays from Resend), and a bare ping-pong sender without line numbers, as cncjs sends.

Usage: senders.py printcore|bare PORT FILE
Prints one JSON line: lines sent, errors, seconds.
"""
import json
import sys
import time


def run_printcore(port, lines):
    from printrun import gcoder
    from printrun.printcore import printcore

    errors = []
    p = printcore()
    p.errorcb = errors.append
    p.connect(port, 115200)
    deadline = time.time() + 30
    while not p.online:
        if time.time() > deadline:
            raise SystemExit("printcore: xlate5 never came online")
        time.sleep(0.05)
    p.startprint(gcoder.LightGCode(lines))
    deadline = time.time() + 600
    while p.printing:
        if time.time() > deadline:
            raise SystemExit("printcore: the print did not finish")
        time.sleep(0.05)
    p.disconnect()
    return len(lines), errors


def run_bare(port, lines):
    import serial

    errors = []
    s = serial.Serial(port, 115200, timeout=30)
    sent = 0
    for line in lines:
        command = line.split(";", 1)[0].strip()
        if not command:
            continue
        s.write((command + "\n").encode())
        sent += 1
        while True:
            reply = s.readline().decode(errors="replace").strip()
            if not reply:
                raise SystemExit("bare sender: no ok for " + command)
            if reply.startswith("Error"):
                errors.append(reply)
            if reply.startswith("ok"):
                break
    s.close()
    return sent, errors


def main():
    mode, port, path = sys.argv[1:4]
    with open(path) as f:
        lines = [l.rstrip("\r\n") for l in f]
    t0 = time.time()
    sent, errors = (run_printcore if mode == "printcore" else run_bare)(port, lines)
    print(json.dumps({"sender": mode, "sent": sent, "errors": errors, "seconds": round(time.time() - t0, 3)}))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
