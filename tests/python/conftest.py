"""pytest setup: import the staged _core module and locate the CLI and the shared characters."""
import os
import subprocess
import sys

import pytest

BUILD_DIR = os.environ.get("MYOSKIN_BUILD_DIR") or os.path.join(os.path.dirname(__file__), "..", "..", "build")
SHARED_DIR = os.environ.get("MYOSKIN_SHARED_DIR") or os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared")
sys.path.insert(0, os.path.join(BUILD_DIR, "blender_scripts", "addons", "myoskin"))

import _core  # noqa: E402  (the compiled module, staged in the add-on folder)


def shared(relative):
    """Path of a file under ../shared, or skip the test with a clear message when it is absent."""
    path = os.path.join(SHARED_DIR, relative)
    if not os.path.exists(path):
        pytest.skip(f"needs {path} (the ../shared folder beside the repository)")
    return path


MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
NEUTRAL = "characters/makehuman_neutral/makehuman_neutral.glb"
LOWPOLY = "characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb"


def run_cli(*args):
    """Run the built `myoskin` CLI; returns CompletedProcess with text output."""
    exe = os.path.join(BUILD_DIR, "bin", "myoskin")
    return subprocess.run([exe, *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="session")
def core():
    return _core
