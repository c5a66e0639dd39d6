#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
# Issue 31's "done when" table: every corpus file on every bundled machine, translated as a user
# would (the machine's own start mode, default tolerances, --report), with per pair whether it
# was refused (and why, in short), the tip and tool-axis deviation as written (the report's
# largest, measured on the joints as printed), the rotary travel against the report's lower
# bound (planner.cpp: bound_rotary_travel) and the printing moves that turn a rotary more than
# 90 degrees. Then each bundled example on the machine its name starts with, and the
# S3-DeformFDM ring read back to tool space through its machine and translated again, against
# the authors' own rotary travel (as tests/test_pole.cpp does).
#
#   bench/rotation_table.py [BUILD_DIR=build] [CORPUS_DIR=../shared/corpus] [MACHINE ...]
#
# Prints a Markdown table on standard output. Slow on the big planar files (each run is a full
# translation): about a minute for all of it on the shared 2-core machine.
import json
import os
import re
import subprocess
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(here)
build = sys.argv[1] if len(sys.argv) > 1 else "build"
corpus = sys.argv[2] if len(sys.argv) > 2 else os.path.join(root, "..", "shared", "corpus")
xlate5 = os.path.join(build if os.path.isabs(build) else os.path.join(root, build), "cli", "xlate5")
machines = sys.argv[3:] or sorted(f[:-5] for f in os.listdir(os.path.join(root, "machines")) if f.endswith(".toml"))
files = sorted(
    os.path.join(d, f)
    for d in (os.path.join(corpus, s) for s in sorted(os.listdir(corpus)))
    if os.path.isdir(d)
    for f in os.listdir(d)
    if os.path.isfile(os.path.join(d, f))
)


def cause(message):
    """The refusal's kind, in a few words."""
    m = message
    if re.search(r"is not a (joint|tool-space word) |rotary word . under G43.5", m):
        return "n/a: written for other joints (%s)" % re.sub(r"^.*?:\d+:\d+: ", "", m)[:48]
    if re.search(r"joint [XYZUVW] would go to .* outside its limits -0\.001 \.\. 0\.001", m):
        return "tool axis out of the machine's reach (its absent joint)"
    if re.search(r"joint [XYZUVW] would go to .* outside its limits", m):
        return "placement (a linear joint out of travel)"
    if "out of this machine's reach" in m:
        return "tool axis out of the machine's reach"
    if "would run past its limit" in m:
        return "rotary limit"
    if "passes a pole" in m:
        return "pole"
    if "not a number" in m or "unknown" in m or "not supported" in m or "cannot" in m:
        return "input: " + re.sub(r"^.*?:\d+:\d+: ", "", m)[:60]
    return re.sub(r"^.*?:\d+:\d+: ", "", m)[:70]


def translate(machine, path, tmp, extra=()):
    report = os.path.join(tmp, "r.json")
    if os.path.exists(report):
        os.remove(report)
    run = subprocess.run([xlate5, "-m", machine, "-i", path, "-o", os.path.join(tmp, "out.gcode"), "--report", report,
                          "--no-progress", *extra], capture_output=True, text=True)
    if run.returncode != 0:
        # The refusal, past any notes (a retargeted park held at the limits).
        first = ([l for l in run.stderr.strip().splitlines() if ": note: " not in l] or ["?"])[0]
        line = re.search(r":(\d+):\d+:", first)
        return None, "refused at line %s: %s" % (line.group(1) if line else "?", cause(first))
    with open(report) as f:
        return json.load(f), None


def row(name, machine, r, err, theirs=None):
    if err:
        return "| %s | %s | %s | | | | | | |" % (name, machine, err)
    total = r.get("rotary_travel_total_deg")
    bound = r.get("rotary_travel_lower_bound_deg")
    ratio = r.get("rotary_travel_ratio")
    travel = "%.0f" % total if total is not None else "(%s)" % ", ".join(
        "%s %.0f" % kv for kv in r.get("rotary_travel_deg", {}).items()) if r.get("rotary_travel_deg") else ""
    if not r.get("moves"):
        travel = "(no tool-space move: joint space passed on)"
    if theirs is not None:
        travel += " (theirs %.0f)" % theirs
    return "| %s | %s | 0 | %.4f | %.3f | %s | %s | %s | %d |" % (
        name, machine, r["tip_deviation_mm"]["max"], r["orientation_deviation_deg"]["max"], travel,
        "%.0f" % bound if bound is not None else "", "%.3f" % ratio if ratio is not None else "",
        r["printing_moves_turning_over_90_deg"])


