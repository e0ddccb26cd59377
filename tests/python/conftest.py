"""pytest setup: import the staged _core module and locate the CLI and the shared characters."""
import os
import subprocess
import sys

import pytest

BUILD_DIR = os.environ.get("MYOSKIN_BUILD_DIR") or os.path.join(os.path.dirname(__file__), "..", "..", "build")
SHARED_DIR = os.environ.get("MYOSKIN_SHARED_DIR") or os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared")
ADDON_DIR = os.path.join(BUILD_DIR, "blender_scripts", "addons", "myoskin")
sys.path.insert(0, ADDON_DIR)


def _refuse_a_core_this_numpy_breaks():
    """Stop before importing a core whose pybind11 cannot read this Python's NumPy (it would segfault): the add-on's
    own check (core_loader.numpy_problem) with the staged build_info."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("myoskin_core_loader", os.path.join(ADDON_DIR, "core_loader.py"))
    loader = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loader)
    info = loader.read_build_info(ADDON_DIR)
    if isinstance(info, dict):
        problem = loader.numpy_problem(info.get("pybind11_version", ""), loader.running_numpy_version())
        if problem:
            pytest.exit(f"{sys.executable}: {problem} (the README's test command uses /usr/bin/python3)", returncode=2)


_refuse_a_core_this_numpy_breaks()
import _core  # noqa: E402  (the compiled module, staged in the add-on folder)


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "figures: the core's figures over generated bodies (held-out seeds, sweeps); the second Python's "
        "tier (tests/CMakeLists.txt, myoskin_python_tier) leaves them out: its core, the other Debian release's "
        "build, is measured there on the shared characters, one held-out body and in the Blender tiers")


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
