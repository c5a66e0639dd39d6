#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The --preview page of a bundled example in a real browser (headless Chromium, WebGL on
SwiftShader): translates the example with --preview and --report, loads the page opened at the
written line of its worst deviation, and checks the scene the page describes in its DOM against
references taken apart from the page: the written file (its move lines, the joints at that line,
the moves whose feed drives a joint at its max_feed, recomputed here from the machine file and
the firmware's length rule), the report's counts, and `xlate5 pose` (forward kinematics) for the
tip the page posed the machine at. Saves a screenshot of the page as a test artefact.

usage: preview_e2e.py XLATE5 SOURCE_DIR ARTEFACT_DIR NAME MACHINE INPUT [ARGS...]
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def chromium_run(chromium, profile, args, url):
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
           "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
           "--window-size=1300,1400", "--user-data-dir=" + profile] + args + [url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300)


def words(line):
    """The letter -> number words of a written line, up to its comment."""
    out = {}
    for w in line.split(";")[0].split()[1:]:
        try:
            out[w[0]] = float(w[1:])
        except ValueError:
            pass
    return out


def main():
    xlate5, source, artefacts, name, machine, input_file = sys.argv[1:7]
    extra = sys.argv[7:]
    chromium = shutil.which("chromium")
    work = tempfile.mkdtemp(prefix="xlate5-preview-")
    out, page, report = (os.path.join(work, f) for f in ("out.gcode", "page.html", "report.json"))
    run = subprocess.run([xlate5, "--machine", machine, "-i", os.path.join(source, input_file), "-o", out, "--preview", page,
                          "--report", report] + [a.replace("@SOURCE@", source) for a in extra], capture_output=True, text=True)
    check(run.returncode == 0, f"{name}: xlate5 translates it ({run.stderr.strip()[-300:]})")
    if run.returncode != 0:
        return 1
    rep = json.load(open(report))
    html = open(page, encoding="utf-8").read()
    data = json.loads(re.search(r'<script type="application/json" id="data">(.*?)</script>', html, re.S).group(1))

    # The machine, from its file: each joint's output letter, kind, home and max_feed.
    spec = tomllib.load(open(os.path.join(source, "machines", machine + ".toml"), "rb"))
    joints = [{"name": j["name"], "out": j.get("output", j["name"]), "rotary": j.get("type") == "rotary",
               "home": j.get("home", 0), "max_feed": j.get("max_feed", 0)} for j in spec["joints"]]
    dialect = spec.get("firmware", {}).get("dialect", "marlin")
    inverse_time = spec.get("firmware", {}).get("inverse_time", False)

    # The written file replayed: joints after every line, move lines, moves at a joint's max_feed
    # (the written feed over the dialect's length: XYZ when a linear joint moves, else the
    # rotaries'; Marlin's articulated rule every axis; Klipper's the largest rotary).
    q = [j["home"] for j in joints]
    at_line, moves, slowed, feed = {}, 0, 0, 0.0
    lines = open(out).read().split("\n")
    for number, line in enumerate(lines, 1):
        if line.startswith("G28") and (len(line) == 3 or line[3] in " ;"):
            named = [k for k, j in enumerate(joints) if j["out"] in line[3:].split(";")[0]]
            for k in named or range(len(joints)):
                q[k] = joints[k]["home"]
            continue
        move = line.startswith("G0 ") or line.startswith("G1 ")
        if not move and not line.startswith("G92 "):
            continue
        w, before = words(line), list(q)
        for k, j in enumerate(joints):
            if j["out"] in w:
                q[k] = w[j["out"]]
        if not move:
            continue
        feed = w.get("F", feed)
        moves += 1
        at_line[number] = list(q)
        lin = sum((q[k] - before[k]) ** 2 for k, j in enumerate(joints) if not j["rotary"])
        rot = [abs(q[k] - before[k]) for k, j in enumerate(joints) if j["rotary"]]
        if dialect == "marlin-articulated":
            length = math.sqrt(lin + sum(r * r for r in rot))
        elif lin > 0:
            length = math.sqrt(lin)
        else:
            length = max(rot, default=0) if dialect == "klipper" else math.sqrt(sum(r * r for r in rot))
        if not inverse_time and feed > 0 and length > 0 and any(
                isinstance(j["max_feed"], (int, float)) and j["max_feed"] > 0 and
                abs(q[k] - before[k]) * feed / length >= 0.995 * j["max_feed"] for k, j in enumerate(joints)):
            slowed += 1

    counts = data["counts"]
    check(counts["moves_written"] == moves == rep["move_lines_written"],
          f"{name}: written move lines: file {moves}, page {counts['moves_written']}, report {rep['move_lines_written']}")
    check(counts["output_moves"] == rep["output_moves"], f"{name}: translated moves: page {counts['output_moves']}, report {rep['output_moves']}")
    check(counts["slowed"] == slowed == rep["moves_at_joint_max_feed"],
          f"{name}: moves at a joint's max_feed: file {slowed}, page {counts['slowed']}, report {rep['moves_at_joint_max_feed']}")
    for kind, key in (("pole", "pole_crossings"), ("unwind", "unwinds"), ("branch", "branch_changes"), ("rezero", "rezeros")):
        check(counts[kind] == rep[key], f"{name}: {key}: page {counts[kind]}, report {rep[key]}")

    # Where a person goes first: the printed kept move of the worst deviation.
    n = len(data["q"])
    printed_moves = [i for i in range(n) if data["pose"][i][7]] or list(range(n))
    worst = max(printed_moves, key=lambda i: data["pose"][i][8]) if n else 0
    line_no = data["line"][worst] if n else 0
    if chromium is None:
        print(f"{name}: skipping the browser checks: chromium is not installed (Debian package chromium)")
        return 1 if failures else 0
    profile = os.path.join(work, "profile")
    dom = chromium_run(chromium, profile, ["--dump-dom"], "file://" + page + "#line=" + str(line_no)).stdout
    m = re.search(r'<pre id="summary"[^>]*>(.*?)</pre>', dom, re.S)
    check(m is not None and "(drawn)</title>" in dom, f"{name}: the page's script ran to its end")
    if m is None:
        return 1
    s = json.loads(m.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&"))
    check(s["webgl"], f"{name}: WebGL is drawn (three.js r{s['three']})")
    check(s["points"] == n and 0 < n <= 4000 and (n == moves or moves > 4000), f"{name}: {s['points']} points of {moves} moves shown")
    prints = sum(1 for i in range(1, n) if data["pose"][i][7])
    check((s["printed_segments"] >= prints) and (prints > 0), f"{name}: {s['printed_segments']} printed segments for {prints} printed moves")
    check(s["bodies"] == len(data["bodies"]) >= 3, f"{name}: {s['bodies']} machine bodies drawn")
    for kind in ("pole", "unwind", "branch", "rezero", "slowed"):
        check(s["marks"][kind] == counts[kind], f"{name}: page's {kind} count is the report's ({counts[kind]})")
        listed = len([k for k in data["marks" if kind != "slowed" else "slowed"] if k[0] == kind])
        check(s["listed"].get(kind, 0) == listed, f"{name}: {listed} {kind} marks listed and clickable")
    check(sum(s["listed"].get(k, 0) for k in ("pole", "unwind", "branch", "rezero")) == min(
        2000, rep["pole_crossings"] + rep["unwinds"] + rep["branch_changes"] + rep["rezeros"]), f"{name}: every report mark listed (up to 2000)")
    check(dom.count('data-kind="') == len(data["marks"]), f"{name}: the report's marks in the DOM")
    ranges = [[r["first_line"], r["last_line"]] for r in rep["preflight"]["drain_ranges"]]
    check(data["drains"] == ranges and s["listed"]["drains"] == len(ranges) == dom.count('data-link="drain"'),
          f"{name}: the {len(ranges)} line ranges where the link drains the planner, listed as the report has them")

    # The scrubber at that line: the joints written there, and the tip forward kinematics gives.
    sc = s["scrubber"]
    check(sc["line"] == line_no and line_no in at_line, f"{name}: the scrubber stands at output line {line_no}")
    ref = at_line.get(line_no, [])
    check(len(ref) == len(sc["joints"]) and all(abs(a - b) < 1e-9 for a, b in zip(ref, sc["joints"])),
          f"{name}: joints at line {line_no}: page {sc['joints']}, file {ref}")
    pose = subprocess.run([xlate5, "pose", "--machine", machine] + [f"{j['name']}={v}" for j, v in zip(joints, ref)],
                          capture_output=True, text=True)
    tip = [float(v) for v in re.search(r"tip\s+X=(\S+) Y=(\S+) Z=(\S+)", pose.stdout).groups()]
    check(all(abs(a - b) < 2e-4 for a, b in zip(tip, sc["tip"])), f"{name}: tip posed {sc['tip']}, xlate5 pose {tip}")

    # The screenshot, kept in the build tree.
    os.makedirs(artefacts, exist_ok=True)
    png = os.path.join(artefacts, name + ".png")
    if os.path.exists(png):
        os.remove(png)
    chromium_run(chromium, profile + "2", ["--screenshot=" + png], "file://" + page + "#line=" + str(line_no))
    check(os.path.exists(png) and os.path.getsize(png) > 30000, f"{name}: screenshot {png} ({os.path.getsize(png) if os.path.exists(png) else 0} bytes)")
    shutil.rmtree(work, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
