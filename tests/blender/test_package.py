# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: the packages in <build>/dist (./myoskin.sh build makes them) installed into a Blender
with empty user folders, as a user installs them, and used there: the extension on 4.2+ (package
bl_ext.user_default.myoskin), the legacy zip on 3.4 (package myoskin). Both carry the core for Python 3.11
and 3.13; each Blender must load its own. The installed batch.py finds its package by itself.

    MYOSKIN_DIST_DIR=build/dist BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_package.py
"""
import glob
import os
import subprocess
import sys
import tempfile

import bpy

SOURCE = os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "tests", "blender"))
import blender_test_runner as runner  # noqa: E402

EXTENSION = bpy.app.version >= (4, 2, 0)
USER = tempfile.mkdtemp(prefix="myoskin_test_package_")


def package_zip():
    dist = os.environ.get("MYOSKIN_DIST_DIR", "")
    zips = sorted(glob.glob(os.path.join(dist, "myoskin-*.zip")))
    legacy = [z for z in zips if z.endswith("-legacy.zip")]
    extension = [z for z in zips if not z.endswith("-legacy.zip")]
    found = extension if EXTENSION else legacy
    if not found:
        raise AssertionError(f"no {'extension' if EXTENSION else 'legacy'} package in MYOSKIN_DIST_DIR={dist!r} "
                             f"(./myoskin.sh build makes them): {zips}")
    return found[0]


def clean_env():
    """The environment of a Blender with empty user folders: nothing of the build's add-on stage."""
    env = {k: v for k, v in os.environ.items() if k not in ("BLENDER_USER_SCRIPTS", "MYOSKIN_ADDON")}
    env.update(BLENDER_USER_CONFIG=os.path.join(USER, "config"), BLENDER_USER_SCRIPTS=os.path.join(USER, "scripts"),
               BLENDER_USER_EXTENSIONS=os.path.join(USER, "extensions"))
    return env


def run(*args):
    done = subprocess.run(runner.blender_command(*args), capture_output=True, text=True, timeout=600, env=clean_env())
    return done.returncode, done.stdout + done.stderr


def installed_folder():
    if EXTENSION:
        return os.path.join(USER, "extensions", "user_default", "myoskin")
    return os.path.join(USER, "scripts", "addons", "myoskin")


def test_installed_package_loads_its_core_and_works():
    out = os.path.join(USER, "installed.blend")
    code, log = run("--python-exit-code", "1", "--python", os.path.join(SOURCE, "tests", "blender", "package_install.py"),
                    "--", package_zip(), out)
    assert code == 0 and "package_install: done" in log, log
    expected = "bl_ext.user_default.myoskin" if EXTENSION else "myoskin"
    assert f"package: {expected}\n" in log, log
    assert f"python: {sys.version_info.major}.{sys.version_info.minor}\n" in log, log
    folder = installed_folder()
    for py in ("3.11", "3.13"):
        assert os.path.isfile(os.path.join(folder, f"build_info-{py}.json")), os.listdir(folder)
    assert os.path.isfile(out)


def test_installed_batch_finds_its_package():
    src = os.path.join(USER, "installed.blend")
    if not os.path.isfile(src):
        runner.skip("needs the .blend of test_installed_package_loads_its_core_and_works (which failed)")
    out = os.path.join(USER, "batch_out.blend")
    batch = os.path.join(installed_folder(), "batch.py")
    code, log = run(src, "--python-exit-code", "1", "-P", batch, "--", "extract", "--bind", "-o", out)
    assert code == 0 and "bound:" in log and os.path.isfile(out), log
    code, log = run(src, "--python-exit-code", "1", "-P", batch, "--", "extract", "-o",
                    os.path.join(USER, "no_such_folder", "x.blend"))
    assert code == 1 and "myoskin batch: error: cannot save" in log and "Traceback" not in log, log


def test_extension_command_line_install():
    if not EXTENSION or runner.is_bpy_module():
        runner.skip("`blender --command extension` needs a Blender 4.2+ executable")
    env = clean_env()
    env["BLENDER_USER_EXTENSIONS"] = os.path.join(USER, "cli_extensions")
    for command in (["validate", package_zip()], ["install-file", "-r", "user_default", "-e", package_zip()]):
        done = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "--command", "extension", *command],
                              capture_output=True, text=True, timeout=300, env=env)
        assert done.returncode == 0, done.stdout + done.stderr
    assert os.path.isfile(os.path.join(USER, "cli_extensions", "user_default", "myoskin", "__init__.py"))


runner.run()
