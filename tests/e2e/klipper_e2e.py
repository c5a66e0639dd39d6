#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""End to end with Klipper: `xlate5 serve --flavor klipper` in front of the virtual printer's
Klipper personality (klippy's pseudo-terminal rules, daemon/virtual_klipper.cpp), a real sender
(Printrun's printcore) streaming a tool-space file into serve's pseudo-terminal, then the commands
the Klipper double ran compared with the offline translation for the same machine written with
`dialect = "klipper"`: every line ran exactly once, in order. The double's moves wait for a full
toolhead queue (move_ms), so oks come late, as Klipper's do.

Usage: klipper_e2e.py XLATE5 MACHINE_TOML FILE
"""
import os
import re
import signal
import subprocess
import sys
import tempfile

from common import start_serve, strip

HERE = os.path.dirname(os.path.abspath(__file__))


def print_through_serve(xlate5, machine, tmp, name, path, sim_extra, timeout):
    """printcore streams `path` through `xlate5 serve --flavor klipper` to the Klipper double,
    which records what it ran in TMP/NAME.executed. Returns (sender's result, serve's exit code,
    serve's log, the record's path)."""
    pty = os.path.join(tmp, name + ".pty")
    record = os.path.join(tmp, name + ".executed")
    log = open(os.path.join(tmp, name + ".log"), "w+")
    config = os.path.join(tmp, name + ".toml")
    with open(config, "w") as f:
        f.write('machine = "%s"\n[firmware]\nport = "sim"\nflavor = "klipper"\nboot_wait = 0.2\n'
                '[sim]\nflavor = "klipper"\nrecord = "%s"\n%s' % (machine, record, sim_extra))
    serve = start_serve(xlate5, ["--config", config], pty, log)
    try:
        result = subprocess.run(["/usr/bin/python3", os.path.join(HERE, "senders.py"), "printcore", pty, path],
                                capture_output=True, text=True, timeout=timeout)
    finally:
        serve.send_signal(signal.SIGTERM)
        code = serve.wait(timeout=120)
    log.seek(0)
    return result, code, log.read(), record


def refused(xlate5, machine, tmp):
    """Klipper refuses a move ("!! Must home axis first": this file has no G28): serve stops the
    print there, names the line to the sender and its log, and sends nothing more: without that,
    the G28 behind it would home and the moves after it run. What was already in flight when the
    "!!" came (here the G28) still runs: Klipper does not stop at an error (docs/firmware.md)."""
    path = os.path.join(tmp, "unhomed.gcode")
    with open(path, "w") as f:
        f.write("G90\nG1 X10 Y10 Z250 F600\nG28\nG1 X20 Y10 Z250\nG1 X30 Y10 Z250\n")
    result, _, served, record = print_through_serve(xlate5, machine, tmp, "refused", path, "", 120)
    out = result.stdout + result.stderr
    if "Klipper refused 'G1" not in served or "Must home axis first" not in served:
        raise SystemExit("serve did not stop at Klipper's refusal:\n" + served)
    if "Klipper refused" not in out:
        raise SystemExit("the sender was not told which line Klipper refused:\n" + out)
    with open(record) as f:
        moves = [l for l in f if l.startswith("G1")]
    if moves:
        raise SystemExit("moves ran after Klipper refused one: %s" % moves)
    print("klipper: the refused move stopped the print, named to the sender; no move ran after it")


def main():
    xlate5, machine_toml, path = sys.argv[1:4]
    with tempfile.TemporaryDirectory(prefix="xlate5-klipper-") as tmp:
        machine = os.path.join(tmp, "rw2k.toml")
        with open(machine_toml) as f:
            text = f.read()
        text, n = re.subn(r'(?m)^dialect = "\w+"', 'dialect = "klipper"', text)
        assert n == 1, "the machine file names no dialect"
        with open(machine, "w") as f:
            f.write(text)
        result, code, served, record = print_through_serve(xlate5, machine, tmp, "print", path,
                                                           "planner = 8\n[sim.faults]\nmove_ms = 2\n", 900)
        print(result.stdout.strip())
        if result.returncode != 0:
            print(result.stderr[-3000:])
            print(served[-3000:])
            raise SystemExit("the sender failed")
        if code != 0:
            raise SystemExit("xlate5 serve exited with %d:\n%s" % (code, served))
        if "firmware ready: FIRMWARE_NAME:Klipper" not in served:
            raise SystemExit("serve did not greet the Klipper double:\n" + served)
        # Its position question went as GET_POSITION and came back with the extra axes, which
        # Klipper's M114 leaves out (the preamble registered them first).
        m = re.search(r"position: the firmware reports (.*)", served)
        if not m or " A:" not in m.group(1) or " B:" not in m.group(1):
            raise SystemExit("serve did not read the position with A and B:\n" + served)
        offline = subprocess.run([xlate5, "--machine", machine, "-i", path], capture_output=True, text=True, check=True).stdout
        expected = [c for c in (strip(l) for l in offline.splitlines()) if c and c != "M105"]
        with open(record) as f:
            executed = [l.rstrip("\n") for l in f]
        # xlate5's own greeting (M115, STATUS), its position question (GET_POSITION, for the
        # sender's or its own M114) and the sender's temperature polls are not part of the file.
        executed = [c for c in executed if c not in ("M115", "STATUS", "GET_POSITION", "M105")]
        if executed != expected:
            for i, (a, b) in enumerate(zip(executed, expected)):
                if a != b:
                    raise SystemExit("command %d: executed '%s', offline '%s'" % (i, a, b))
            raise SystemExit("executed %d commands, offline translation has %d" % (len(executed), len(expected)))
        if not any(c.startswith("MANUAL_STEPPER STEPPER=axis_a GCODE_AXIS=A") for c in executed):
            raise SystemExit("the extra axes were never registered with Klipper")
        print("klipper: %d commands executed once each, in order, identical to the offline translation" % len(executed))
        refused(xlate5, machine, tmp)


if __name__ == "__main__":
    main()