print("| file | machine | refusals | tip mm (max) | axis deg (max) | rotary travel deg | lower bound deg | ratio | printing moves turning > 90 deg |")
print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
with tempfile.TemporaryDirectory() as tmp:
    for path in files:
        name = os.path.relpath(path, corpus)
        # The ring drives its extruder as A (as scripts/compare-outputs.sh runs it).
        extra = ("--extruder-letter", "A") if name.endswith("ring_Gcode.txt") else ()
        for m in machines:
            r, err = translate(m, path, tmp, extra)
            print(row(name, m, r, err), flush=True)
    # The bundled examples, each on the machine its name starts with (they are written for it).
    examples = os.path.join(root, "examples")
    for f in sorted(os.listdir(examples)):
        m = f.split("_")[0]
        if f.endswith(".gcode") and m in machines:
            r, err = translate(m, os.path.join(examples, f), tmp)
            print(row("examples/" + f, m, r, err), flush=True)
    # The ring: the authors' joint-space output for their B-C table, read back to tool space
    # through machines/s3deformfdm.toml (extruder on A), then translated again.
    ring = os.path.join(corpus, "s3deformfdm", "ring_Gcode.txt")
    if os.path.exists(ring) and "s3deformfdm" in machines:
        theirs, last = 0.0, {}
        with open(ring) as f:
            for line in f:
                if not line.startswith("G1 "):
                    continue
                for ax in "BC":
                    w = re.search(r"\b%s(-?[0-9.]+)" % ax, line)
                    if w:
                        v = float(w.group(1))
                        if ax in last:
                            theirs += abs(v - last[ax])
                        last[ax] = v
        tool = os.path.join(tmp, "ring_tool.gcode")
        back = subprocess.run([xlate5, "-m", "s3deformfdm", "--inverse", "--extruder-letter", "A", "--preview-form", "G43.5",
                               "-i", ring, "-o", tool, "--no-progress"], capture_output=True, text=True)
        if back.returncode != 0:
            print("| ring, read back | s3deformfdm | inverse refused: %s | | | | | | |" % back.stderr.strip()[:80])
        else:
            r, err = translate("s3deformfdm", tool, tmp, ("--mode", "G43.5"))
            print(row("s3deformfdm/ring_Gcode.txt, read back to tool space", "s3deformfdm", r, err, theirs))
    # Retargeting (--from): each joint-space corpus file onto the machines named here, placed
    # with --place where its own origin lies outside that machine's travel (README, --from).
    s4 = os.path.join(corpus, "s4", "pi_3mm_side_paint_rtheta.gcode")
    for path, source, extra, target, place in (
            (ring, "s3deformfdm", ("--extruder-letter", "A"), "koc5", None),
            (ring, "s3deformfdm", ("--extruder-letter", "A"), "rw2", None),
            (ring, "s3deformfdm", ("--extruder-letter", "A"), "rw2", "120,120,0"),
            (ring, "s3deformfdm", ("--extruder-letter", "A"), "core-rtheta", None),
            (s4, "core-rtheta", (), "core-rtheta", None),
            (s4, "core-rtheta", (), "pentarod", None),
            (s4, "core-rtheta", (), "voron-xyzac", None),
            (s4, "core-rtheta", (), "voron-xyzac", "0,0,0.3")):
        if not os.path.exists(path) or target not in machines:
            continue
        args = ("--from", source) + extra + (("--place", place) if place else ())
        r, err = translate(target, path, tmp, args)
        name = "%s --from %s%s" % (os.path.relpath(path, corpus), source, " --place " + place if place else "")
        print(row(name, target, r, err))
