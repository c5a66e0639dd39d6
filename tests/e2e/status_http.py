#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""`xlate5 serve --http`: the read-only status endpoint as its users see it.

A real HTTP client (Python's urllib, and raw sockets for what a client library will not send)
reads /status.json while a numbered, checksummed sender prints through the pseudo-terminal; the
joints it reports are checked against `xlate5 pose` (forward kinematics by another path) and its
tip against the programmed one; every method but GET and HEAD is refused and changes nothing;
oversized requests and too many connections are bounded; the page, in headless Chromium, shows
the same figures. Chromium's part is skipped (and says so) when chromium is not installed.

Usage: status_http.py XLATE5 MACHINES_DIR
"""
import http.client
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
import urllib.error
import urllib.request

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def checksum(s):
    cs = 0
    for b in s.encode():
        cs ^= b
    return cs


class Sender:
    """Numbered lines with checksums, one at a time, as OctoPrint and Printrun send them."""

    def __init__(self, path):
        import termios
        import tty

        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        self.n = 0
        self.replies = []
        self.pending = b""

    def readline(self, timeout=20):
        import select

        deadline = time.time() + timeout
        while b"\n" not in self.pending:
            left = deadline - time.time()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                return ""
            self.pending += os.read(self.fd, 4096)
        line, self.pending = self.pending.split(b"\n", 1)
        return line.decode(errors="replace").strip()

    def send(self, command, numbered=True):
        if numbered:
            self.n += 1
            body = "N%d %s" % (self.n, command)
            line = "%s*%d\n" % (body, checksum(body))
        else:
            line = command + "\n"
        os.write(self.fd, line.encode())
        while True:
            reply = self.readline()
            if not reply:
                raise SystemExit("sender: no ok for " + command)
            self.replies.append(reply)
            if reply.startswith("ok"):
                return

    def close(self):
        os.close(self.fd)


def get(url, timeout=10):
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, dict(r.headers), r.read().decode()


def status(base):
    code, headers, body = get(base + "status.json")
    check(code == 200, "GET /status.json: %d" % code)
    check(headers.get("Content-Type") == "application/json", "status.json's type: %s" % headers.get("Content-Type"))
    return json.loads(body)


def raw(base, data, timeout=10):
    """Sends bytes as they are; returns what comes back until the server closes (or times out)."""
    host, port = re.match(r"http://([^:/]+):(\d+)/", base).groups()
    s = socket.create_connection((host, int(port)), timeout=timeout)
    try:
        s.sendall(data)
        got = b""
        while True:
            try:
                chunk = s.recv(65536)
            except (socket.timeout, ConnectionResetError):
                break
            if not chunk:
                break
            got += chunk
        return got.decode(errors="replace")
    finally:
        s.close()


def main():
    xlate5, machines = sys.argv[1:3]
    with open(os.path.join(machines, "rw2.toml"), "rb") as f:
        letters = [j.get("output", j["name"]) for j in tomllib.load(f)["joints"]]
    with tempfile.TemporaryDirectory(prefix="xlate5-http-") as tmp:
        pty = os.path.join(tmp, "printer")
        log = open(os.path.join(tmp, "serve.log"), "w+")
        env = dict(os.environ, XLATE5_MACHINES=machines)
        env.pop("JOURNAL_STREAM", None)
        serve = subprocess.Popen([xlate5, "serve", "-m", "rw2", "--printer", "sim", "--pty", pty, "--boot-wait", "0.2",
                                  "--http", "127.0.0.1:0"], stderr=log, env=env)
        try:
            base = None
            deadline = time.time() + 20
            while time.time() < deadline and (base is None or not os.path.exists(pty)):
                log.seek(0)
                m = re.search(r"status: (http://127\.0\.0\.1:\d+/) and", log.read())
                base = m.group(1) if m else None
                time.sleep(0.1)
            if base is None or not os.path.exists(pty):
                log.seek(0)
                raise SystemExit("serve did not start:\n" + log.read())
            log.seek(0)
            text = log.read()
            check("WITHOUT authentication" in text, "the log does not say the status page has no authentication")

            # Before any sender: idle, the machine's joints in the firmware's order at home.
            s = status(base)
            check(s["machine"] == "rw2", "machine: %s" % s["machine"])
            check(s["authentication"] == "none", "authentication: %s" % s["authentication"])
            check(s["print"]["sender"] == "" and s["print"]["line"] is None, "a sender before any: %s" % s["print"])
            check(list(s["position"]["joints"].keys()) == letters, "joints %s, the machine file's %s" % (list(s["position"]["joints"]), letters))
            # Greeted, then its own M114: never "printing" before a sender sends anything.
            deadline = time.time() + 10
            seen = set()
            while (s["firmware"]["state"] != "ready" or s["state"] != "idle") and time.time() < deadline:
                seen.add(s["state"])
                time.sleep(0.1)
                s = status(base)
            check(seen <= {"starting", "idle", "reading position"}, "states before a sender: %s" % sorted(seen))
            check(s["state"] == "idle" and s["firmware"]["state"] == "ready", "state at start: %s / %s" % (s["state"], s["firmware"]["state"]))

            # A sender prints three numbered lines; M400 returns once the firmware ran them.
            sender = Sender(pty)
            sender.send("M110 N0", numbered=False)
            sender.send("G28")
            sender.send("G1 X10 Y20 Z5 A30 B10 F600")
            sender.send("M400")
            s = status(base)
            p = s["print"]
            check(p["sender"] == "pty " + pty, "sender: %s" % p["sender"])
            check(p["line"] == 3, "line: %s" % p["line"])
            check(p["lines_from_senders"] == 3, "lines from senders: %s" % p["lines_from_senders"])
            check(p["lines_to_firmware"] >= 3, "lines to the firmware: %s" % p["lines_to_firmware"])
            check(s["firmware"]["acked"] >= 3, "acknowledged: %s" % s["firmware"]["acked"])
            tip = s["position"]["tip"]
            check(all(abs(a - b) < 1e-6 for a, b in zip(tip, [10, 20, 5])), "tip %s, programmed 10 20 5" % tip)
            # The reported joints through forward kinematics by another path: `xlate5 pose`.
            joints = s["position"]["joints"]
            out = subprocess.run([xlate5, "--machine", "rw2", "pose"] + ["%s=%.6f" % (k, v) for k, v in joints.items()],
                                 capture_output=True, text=True, env=env, check=True).stdout
            fk = [float(x) for x in re.search(r"tip\s+X=(\S+) Y=(\S+) Z=(\S+)", out).groups()]
            axis = [float(x) for x in re.search(r"axis\s+I=(\S+) J=(\S+) K=(\S+)", out).groups()]
            check(all(abs(a - b) < 1e-3 for a, b in zip(fk, tip)), "pose of the reported joints %s, reported tip %s" % (fk, tip))
            check(all(abs(a - b) < 1e-5 for a, b in zip(axis, s["position"]["axis"])), "pose's axis %s, reported %s" % (axis, s["position"]["axis"]))

            # A refused line: counted and shown as the last error.
            sender.send("G1 X0 Y..2", numbered=False)
            s = status(base)
            check(s["print"]["refused"] == 1, "refused: %s" % s["print"]["refused"])
            check("G1 X0 Y..2" in s["last_error"], "last error: %r" % s["last_error"])

            # Nothing changes anything: every other method is refused, the state stays.
            before = status(base)
            for method in ["POST", "PUT", "DELETE", "PATCH"]:
                for path in ["/status.json", "/", "/stop"]:
                    c = http.client.HTTPConnection(*re.match(r"http://([^:/]+):(\d+)/", base).groups(), timeout=10)
                    c.request(method, path, body="M112\n")
                    r = c.getresponse()
                    r.read()
                    check(r.status == 405, "%s %s: %d" % (method, path, r.status))
                    check(r.getheader("Allow") == "GET, HEAD", "%s %s: Allow %s" % (method, path, r.getheader("Allow")))
                    c.close()
            after = status(base)
            check(after["state"] == before["state"] and after["print"] == before["print"] and after["firmware"]["sent"] == before["firmware"]["sent"],
                  "a refused request changed the state: %s -> %s" % (before, after))
            try:
                get(base + "nothing-here")
                check(False, "GET /nothing-here was not 404")
            except urllib.error.HTTPError as e:
                check(e.code == 404, "GET /nothing-here: %d" % e.code)
            req = urllib.request.Request(base + "status.json", method="HEAD")
            with urllib.request.urlopen(req, timeout=10) as r:
                check(r.status == 200 and r.read() == b"" and int(r.headers["Content-Length"]) > 100, "HEAD /status.json")

            # Bounds: headers past 8 KiB are 431; a body is not taken; a ninth connection at once 503.
            big = "GET /status.json HTTP/1.1\r\nHost: x\r\nX-Big: " + "a" * 9000 + "\r\n\r\n"
            check(raw(base, big.encode()).startswith("HTTP/1.1 431"), "headers past the limit were not 431")
            post = "POST /status.json HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n" + "M112\n" * 100
            check(raw(base, post.encode()).startswith("HTTP/1.1 413"), "a large body was not 413")
            host, port = re.match(r"http://([^:/]+):(\d+)/", base).groups()
            idle = [socket.create_connection((host, int(port)), timeout=10) for _ in range(8)]
            time.sleep(0.3)
            ninth = raw(base, b"GET /status.json HTTP/1.1\r\nHost: x\r\n\r\n", timeout=5)
            check(ninth.startswith("HTTP/1.1 503"), "a ninth connection was not 503: %r" % ninth[:40])
            for c in idle:
                c.close()
            time.sleep(0.3)
            check(status(base)["machine"] == "rw2", "no answer once the idle connections closed")

            # The page in headless Chromium shows the JSON's figures.
            chromium = shutil.which("chromium")
            if chromium:
                dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                                      "--virtual-time-budget=3000", "--dump-dom", base], capture_output=True, text=True, timeout=120).stdout
                s = status(base)
                cell = lambda i: (re.search(r'id="%s">([^<]*)<' % i, dom) or re.search("()", "")).group(1)
                check(cell("machine") == "rw2", "page: machine %r" % cell("machine"))
                check(cell("state") == s["state"], "page: state %r, JSON %r" % (cell("state"), s["state"]))
                check(cell("line") == "pty %s, line 3" % pty, "page: printing %r" % cell("line"))
                want = "%d from senders, %d to the firmware, 1 refused" % (s["print"]["lines_from_senders"], s["print"]["lines_to_firmware"])
                check(cell("lines") == want, "page: lines %r, JSON %r" % (cell("lines"), want))
                check(cell("tip") == "10.000 20.000 5.000", "page: tip %r" % cell("tip"))
                check(cell("joints").startswith("X %.3f" % s["position"]["joints"]["X"]), "page: joints %r" % cell("joints"))
                check("G1 X0 Y..2" in cell("error"), "page: last error %r" % cell("error"))
                check("no authentication" in dom, "the page does not say it has no authentication")
            else:
                print("chromium not installed: the page's part is skipped")
            sender.close()
        finally:
            serve.terminate()
            code = serve.wait(timeout=60)
            check(code == 0, "serve exit code %d" % code)

        # Not on another address unless asked: the page has no authentication.
        r = subprocess.run([xlate5, "serve", "-m", "rw2", "--printer", "sim", "--no-pty", "--tcp", "127.0.0.1:0", "--http", "0.0.0.0:0"],
                           capture_output=True, text=True, env=env, timeout=60)
        check(r.returncode == 4 and "not a loopback address" in r.stderr and "allow_remote" in r.stderr,
              "--http 0.0.0.0:0 without --allow-remote: %d %s" % (r.returncode, r.stderr))
    if failures:
        raise SystemExit("%d failures" % len(failures))
    print("status endpoint: JSON, page, refusals and bounds ok")


if __name__ == "__main__":
    main()
