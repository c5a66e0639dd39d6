#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""End to end: `xlate5 serve` with its virtual printer, a real sender streaming a tool-space file
into its pseudo-terminal, SIGTERM (drain), then the commands the printer executed compared with
the offline translation of the same file (`xlate5 --machine M -i FILE`). Nothing may be lost,
duplicated or reordered.

Usage: service_e2e.py XLATE5 MACHINE FILE printcore|bare [extra serve flags...]
"""
import os
import signal
import subprocess
import sys
import tempfile
import time

from common import sim_config, start_serve, strip

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    xlate5, machine, path, sender = sys.argv[1:5]
    extra = sys.argv[5:]
    with tempfile.TemporaryDirectory(prefix="xlate5-e2e-") as tmp:
        pty = os.path.join(tmp, "printer")
        record = os.path.join(tmp, "executed.gcode")
        log = open(os.path.join(tmp, "serve.log"), "w+")
        config = sim_config(tmp, machine, record)
        serve = start_serve(xlate5, ["--config", config, *extra], pty, log)
        try:
            result = subprocess.run(["/usr/bin/python3", os.path.join(HERE, "senders.py"), sender, pty, path],
                                    capture_output=True, text=True, timeout=900)
            print(result.stdout.strip())
            if result.returncode != 0:
                print(result.stderr[-3000:])
                raise SystemExit("the sender failed")
            # Idle now: SIGHUP re-reads the configuration.
            serve.send_signal(signal.SIGHUP)
            deadline = time.time() + 10
            while True:
                log.seek(0)
                if "SIGHUP: reloaded" in log.read():
                    break
                if time.time() > deadline:
                    raise SystemExit("SIGHUP did not reload the configuration")
                time.sleep(0.05)
        finally:
            serve.send_signal(signal.SIGTERM)
            code = serve.wait(timeout=120)
        log.seek(0)
        if code != 0:
            raise SystemExit("xlate5 serve exited with %d:\n%s" % (code, log.read()))
        offline = subprocess.run([xlate5, "--machine", machine, "-i", path], capture_output=True, text=True, check=True).stdout
        expected = [c for c in (strip(l) for l in offline.splitlines()) if c]
        with open(record) as f:
            executed = [l.rstrip("\n") for l in f]
        # xlate5's own greeting (M110, M115) and the senders' temperature polls are not part
        # of the file.
        executed = [c for c in executed if c not in ("M115", "M105") and not c.startswith("M110 ")]
        if executed[:1] == ["M114"]:  # the service asks where the machine is, once greeted
            executed = executed[1:]
        expected = [c for c in expected if c != "M105"]
        if executed != expected:
            for i, (a, b) in enumerate(zip(executed, expected)):
                if a != b:
                    raise SystemExit("command %d: executed '%s', offline '%s'" % (i, a, b))
            raise SystemExit("executed %d commands, offline translation has %d" % (len(executed), len(expected)))
        print("%s: %d commands executed, identical to the offline translation" % (sender, len(executed)))


if __name__ == "__main__":
    main()
