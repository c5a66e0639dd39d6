#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The --preview page of a bundled example in a real browser (headless Chromium, WebGL on
SwiftShader): translates the example with --preview and --report, loads the page opened at the
written line of its worst deviation, and checks the scene the page describes in its DOM against
references taken apart from the page: the written file (its move lines, the joints at that line,
the moves whose feed drives a joint at its max_feed, recomputed here from the machine file and
the firmware's length rule), the report's counts, and `xlate5 pose` (forward kinematics) for the
tip the page posed the machine at. Saves a screenshot of the page as a test artefact.

With --test-bodies the machine gets the collision bodies of tests/bodies/MACHINE.toml (guesses
from its sources, as test_collide uses them) and three more on the base, far from the work: a
sphere, a capsule and a mesh (a UV sphere of TEST_MESH_TRIANGLES triangles, written here as binary
STL, more than the page's cap): the page must draw the machine's own bodies, every shape, the mesh
thinned to the cap, posed at the scrubber's line as `xlate5 pose` places the tip and tool axis.
With --test-collide the input gets COLLIDE[MACHINE]'s moves appended, which run the head into the
printed part and the bed: the run uses --collision warn, and the page's collision marks must be
the report's, body names and input lines in order, each clickable to its written move.

usage: preview_e2e.py XLATE5 SOURCE_DIR ARTEFACT_DIR NAME MACHINE INPUT [--test-bodies] [--test-collide] [ARGS...]
"""
import struct
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

TEST_MESH_TRIANGLES = 2 * 200 * 99  # a UV sphere of 200 x 100 facets (the poles' fans single)

# Moves appended to the bundled example (its tool-space dialect): lifted clear, the head tilted
# 60 degrees over the wall just printed and lowered into it; then tilted 85 degrees over the bed
# and lowered onto it (collisions: their ends meet what they meet); then, upright, down inside
# the wall and a travel out through it at Z 3 (re-routed: lifted over the wall).
COLLIDE = {"rw2": "G1 X110 Y100 Z20 A90 B60 F3000\nG1 Z4\nG1 Z20\nG1 X150 Y150 Z20 A0 B0\nG1 B85\nG1 Z3\nG1 Z20\n"
                  "G0 X110 Y110 Z20 A0 B0\nG0 Z3\nG0 X150 Y110 Z3\nG0 Z20\n"}


def sphere_stl(path, radius, nu=200, nv=100):
    """A UV sphere as binary STL: nu * (nv - 1) * 2 triangles (one per pole facet, two elsewhere)."""
    def at(i, j):
        t, p = math.pi * j / nv, 2 * math.pi * i / nu
        return (radius * math.sin(t) * math.cos(p), radius * math.sin(t) * math.sin(p), radius * math.cos(t))
    tris = []
    for j in range(nv):
        for i in range(nu):
            a, b, c, d = at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)
            if j > 0:
                tris.append((a, b, c))
            if j < nv - 1:
                tris.append((a, c, d))
    with open(path, "wb") as f:
        f.write(b"xlate5 test sphere".ljust(80, b" ") + struct.pack("<I", len(tris)))
        for t in tris:
            f.write(struct.pack("<12fH", 0, 0, 0, *t[0], *t[1], *t[2], 0))
    return len(tris)


def machine_with_bodies(source, work, machine):
    """machines/MACHINE.toml with tests/bodies/MACHINE.toml and three base bodies far from the work."""
    mesh = os.path.join(work, "sphere.stl")
    triangles = sphere_stl(mesh, 20)
    extra = (
        '\n[[bodies]]\nname = "test sphere"\nside = "part"\nafter = "base"\nshape = "sphere"\nradius = 10\ntranslate = [-400, 0, 0]\n'
        '\n[[bodies]]\nname = "test capsule"\nside = "part"\nafter = "base"\nshape = "capsule"\nradius = 5\nlength = 30\n'
        'translate = [-400, 60, 0]\nrotate = { axis = [1, 0, 0], angle = 90 }\n'
        '\n[[bodies]]\nname = "test mesh"\nside = "part"\nafter = "base"\nshape = "mesh"\nmesh = "sphere.stl"\ntranslate = [-400, -80, 0]\n')
    path = os.path.join(work, machine + "-bodies.toml")
    with open(path, "w") as f:
        f.write(open(os.path.join(source, "machines", machine + ".toml")).read() + "\n" +
                open(os.path.join(source, "tests", "bodies", machine + ".toml")).read() + extra)
    return path, triangles


def mat(rows):
    """A 3 x 4 matrix, row by row -> (rotation rows, translation)."""
    return [rows[0:3], rows[4:7], rows[8:11]], [rows[3], rows[7], rows[11]]


def check_bodies(name, data, s, tip, axis, tool_axis):
    """Every body as posed at the scrubber, against the tip and axis `xlate5 pose` gives there."""
    for posed, body in zip(s["posed"], data["bodies"]):
        R, c = mat(posed["part"])
        P, t = mat(body["pose"])
        if posed["frame"] == "tool":  # rigid with the tip: its place from the tip, its tool axis the pose's
            d = [c[k] - tip[k] for k in range(3)]
            along = sum(t[k] * tool_axis[k] for k in range(3))
            # The tool axis in the body's own frame, turned by the body's pose in the part frame.
            local = [sum(P[r][k] * tool_axis[r] for r in range(3)) for k in range(3)]
            turned = [sum(R[k][r] * local[r] for r in range(3)) for k in range(3)]
            ok = abs(math.dist(c, tip) - math.hypot(*t)) < 1e-3 and abs(sum(d[k] * axis[k] for k in range(3)) - along) < 1e-3 and \
                all(abs(turned[k] - axis[k]) < 1e-5 for k in range(3))
            check(ok, f"{name}: tool body '{body['name']}' at {[round(v, 3) for v in c]}: {math.hypot(*t):.3f} mm from the tip, "
                      f"{along:.3f} along the tool axis {axis}")
        elif posed["frame"] in ("part", "tool:0"):  # on the plate: fixed in the part frame; on the base: in the base frame
            got = posed["part"] if posed["frame"] == "part" else posed["base"]
            check(all(abs(a - b) < 1e-6 for a, b in zip(got, body["pose"])),
                  f"{name}: body '{body['name']}' on frame {posed['frame']} stays where the machine file puts it")


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


def fk(xlate5, machine, joints, q):
    """`xlate5 pose`'s tip and tool axis (part frame) at joints q."""
    pose = subprocess.run([xlate5, "pose", "--machine", machine] + [f"{j['name']}={v}" for j, v in zip(joints, q)],
                          capture_output=True, text=True)
    tip = [float(v) for v in re.search(r"tip\s+X=(\S+) Y=(\S+) Z=(\S+)", pose.stdout).groups()]
    axis = [float(v) for v in re.search(r"axis\s+I=(\S+) J=(\S+) K=(\S+)", pose.stdout).groups()]
    return tip, axis


def main():
    xlate5, source, artefacts, name, machine, input_file = sys.argv[1:7]
    extra = sys.argv[7:]
    chromium = shutil.which("chromium")
    work = tempfile.mkdtemp(prefix="xlate5-preview-")
    out, page, report = (os.path.join(work, f) for f in ("out.gcode", "page.html", "report.json"))
    bodies = "--test-bodies" in extra
    collide = "--test-collide" in extra
    extra = [a for a in extra if a not in ("--test-bodies", "--test-collide")]
    machine_arg, mesh_triangles = machine_with_bodies(source, work, machine) if bodies else (machine, 0)
    input_path = os.path.join(source, input_file)
    if collide:
        text = open(input_path).read()
        lift = text.rfind("\nG1 Z20")  # after the example's last lift, before its end
        cut = text.find("\n", lift + 1) + 1
        input_path = os.path.join(work, "input.gcode")
        with open(input_path, "w") as f:
            f.write(text[:cut] + COLLIDE[machine] + text[cut:])
    if bodies:
        extra = extra + ["--collision", "warn"]
    run = subprocess.run([xlate5, "--machine", machine_arg, "-i", input_path, "-o", out, "--preview", page,
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
    # One launch writes the DOM and the screenshot (kept in the build tree) of the same page.
    os.makedirs(artefacts, exist_ok=True)
    png = os.path.join(artefacts, name + ".png")
    if os.path.exists(png):
        os.remove(png)
    dom = chromium_run(chromium, profile, ["--dump-dom", "--screenshot=" + png], "file://" + page + "#line=" + str(line_no)).stdout
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
    check(len(html) < 8_000_000, f"{name}: the page is {len(html)} bytes")
    if bodies:
        own = tomllib.load(open(machine_arg, "rb"))["bodies"]
        check(data["own_bodies"] and s["body_source"] == "machine" and [b["name"] for b in data["bodies"]] == [b["name"] for b in own]
              and dom.count('data-body="') == len(own),
              f"{name}: the machine file's {len(own)} bodies drawn and listed, not the default")
        kinds = sorted({b["shape"] for b in own})
        check(sorted(s["shapes"]) == kinds and sum(s["shapes"].values()) == len(own), f"{name}: shapes drawn {s['shapes']} (the file's: {kinds})")
        mesh = next(b for b in data["bodies"] if b["name"] == "test mesh")
        xs = [mesh["vertices"][k::3] for k in range(3)]
        check(mesh["source_triangles"] == mesh_triangles > 20000 >= s["triangles"] == len(mesh["triangles"]) // 3 > 1000,
              f"{name}: the mesh's {mesh_triangles} triangles thinned to {s['triangles']} (the cap: 20000)")
        check(all(abs(max(x) - min(x) - 40) < 2 for x in xs), f"{name}: the thinned mesh keeps the sphere's 40 mm extent")
    else:
        check(not data["own_bodies"] and s["body_source"] == "default", f"{name}: default bodies from the chains")
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

    # Collisions: the report's, each a mark with its bodies and input line, in order.
    col = rep.get("collisions", {"count": 0, "list": []})
    check(s["marks"]["collision"] == counts["collisions"] == col["count"] and s["listed"]["collision"] == len(data["collisions"]) ==
          min(2000, col["count"]) == dom.count('data-collision="'), f"{name}: {col['count']} collisions: page {s['marks']['collision']}, "
          f"listed {s['listed']['collision']}")
    check([int(x.split(":")[0]) for x in col["list"]] == [c["line"] for c in data["collisions"]] and all(
        f"collision: {c['tool']} meets " + (f"printed part at line {c['bead_line']}" if c["other"] is None else c["other"]) in x
        for x, c in zip(col["list"], data["collisions"])), f"{name}: each collision's input line and bodies are the report's")
    if collide:
        check(col["count"] >= 2 and any(c["other"] is None for c in data["collisions"]) and any(c["other"] for c in data["collisions"]),
              f"{name}: the constructed moves meet the printed part and a body")
    # Re-routed travels: the report's, each a mark clickable to the detour's crossing.
    rr = rep.get("rerouted", {"count": 0, "list": []})
    check(s["marks"]["reroute"] == counts["reroutes"] == rr["count"] and s["listed"]["reroute"] == len(data["reroutes"]) ==
          min(2000, rr["count"]) == dom.count('data-reroute="'), f"{name}: {rr['count']} re-routed travels: page {s['marks']['reroute']}, "
          f"listed {s['listed']['reroute']}")
    check([int(x.split(":")[0]) for x in rr["list"]] == [c["line"] for c in data["reroutes"]] and all(
        f"travel re-routed, lifted " in x and f"{c['tool']} would meet " in x for x, c in zip(rr["list"], data["reroutes"])),
          f"{name}: each re-routed travel's input line and bodies are the report's")
    if collide:
        check(rr["count"] >= 1, f"{name}: the travel out through the wall is re-routed ({rr['count']})")
        # Its crossing, as written in the file (the mark's written move and the lift before it):
        # the tip above the wall (6 mm high) at both of its ends, by `xlate5 pose`.
        written = [at_line[number] for number in sorted(at_line)]
        for c in data["reroutes"]:
            tips = [fk(xlate5, machine, joints, written[k])[0] for k in (c["move"] - 1, c["move"]) if 0 <= k < len(written)]
            check(len(tips) == 2 and all(t[2] > 6 for t in tips), f"{name}: re-routed crossing at move {c['move']} lifted: tips {tips}")

    # The scrubber at that line: the joints written there, and the tip forward kinematics gives.
    sc = s["scrubber"]
    check(sc["line"] == line_no and line_no in at_line, f"{name}: the scrubber stands at output line {line_no}")
    ref = at_line.get(line_no, [])
    check(len(ref) == len(sc["joints"]) and all(abs(a - b) < 1e-9 for a, b in zip(ref, sc["joints"])),
          f"{name}: joints at line {line_no}: page {sc['joints']}, file {ref}")
    tip, axis = fk(xlate5, machine, joints, ref)
    check(all(abs(a - b) < 2e-4 for a, b in zip(tip, sc["tip"])), f"{name}: tip posed {sc['tip']}, xlate5 pose {tip}")
    tool_axis = spec.get("tool", {}).get("axis", [0, 0, 1])
    if bodies:
        check_bodies(name, data, s, tip, axis, tool_axis)
        # The first collision's button: the scrubber at its written move, the bodies posed there.
        dom = chromium_run(chromium, profile, ["--dump-dom"], "file://" + page + "#collision=0").stdout
        m = re.search(r'<pre id="summary"[^>]*>(.*?)</pre>', dom, re.S)
        if data["collisions"] and m:
            s2 = json.loads(m.group(1).replace("&quot;", '"').replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&"))
            c, sc = data["collisions"][0], s2["scrubber"]
            want = max((i for i in range(n) if data["move"][i] <= c["move"]), default=0)
            check(sc["index"] == want and (n != moves or sc["move"] == c["move"]),
                  f"{name}: the first collision's button puts the scrubber at written move {sc['move']} (the mark's: {c['move']})")
            ref = at_line.get(sc["line"], [])
            check(len(ref) == len(sc["joints"]) and all(abs(a - b) < 1e-9 for a, b in zip(ref, sc["joints"])),
                  f"{name}: joints at the collision's line {sc['line']}: page {sc['joints']}, file {ref}")
            tip, axis = fk(xlate5, machine, joints, ref)
            check(all(abs(a - b) < 2e-4 for a, b in zip(tip, sc["tip"])), f"{name}: tip at the collision {sc['tip']}, xlate5 pose {tip}")
            check_bodies(name + " at the collision", data, s2, tip, axis, tool_axis)

    check(os.path.exists(png) and os.path.getsize(png) > 30000, f"{name}: screenshot {png} ({os.path.getsize(png) if os.path.exists(png) else 0} bytes)")
    shutil.rmtree(work, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
