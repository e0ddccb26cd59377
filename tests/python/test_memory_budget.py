"""The memory budget from Python and the CLI: a stage that would not fit stops with ValueError / one error line
(never an out-of-memory kill), under MYOSKIN_MEMORY_LIMIT as a farm job would set it."""
import os
import subprocess
import sys

from conftest import BUILD_DIR, MUSCULAR, run_cli, shared

SCRIPT = """
import sys
sys.path.insert(0, sys.argv[1])
import _core
body, _ = _core.make_synthetic_body(seed=3)
try:
    _core.extract_muscles(body)
except ValueError as e:
    print("REFUSED", e)
else:
    print("RAN")
"""


def run_python(limit):
    env = dict(os.environ)
    env.pop("MYOSKIN_MEMORY_LIMIT", None)
    if limit:
        env["MYOSKIN_MEMORY_LIMIT"] = limit
    return subprocess.run([sys.executable, "-c", SCRIPT, os.path.join(BUILD_DIR, "blender_scripts", "addons", "myoskin")],
                          capture_output=True, text=True, timeout=300, env=env)


def test_available_memory_follows_the_limit(core):
    free = core.available_memory()
    assert free > 0
    os.environ["MYOSKIN_MEMORY_LIMIT"] = "2G"
    try:
        assert core.available_memory() <= 2 * 1024 ** 3
        os.environ["MYOSKIN_MEMORY_LIMIT"] = "plenty"
        try:
            core.available_memory()
        except ValueError as e:
            assert "MYOSKIN_MEMORY_LIMIT" in str(e)
        else:
            raise AssertionError("a malformed MYOSKIN_MEMORY_LIMIT was accepted")
    finally:
        del os.environ["MYOSKIN_MEMORY_LIMIT"]


def test_extraction_refuses_what_would_not_fit():
    refused = run_python("1M")
    assert refused.returncode == 0, refused.stderr
    assert refused.stdout.startswith("REFUSED muscle extraction on"), refused.stdout
    assert "needs about" in refused.stdout and "MiB" in refused.stdout
    ran = run_python("")
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.strip() == "RAN"


def test_cli_reports_one_line(tmp_path):
    path = shared(MUSCULAR)
    env_before = os.environ.get("MYOSKIN_MEMORY_LIMIT")
    os.environ["MYOSKIN_MEMORY_LIMIT"] = "4M"
    try:
        done = run_cli("extract", path, "-o", str(tmp_path / "m.json"))
    finally:
        if env_before is None:
            del os.environ["MYOSKIN_MEMORY_LIMIT"]
        else:
            os.environ["MYOSKIN_MEMORY_LIMIT"] = env_before
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "needs about" in lines[0], done.stderr
    assert not (tmp_path / "m.json").exists()
