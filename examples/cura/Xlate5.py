# Cura post-processing script: the sliced G-code through xlate5 into joint space.
#
# Install: copy this file into the "scripts" folder of Cura's configuration folder (Help > Show
# Configuration Folder), restart Cura, then Extensions > Post Processing > Modify G-Code > Add a
# script > "xlate5: joint space". Cura hands the G-code over as a list of layers and takes the
# list back; this script gives xlate5 the whole file on standard input and returns its output
# as one piece. If xlate5 refuses the file (a move it cannot reach, a file already translated),
# the error is raised, Cura reports it, and no G-code is written.
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

    def execute(self, data):
        text = "".join(layer if layer.endswith("\n") else layer + "\n" for layer in data)
        result = subprocess.run(
            [self.getSettingValueByKey("program"), "--machine", self.getSettingValueByKey("machine"), "--no-progress"],
            input=text, capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeError("xlate5 refused the G-code: " + result.stderr.strip())
        return [result.stdout]
