# SPDX-License-Identifier: GPL-3.0-or-later
"""What the end-to-end scripts (tests/e2e/) and the soak (bench/soak.py) share: starting
`xlate5 serve` on a pseudo-terminal, its configuration for the virtual printer, and the comment
stripping that executed commands are compared with."""
import os
import subprocess
import time


def strip(line):
    """A G-code line without its comments (';' to the end, '( ... )') and surrounding blanks."""
    line = line.split(";", 1)[0]
    out, depth = [], 0
    for ch in line:
        if ch == "(":
            depth += 1
        elif ch == ")" and depth:
            depth -= 1
        elif not depth:
            out.append(ch)
    return "".join(out).strip()


def sim_config(tmp, machine, record, extra=""):
    """A configuration file in TMP: MACHINE on the virtual printer, which records what it
    executes in RECORD; EXTRA is appended (TOML). Returns its path."""
    config = os.path.join(tmp, "printer.toml")
    with open(config, "w") as f:
        f.write('machine = "%s"\n[firmware]\nport = "sim"\nboot_wait = 0.2\n[sim]\nrecord = "%s"\n' % (machine, record) + extra)
    return config


def start_serve(xlate5, args, pty, log, seconds=20):
    """Starts `xlate5 serve ARGS --pty PTY`, its log to the open file LOG, and waits until the
    pseudo-terminal is there; if it is not within SECONDS, or serve exits, stops with its log."""
    serve = subprocess.Popen([xlate5, "serve", *args, "--pty", pty], stderr=log)
    deadline = time.time() + seconds
    while not os.path.exists(pty):
        if time.time() > deadline or serve.poll() is not None:
            log.seek(0)
            raise SystemExit("xlate5 serve did not start:\n" + log.read())
        time.sleep(0.05)
    return serve
