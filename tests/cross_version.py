# SPDX-License-Identifier: GPL-3.0-or-later
"""A .blend saved by one Blender and opened by another keeps every piece of Myoskin state (ctest
blender-cross.*): made in A, opened and re-saved in B, opened again in A; the state read each time (muscles,
settings, bind record, joint bones, vertex groups, locators) must be identical.

    python3 tests/cross_version.py --a LABEL_A SCRIPTS_A CMD_A... --b LABEL_B SCRIPTS_B CMD_B...

CMD is the command that runs a Blender script the way ctest runs the Blender tier (ending in --python).
"""
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "blender", "blend_state.py")


def split(argv):
    a = argv[argv.index("--a") + 1:argv.index("--b")]
    b = argv[argv.index("--b") + 1:]
    return (a[0], a[1], a[2:]), (b[0], b[1], b[2:])


def state(flavour, *args):
    label, scripts, cmd = flavour
    env = dict(os.environ, BLENDER_USER_SCRIPTS=scripts)
    done = subprocess.run(cmd + [SCRIPT, "--", *args], capture_output=True, text=True, timeout=600, env=env)
    log = done.stdout + done.stderr
    lines = [line for line in done.stdout.splitlines() if line.startswith("state: ")]
    if done.returncode != 0 or len(lines) != 1:
        sys.exit(f"FAIL {label} {' '.join(args)} (exit {done.returncode}):\n{log}")
    return json.loads(lines[0][len("state: "):])


def diff(x, y, path=""):
    """The first difference between two summaries (floats to 1e-6), or None."""
    if isinstance(x, dict) and isinstance(y, dict):
        for k in sorted(set(x) | set(y)):
            d = diff(x.get(k), y.get(k), f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(x, list) and isinstance(y, list):
        if len(x) != len(y):
            return f"{path}: {len(x)} items against {len(y)}"
        return next((d for d in (diff(p, q, f"{path}[{i}]") for i, (p, q) in enumerate(zip(x, y))) if d), None)
    if isinstance(x, float) and isinstance(y, float):
        return None if abs(x - y) <= 1e-6 * max(1.0, abs(x)) else f"{path}: {x} against {y}"
    return None if x == y else f"{path}: {x!r} against {y!r}"


def main(argv):
    a, b = split(argv)
    tmp = tempfile.mkdtemp(prefix="myoskin_cross_")
    first, second, third = (os.path.join(tmp, f"{n}.blend") for n in ("a", "b", "c"))
    made = state(a, "make", first)
    assert made["muscles"] and made["bound"] and made["joint_bones"], "nothing to compare"
    failed = 0
    for flavour, step, args in ((b, f"{a[0]} -> {b[0]}", ("resave", first, second)),
                                (a, f"{a[0]} -> {b[0]} -> {a[0]}", ("resave", second, third))):
        d = diff(made, state(flavour, *args))
        print(f"{'FAIL' if d else 'PASS'} {step}: {len(made['muscles'])} muscles, "
              f"{len(made['joint_bones'])} joint bones{': ' + d if d else ''}", flush=True)
        failed += bool(d)
    print(f"{2 - failed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
