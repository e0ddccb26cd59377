# SPDX-License-Identifier: GPL-3.0-or-later
"""Run a Blender script under the `bpy` module (the official builds on the Python package index) the way
`blender -b --factory-startup --python-exit-code 1 --addons NAME --python SCRIPT -- ARGS` runs it:

    python bpy_main.py [FILE.blend] [-b] [--factory-startup] [--addons A,B] [--python-exit-code N]
                       (--python|-P) SCRIPT [-- ARGS...]

The script runs as __main__ with sys.argv ending in "-- ARGS" as under Blender; the add-ons are found in
$BLENDER_USER_SCRIPTS/addons (or installed as extensions) and enabled first. MYOSKIN_BPY_MODULE=1 tells
the test runner which kind of Blender this is (it starts child processes the same way).
"""
import os
import runpy
import sys
import traceback


def parse(argv):
    opts = {"blend": None, "addons": [], "exit_code": 0, "script": None, "rest": None}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--":
            opts["rest"] = argv[i + 1:]
            break
        if a in ("-b", "--background", "--factory-startup"):
            i += 1
        elif a == "--addons":
            opts["addons"] += [n for n in argv[i + 1].split(",") if n]
            i += 2
        elif a == "--python-exit-code":
            opts["exit_code"] = int(argv[i + 1])
            i += 2
        elif a in ("--python", "-P"):
            opts["script"] = argv[i + 1]
            i += 2
        elif a.endswith(".blend") and not a.startswith("-"):
            opts["blend"] = a
            i += 1
        else:
            sys.exit(f"bpy_main.py: unsupported argument {a!r}")
    if opts["script"] is None:
        sys.exit("bpy_main.py: no --python SCRIPT")
    return opts


def main(argv):
    opts = parse(argv)
    os.environ["MYOSKIN_BPY_MODULE"] = "1"
    user_scripts = os.environ.get("BLENDER_USER_SCRIPTS")
    if user_scripts and os.path.join(user_scripts, "addons") not in sys.path:
        sys.path.insert(0, os.path.join(user_scripts, "addons"))
    import bpy
    import addon_utils
    if opts["blend"]:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(opts["blend"]))
    for name in opts["addons"]:
        if addon_utils.enable(name, default_set=True) is None:
            print(f"bpy_main.py: add-on {name!r} could not be enabled", file=sys.stderr)
    script = os.path.abspath(opts["script"])
    sys.argv = [script] + (["--"] + opts["rest"] if opts["rest"] is not None else [])
    sys.path.insert(0, os.path.dirname(script))
    code = 0
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except BaseException:  # noqa: BLE001 (as Blender: print the traceback, exit with the given code)
        traceback.print_exc()
        code = opts["exit_code"]
    # Leave at once, as Blender does after --python in the background: the bpy module's own teardown
    # at interpreter exit can wait forever on its threads.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    main(sys.argv[1:])
