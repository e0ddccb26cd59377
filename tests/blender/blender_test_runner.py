# SPDX-License-Identifier: GPL-3.0-or-later
"""A tiny test runner for scripts run inside Blender (blender -b ... --python tests/blender/test_X.py).

Usage at the end of a test script:
    import blender_test_runner as runner
    runner.run()          # collects test_* functions of the calling module, in definition order

Prints "PASS name", "FAIL name" (with the traceback) or "SKIP name: reason" per test, then a final line
exactly "N passed, N failed" (", N skipped" appended when some were skipped), and exits with status 1
when any test failed (and 0 otherwise, so Blender stops without running its UI).

Skipping: raise runner.Skip("reason"), or use runner.shared_file("characters/x/x.glb"), which returns
the path under MYOSKIN_SHARED_DIR (default: <source>/../shared) or skips naming the missing file.
"""
import inspect
import os
import sys
import time
import traceback
import warnings

SOURCE_DIR = os.environ.get("MYOSKIN_SOURCE_DIR") or os.path.abspath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
SHARED_DIR = os.environ.get("MYOSKIN_SHARED_DIR") or os.path.abspath(os.path.join(SOURCE_DIR, "..", "shared"))


# The add-on's package: "myoskin" from a user-scripts folder, "bl_ext.<repository>.myoskin" as an extension.
ADDON = os.environ.get("MYOSKIN_ADDON", "myoskin")
BPY_MAIN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bpy_main.py")


# The synthetic arm the binding tests add and bind again and again: 240 rings per metre and 64 segments around (13.8k
# vertices, the default 33.6k), the same six muscles on seeds 0-3. Bind's cost at full size is the benchmarks' to
# measure; the tests that compare with the core's default arm keep the default.
LIGHT_ARM = {"rings_per_metre": 240, "segments_around": 64}


class Skip(Exception):
    """Raise to skip the current test; the message is the reason."""


def addon_module(name=""):
    """The add-on package `myoskin` or one of its submodules, as Blender imported them."""
    full = ADDON + ("." + name if name else "")
    __import__(full)
    return sys.modules[full]


def core():
    """The compiled _core module, through the add-on's loader."""
    return addon_module("core_loader").core()


def operator_error(op, **kwargs):
    """Call an operator that must fail cleanly; returns its error text ('' when it returned CANCELLED
    without Blender raising). A Python traceback inside the text means the operator itself raised."""
    try:
        result = op(**kwargs)
    except RuntimeError as e:
        text = str(e)
        assert "Traceback" not in text, f"operator raised instead of reporting:\n{text}"
        return text
    assert result == {'CANCELLED'}, result
    return ""


def weights_of(skin):
    """{group name: {vertex: weight}}: the exact state of every vertex group of a mesh object."""
    names = {g.index: g.name for g in skin.vertex_groups}
    out = {n: {} for n in names.values()}
    for v in skin.data.vertices:
        for g in v.groups:
            out[names[g.group]][v.index] = g.weight
    return out


def evaluated(skin):
    """#V by 3 evaluated (deformed) vertices of a mesh object, mesh space, after a view-layer update."""
    import bpy
    bpy.context.view_layer.update()
    return addon_module("blender_io").evaluated_vertices(skin)


def size_of(skin):
    """The diagonal of a mesh object's rest bounding box (the size tolerances are relative to)."""
    import numpy as np
    rest = addon_module("blender_io").mesh_vertices(skin.data)
    return float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))


def is_bpy_module():
    """True under the `bpy` module (a Python interpreter), False inside a Blender executable."""
    return os.environ.get("MYOSKIN_BPY_MODULE") == "1"


def blender_command(*args):
    """The command line that starts another Blender of the same kind in the background with `args`
    (Blender's own options: FILE.blend, --python-exit-code, -P SCRIPT, -- ...), e.g. for batch.py."""
    import bpy
    if is_bpy_module():
        return [sys.executable, BPY_MAIN, "--factory-startup", *args]
    return [bpy.app.binary_path, "-b", "--factory-startup", *args]


def skip(reason):
    raise Skip(reason)


def shared_file(relative):
    """Absolute path of a file in the shared folder, or Skip with a message naming what is missing."""
    path = os.path.join(SHARED_DIR, relative)
    if not os.path.exists(path):
        raise Skip(f"needs {path} (the ../shared folder beside the repository; set MYOSKIN_SHARED_DIR)")
    return path


def collect(namespace):
    """test_* functions of a module namespace, in definition (line) order."""
    tests = [v for k, v in namespace.items() if k.startswith("test_") and inspect.isfunction(v)]
    return sorted(tests, key=lambda f: f.__code__.co_firstlineno)


def enable_addon(name=ADDON):
    """Enable the add-on as a user would (listed in the preferences), not only loaded by --addons."""
    import addon_utils
    import bpy
    if name not in bpy.context.preferences.addons:
        addon_utils.enable(name, default_set=True)


def run(namespace=None, exit=True):
    """Run the test_* functions of `namespace` (default: the caller's globals). Returns (passed, failed,
    skipped); with exit=True ends the process with status 1 on any failure."""
    if namespace is None:
        namespace = inspect.currentframe().f_back.f_globals
    # Deprecations raised from the add-on's own code (Python 3.13, numpy 2, Blender's API) fail the test.
    warnings.filterwarnings("error", category=DeprecationWarning, module=r"(bl_ext\.[^.]+\.)?myoskin(\..*)?$")
    enable_addon()
    only = os.environ.get("MYOSKIN_TEST_FILTER", "")
    passed = failed = skipped = 0
    for test in collect(namespace):
        name = test.__name__
        if only and only not in name:
            continue
        start = time.perf_counter()
        try:
            test()
        except Skip as e:
            skipped += 1
            print(f"SKIP {name}: {e}", flush=True)
        except Exception:  # noqa: BLE001
            failed += 1
            print(f"FAIL {name}", flush=True)
            traceback.print_exc()
            sys.stderr.flush()
        else:
            passed += 1
            print(f"PASS {name} ({time.perf_counter() - start:.2f} s)", flush=True)
    summary = f"{passed} passed, {failed} failed"
    if skipped:
        summary += f", {skipped} skipped"
    print(summary, flush=True)
    if exit:
        sys.exit(1 if failed else 0)
    return passed, failed, skipped
