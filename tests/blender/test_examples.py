# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: the main job (examples/demo.py, what `./myoskin.sh demo` runs) in its own Blender of the
same kind, at a tiny render size: it exits 0 and writes the .blend, the JSONs and both renders.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_examples.py
"""
import json
import os
import subprocess
import sys
import tempfile

SOURCE = os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "tests", "blender"))
import blender_test_runner as runner  # noqa: E402


def test_demo_writes_its_outputs():
    out = tempfile.mkdtemp(prefix="myoskin_test_demo_")
    cmd = runner.blender_command("--addons", runner.ADDON, "--python-exit-code", "1", "--python",
                                 os.path.join(SOURCE, "examples", "demo.py"), "--", "--output", out,
                                 "--samples", "1", "--resolution", "64", "36")
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=dict(os.environ))
    log = done.stdout + done.stderr
    assert done.returncode == 0 and "Traceback" not in log, log
    for name in ("myoskin_demo.blend", "muscles.json", "truth.json", "render_rest.png", "render_posed.png"):
        path = os.path.join(out, name)
        assert os.path.isfile(path) and os.path.getsize(path) > 0, f"{name} missing:\n{log}"
    with open(os.path.join(out, "muscles.json"), encoding="utf-8") as f:
        assert len(json.load(f)["muscles"]) >= 4


runner.run()
