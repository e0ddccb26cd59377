# SPDX-License-Identifier: GPL-3.0-or-later
"""The one place of the add-on that imports the compiled core `_core`.

The import is guarded (as Animation Nodes does): the add-on folder may carry cores for several Pythons
(a package for Blender 3.4 to 5.x has one for 3.11 and one for 3.13), each with a build_info-X.Y.json
written by CMake next to it; the one for this Blender's Python major.minor is chosen, and the module
file it names must exist (Python itself picks the file by its ABI suffix). When anything is wrong the add-on still registers; `status()` says
exactly what to do and every panel shows it, and `core()` raises CoreUnavailableError with the same text.

No bpy here, so this module can be imported by background scripts and tests alike.
"""
import json
import os
import re
import sys

ADDON_DIR = os.path.dirname(os.path.abspath(__file__))
BUILD_INFO_FILE = "build_info-{}.json"  # .format(python "X.Y")
BUILD_COMMAND = "./myoskin.sh build"


class CoreUnavailableError(RuntimeError):
    """Raised by core() when the compiled core could not be loaded; the message says what to do."""


class CoreStatus:
    """What happened when the core was loaded.

    available: the module imported and matches this Python.
    message: one line for the user (what works, or exactly what to do).
    build_info: the parsed build_info.json (or {}), module_path: the module file (or "").
    """

    __slots__ = ("available", "message", "build_info", "module_path")

    def __init__(self, available, message, build_info=None, module_path=""):
        self.available = available
        self.message = message
        self.build_info = dict(build_info or {})
        self.module_path = module_path

    def __repr__(self):
        return f"CoreStatus(available={self.available!r}, message={self.message!r})"


def running_python_version():
    """This interpreter's "major.minor" (Blender's embedded Python)."""
    return f"{sys.version_info.major}.{sys.version_info.minor}"


def blender_python_hint(version=None):
    """Best guess at the interpreter to build for: <sys.prefix>/bin/pythonX.Y.

    Inside Blender sys.executable is the Blender binary, not Python; sys.prefix is the Python
    installation Blender uses (/usr on Debian, <blender>/X.Y/python for official builds).
    """
    version = version or running_python_version()
    return os.path.join(sys.prefix, "bin", f"python{version}")


def running_numpy_version():
    """This Python's NumPy version ("" without NumPy)."""
    try:
        import numpy
        return str(numpy.__version__)
    except Exception:  # noqa: BLE001 (a broken NumPy must not stop the add-on registering)
        return ""


def _major_minor(version):
    parts = re.findall(r"\d+", str(version))
    return (int(parts[0]), int(parts[1])) if len(parts) >= 2 else None


def numpy_problem(pybind11_version, numpy_version):
    """The message when a core built with `pybind11_version` ("" = unknown, taken as old) cannot work with
    `numpy_version` ("" = no NumPy), else None."""
    pybind11, numpy = _major_minor(pybind11_version), _major_minor(numpy_version)
    if numpy is None or numpy < (2, 0) or (pybind11 is not None and pybind11 >= (2, 12)):
        return None
    return (f"Myoskin's compiled core was built with pybind11 {pybind11_version or '(unknown, before 2.12)'}, which "
            f"cannot exchange arrays with NumPy 2, and this Python has NumPy {numpy_version}: use NumPy 1 "
            f"(pip install 'numpy<2'), or rebuild against pybind11 2.12 or newer (pip install 'pybind11>=2.12', then "
            f"cmake -S . -B build -Dpybind11_DIR=$(python3 -m pybind11 --cmakedir) and `{BUILD_COMMAND}`)")


