# SPDX-License-Identifier: GPL-3.0-or-later
# Cura post-processing script: the sliced G-code through xlate5 into joint space.
#
# Install: copy this file into the "scripts" folder of Cura's configuration folder (Help > Show
# Configuration Folder), restart Cura, then Extensions > Post Processing > Modify G-Code > Add a
# script > "xlate5: joint space". Cura hands the G-code over as a list of pieces (the header,
# the start code, one piece per layer, the end code) and takes the list back. xlate5 needs the
# whole stream (a move is translated knowing the ones before it), so the pieces are joined with
# a marker comment between them, translated as one file, and cut again at the markers: the
# list goes back with as many pieces as it came, each layer its own, so scripts after this one
# (pause at height, layer-by-layer edits) still find their layers. If xlate5 refuses the file
# (a move it cannot reach, a file already translated), the error is raised, Cura reports it,
# and no G-code is written.
import subprocess

from ..Script import Script


class Xlate5(Script):
    def getSettingDataString(self):
        return """{
            "name": "xlate5: joint space",
            "key": "Xlate5",
            "metadata": {},
            "version": 2,
            "settings": {
                "machine": {
                    "label": "Machine",
                    "description": "xlate5 machine name (see 'xlate5 machines') or path to its .toml",
                    "type": "str",
                    "default_value": "rw2"
                },
                "program": {
                    "label": "xlate5 program",
                    "description": "the xlate5 executable",
                    "type": "str",
                    "default_value": "xlate5"
                }
            }
        }"""

    # A comment xlate5 passes through in its place; the number keeps a marker in a piece's own
    # text from being taken for one.
    MARK = ";xlate5-cura-piece "

    def execute(self, data):
        parts = []
        for i, piece in enumerate(data):
            if i:
                parts.append(self.MARK + str(i) + "\n")
            parts.append(piece if piece.endswith("\n") or not piece else piece + "\n")
        result = subprocess.run(
            [self.getSettingValueByKey("program"), "--machine", self.getSettingValueByKey("machine"), "--no-progress"],
            input="".join(parts), capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeError("xlate5 refused the G-code: " + result.stderr.strip())
        pieces, current, expected = [], [], 1
        for line in result.stdout.splitlines(keepends=True):
            if line.rstrip("\r\n") == self.MARK + str(expected):
                pieces.append("".join(current))
                current, expected = [], expected + 1
            else:
                current.append(line)
        pieces.append("".join(current))
        if len(pieces) != len(data):
            raise RuntimeError("xlate5's output has %d pieces for Cura's %d" % (len(pieces), len(data)))
        return pieces
