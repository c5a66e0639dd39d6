#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The Cura post-processing script (examples/cura/Xlate5.py) as Cura runs it: loaded as a module
of a package that provides Cura's `Script` base class (a stand-in with the same two methods the
script calls), given a real Cura file cut into Cura's pieces (the header, one piece per layer
from each ";LAYER:" line), and asked to translate them. The pieces must come back as many as they
went, each layer its own and starting with its own ";LAYER:" line, and together exactly what
xlate5 makes of the whole file.

Usage: cura_script.py XLATE5 SCRIPT CORPUS_DIR
"""
import os
import shutil
import subprocess
import sys
import tempfile

xlate5, script, corpus = sys.argv[1:4]
source = os.path.join(corpus, "planar", "pi_3mm_deformed_tet_cura-5.8.0.gcode")
if not os.path.exists(source):
    print("skipping the Cura script test: the corpus file %s is absent" % source)
    sys.exit(0)

with open(source, newline="") as f:
    text = f.read()
pieces, current = [], []
for line in text.splitlines(keepends=True):
    if line.startswith(";LAYER:") and current:
        pieces.append("".join(current))
        current = []
    current.append(line)
pieces.append("".join(current))
assert len(pieces) > 100, len(pieces)

with tempfile.TemporaryDirectory(prefix="xlate5-cura-") as tmp:
    pkg = os.path.join(tmp, "curastub")
    os.makedirs(os.path.join(pkg, "scripts"))
    open(os.path.join(pkg, "__init__.py"), "w").close()
    open(os.path.join(pkg, "scripts", "__init__.py"), "w").close()
    with open(os.path.join(pkg, "Script.py"), "w") as f:
        f.write("class Script:\n"
                "    settings = {}\n"
                "    def getSettingValueByKey(self, key):\n"
                "        return self.settings[key]\n")
    shutil.copy(script, os.path.join(pkg, "scripts", "Xlate5.py"))
    sys.path.insert(0, tmp)
    from curastub.scripts.Xlate5 import Xlate5

    s = Xlate5()
    s.settings = {"machine": "rw2", "program": xlate5}
    out = s.execute(list(pieces))

    whole = subprocess.run([xlate5, "--machine", "rw2", "--no-progress"], input=text, capture_output=True, text=True, check=True).stdout
    failures = []
    if len(out) != len(pieces):
        failures.append("%d pieces back for %d" % (len(out), len(pieces)))
    else:
        for k in range(1, len(pieces)):
            layer = pieces[k].split("\n", 1)[0]
            if not out[k].startswith(layer + "\n"):
                failures.append("piece %d starts %r, not its layer %r" % (k, out[k][:30], layer))
                break
    if "".join(out) != whole:
        failures.append("the pieces together differ from xlate5's translation of the whole file")
    if "xlate5-cura-piece" in "".join(out):
        failures.append("a marker was left in the output")
    # A refusal reaches Cura as an exception, with xlate5's message.
    try:
        s.execute(["G1 X0 Y..2\n"])
        failures.append("a refused file raised nothing")
    except RuntimeError as e:
        if "xlate5 refused the G-code" not in str(e):
            failures.append("refusal: %s" % e)
    if failures:
        for f in failures:
            print("FAIL:", f, file=sys.stderr)
        sys.exit(1)
    print("Cura script: %d pieces back, each layer its own, together the whole translation" % len(out))