def check_build_info(info, addon_dir=ADDON_DIR, python_version=None, numpy_version=None):
    """Return None if `info` (a parsed build_info-X.Y.json, or None when absent) fits this Blender,
    otherwise the message telling the user what to do. Pure function: tests pass fake dicts (and versions)."""
    python_version = python_version or running_python_version()
    if info is None:
        return (f"Myoskin's compiled core is missing (no {BUILD_INFO_FILE.format(python_version)} in "
                f"{addon_dir}): "
                f"run `{BUILD_COMMAND}` and start Blender with "
                f"BLENDER_USER_SCRIPTS=<repository>/build/blender_scripts")
    if not isinstance(info, dict):
        return (f"Myoskin's {BUILD_INFO_FILE.format(python_version)} in {addon_dir} is unreadable: "
                f"rebuild with `{BUILD_COMMAND}`")
    built_for = str(info.get("python_version", "")).strip()
    if built_for != python_version:
        hint = blender_python_hint(python_version)
        return (f"Myoskin's compiled core was built for Python {built_for or '(unknown)'} but this Blender "
                f"runs {python_version}: rebuild with `{BUILD_COMMAND}` using "
                f"-DPython3_EXECUTABLE={hint} (reconfigure: cmake -S . -B build "
                f"-DPython3_EXECUTABLE={hint})")
    # pybind11 before 2.12 reads NumPy 1's array descriptors: under NumPy 2 its arrays come out wrong or crash. A core
    # whose build_info has no pybind11_version was built before this check and is taken as old.
    numpy_version = running_numpy_version() if numpy_version is None else numpy_version
    problem = numpy_problem(info.get("pybind11_version", ""), numpy_version)
    if problem:
        return problem
    module = info.get("module") or ""
    if not module or not os.path.isfile(os.path.join(addon_dir, module)):
        return (f"Myoskin's compiled core is missing ({module or 'the _core module'} not found in "
                f"{addon_dir}): run `{BUILD_COMMAND}`")
    return None


def read_build_info(addon_dir=ADDON_DIR, python_version=None):
    """The parsed build_info-X.Y.json for `python_version` (default: this Python), None when absent, or a
    string describing why it is unreadable."""
    path = os.path.join(addon_dir, BUILD_INFO_FILE.format(python_version or running_python_version()))
    if not os.path.isfile(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        return f"{path}: {e}"


def available_pythons(addon_dir=ADDON_DIR):
    """The Python versions ("X.Y", sorted) the add-on folder has a core for."""
    prefix, suffix = BUILD_INFO_FILE.split("{}")
    try:
        names = os.listdir(addon_dir)
    except OSError:
        return []
    found = [n[len(prefix):-len(suffix)] for n in names if n.startswith(prefix) and n.endswith(suffix)]
    return sorted(found, key=lambda v: tuple(int(x) if x.isdigit() else 0 for x in v.split(".")))


def pythons_text(versions):
    """"3.11", "3.11 and 3.13", "3.10, 3.11 and 3.13"."""
    return " and ".join(filter(None, [", ".join(versions[:-1]), versions[-1]])) if versions else "(none)"


def best_build_info(addon_dir=ADDON_DIR, python_version=None):
    """The build info for this Python; when there is none, another Python's (so the message can say which
    Python the core has); None when the folder has no core at all."""
    python_version = python_version or running_python_version()
    info = read_build_info(addon_dir, python_version)
    if info is not None:
        return info
    others = available_pythons(addon_dir)
    if not others:
        return None
    info = read_build_info(addon_dir, others[-1])
    if isinstance(info, dict):
        info = dict(info, python_version=pythons_text(others))
    return info


_module = None
_status = CoreStatus(False, "Myoskin's compiled core has not been loaded yet")


def load():
    """(Re)try to import the core; returns the new CoreStatus. Called once at import of this module."""
    global _module, _status
    info = best_build_info()
    problem = check_build_info(info)
    info = info if isinstance(info, dict) else {}
    module_path = os.path.join(ADDON_DIR, info.get("module", "")) if info.get("module") else ""
    if problem is None:
        try:
            from . import _core as module
        except ImportError as e:
            problem = (f"Myoskin's compiled core failed to load ({e}): rebuild with `{BUILD_COMMAND}`")
        else:
            loaded = str(module.build_info().get("python_version", ""))
            if loaded != running_python_version():
                problem = check_build_info(dict(info, python_version=loaded))
            else:
                _module = module
                _status = CoreStatus(True, f"Myoskin core {module.__version__} loaded "
                                           f"(Python {loaded}, {info.get('build_type', '?')} build)",
                                     info, module_path)
                return _status
    _module = None
    _status = CoreStatus(False, problem, info, module_path)
    return _status


def status():
    """The CoreStatus of the last load attempt."""
    return _status


def available():
    return _module is not None


def core():
    """The compiled `_core` module; raises CoreUnavailableError (saying what to do) when it did not load."""
    if _module is None:
        raise CoreUnavailableError(_status.message)
    return _module


load()
