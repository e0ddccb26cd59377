"""The `myoskin` CLI: info on the shared characters, generate, and one-line errors on bad input."""
import json
import re

import pytest

from conftest import LOWPOLY, MUSCULAR, run_cli, shared


def _counts(out):
    vertices = int(re.search(r"^vertices: (\d+)", out, re.M).group(1))
    bones = int(re.search(r"^bones: (\d+)", out, re.M).group(1))
    return vertices, bones


def test_info_muscular_male_prints_readme_counts():
    r = run_cli("info", shared(MUSCULAR))
    assert r.returncode == 0, r.stderr
    assert _counts(r.stdout) == (13380, 163)
    assert "triangles: 26756" in r.stdout
    assert "(closed manifold)" in r.stdout
    assert "bounding box: min (-0.60" in r.stdout


def test_info_lowpoly_prints_welded_counts():
    r = run_cli("info", shared(LOWPOLY))
    assert r.returncode == 0, r.stderr
    assert _counts(r.stdout) == (904, 56)
    assert "1226 as stored" in r.stdout
    assert "(closed manifold)" in r.stdout


def test_generate_arm_writes_a_loadable_character(tmp_path):
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "3")
    assert r.returncode == 0, r.stderr
    truth = json.load(open(tmp_path / "arm.truth.json"))
    assert len(truth["muscles"] if isinstance(truth, dict) else truth) >= 5
    info = run_cli("info", str(tmp_path / "arm.obj"))
    assert info.returncode == 0, info.stderr
    assert "(closed manifold)" in info.stdout


def test_extract_expert_options(tmp_path):
    """Expert tuning reaches the core through --expert KEY=VALUE and --options FILE.json; the old expert flags
    name their key; the five user-facing flags are checked."""
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "2")
    assert r.returncode == 0, r.stderr
    arm = str(tmp_path / "arm.obj")

    def count(*extra):
        out = tmp_path / "m.json"
        r = run_cli("extract", arm, "-o", str(out), "--no-surfaces", *extra)
        assert r.returncode == 0, r.stderr
        return len(json.load(open(out))["muscles"])

    counts = [count("--expert", "filters.minEvidence=0"), count(),
              count("--expert", "filters.minEvidence=1000", "--expert", "filters.spindleEnds=0")]
    assert counts[0] >= counts[1] == 6 and counts[2] == 0, counts  # seed 2: its six muscles at the default
    options = tmp_path / "expert.json"
    json.dump({"filters.minEvidence": 1000, "filters.spindleEnds": 0}, open(options, "w"))
    assert count("--options", str(options)) == 0
    assert count("--options", str(options), "--expert", "filters.minEvidence=6.6") > 0  # --expert after the file
    assert count("--max-per-region", "1") < 6 and count("--min-confidence", "1") == 0
    r = run_cli("extract", "--expert", "list")
    assert r.returncode == 0 and "filters.minEvidence = 6.6 (double)" in r.stdout, r.stdout
    for bad, message in ((["--min-evidence", "1"], "--expert filters.minEvidence"),
                         (["--spindle-ends", "2"], "--expert filters.spindleEnds"),
                         (["--expert", "filters.nothing=1"], "unknown expert extraction option 'filters.nothing'"),
                         (["--expert", "filters.minEvidence"], "KEY=VALUE"),
                         (["--expert", "filters.minEvidence=-1"], "filters.minEvidence must be >= 0"),
                         (["--expert", "link.maxGap=2.5"], "must be an integer"),
                         (["--spacing", "-1"], "--spacing"), (["--joint-wrap", "-1"], "--joint-wrap"),
                         (["--max-per-region", "-1"], "--max-per-region"), (["--no-such-flag"], "--no-such-flag")):
        r = run_cli("extract", arm, "-o", str(tmp_path / "x.json"), *bad)
        assert r.returncode != 0 and message in r.stderr, (bad, r.stderr)


def test_extract_notes_a_body_far_from_the_reference_size(tmp_path):
    """The horse's limbs are 2.5 times the reference limb radius: extract says its muscles depend on its size and
    names scale.continuous, which analyses it at the reference size and says nothing."""
    horse = shared("characters/quaternius_horse/horse.glb")
    r = run_cli("extract", horse, "-o", str(tmp_path / "m.json"), "--no-surfaces")
    assert r.returncode == 0, r.stderr
    assert re.search(r"^note: limb radius .* 2\.\d\d times .*scale\.continuous", r.stdout, re.M), r.stdout
    r = run_cli("extract", horse, "-o", str(tmp_path / "m.json"), "--no-surfaces", "--expert", "scale.continuous=1")
    assert r.returncode == 0 and "note:" not in r.stdout and len(json.load(open(tmp_path / "m.json"))["muscles"]) > 0


def test_extract_spacing_in_limb_radii(tmp_path):
    """--spacing is in limb radii: half the spacing cuts twice the planes; a value in metres is refused."""
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "1")
    assert r.returncode == 0, r.stderr
    arm = str(tmp_path / "arm.obj")
    planes = []
    for spacing in ("0", "0.5", "1"):
        r = run_cli("extract", arm, "-o", str(tmp_path / "m.json"), "--no-surfaces", "--spacing", spacing)
        assert r.returncode == 0, r.stderr
        planes.append(int(r.stdout.split(" planes,")[0].split("(")[-1]))
    assert planes[1] > planes[2] > 0 and 1.6 < planes[1] / planes[2] < 2.4, planes  # twice as many at half
    # 2 cm, as the option was given before it took limb radii: refused, not tens of thousands of planes
    r = run_cli("extract", arm, "-o", str(tmp_path / "m.json"), "--no-surfaces", "--spacing", "0.02")
    assert r.returncode != 0 and "limb radii" in r.stderr, r.stderr


def _write_obj(path, vertices, faces):
    with open(path, "w") as f:
        for v in vertices:
            f.write("v %s %s %s\n" % v)
        for t in faces:
            f.write("f %d %d %d\n" % t)


TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)]
SKELETON = {"bones": [{"name": "root", "parent": None, "head": [0, 0, 0], "tail": [0, 0.5, 0]}],
            "weights": {"root": [[0, 1.0], [1, 1.0], [2, 1.0], [3, 1.0]]}}


def _bad_inputs(tmp_path):
    """(name, path) of each kind of bad input the CLI must reject."""
    cases = [("missing file", str(tmp_path / "missing.glb"))]
    wrong = tmp_path / "wrong.glb"
    wrong.write_text("not a glb at all")
    cases.append(("wrong format", str(wrong)))
    unknown = tmp_path / "model.fbx"
    unknown.write_text("x")
    cases.append(("unknown extension", str(unknown)))
    _write_obj(tmp_path / "nan.obj", [(0, 0, 0), ("nan", 0, 0), (0, 1, 0), (0, 0, 1)], TETRA_F)
    json.dump(SKELETON, open(tmp_path / "nan.skeleton.json", "w"))
    cases.append(("NaN positions", str(tmp_path / "nan.obj")))
    _write_obj(tmp_path / "noskin.obj", TETRA_V, TETRA_F)
    json.dump({"bones": SKELETON["bones"]}, open(tmp_path / "noskin.skeleton.json", "w"))
    cases.append(("mesh without skin", str(tmp_path / "noskin.obj")))
    return cases


@pytest.mark.parametrize("command", ["info", "extract", "deform"])
def test_bad_input_gives_one_line_error_and_nonzero_exit(tmp_path, command):
    for name, path in _bad_inputs(tmp_path):
        r = run_cli(command, path, "-o", str(tmp_path / "out.json"))
        assert r.returncode not in (0, -6, -11), f"{name}: exit {r.returncode}"
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("myoskin: error: "), f"{name}: {r.stderr!r}"


def test_unskinned_glb_is_rejected():
    path = shared("characters/bodyparts3d_right_leg/bodyparts3d_right_leg.glb")
    r = run_cli("info", path)
    assert r.returncode != 0 and r.stderr.startswith("myoskin: error: ")


def test_usage_errors():
    assert run_cli().returncode == 2
    r = run_cli("frobnicate")
    assert r.returncode == 2 and "unknown command" in r.stderr
    assert run_cli("--help").returncode == 0


# ============================================================================
# Any character: several meshes, bone roles, saying why
# ============================================================================

SOLDIER = "characters/quaternius_woman_soldier/woman_soldier.glb"


def test_info_and_extract_take_every_mesh_of_the_character(tmp_path):
    r = run_cli("info", shared(SOLDIER))
    assert r.returncode == 0, r.stderr
    assert "15836 as stored" in r.stdout  # all four meshes
    assert re.search(r"^meshes: 4 Soldier_Body \(5444\)", r.stdout, re.M), r.stdout
    out = tmp_path / "m.json"
    r = run_cli("extract", shared(SOLDIER), "-o", str(out), "--no-surfaces")
    assert r.returncode == 0, r.stderr
    assert re.search(r"left out of the analysis: \d+ rigid in mesh 'Soldier_Head' bound to 'Head'", r.stdout), r.stdout
    regions = {m["region"] for m in json.load(open(out))["muscles"]}
    assert {"UpperLeg.L", "UpperLeg.R"} <= regions, regions
    legs = run_cli("info", shared(SOLDIER), "--mesh", "Soldier_Legs")
    assert legs.returncode == 0 and "2600 as stored" in legs.stdout, legs.stdout + legs.stderr
    r = run_cli("info", shared(SOLDIER), "--mesh", "Cape")
    assert r.returncode == 1 and "no mesh called 'Cape'" in r.stderr and "Soldier_Feet" in r.stderr


def test_roles_prints_and_writes_the_role_map_that_extract_takes(core, tmp_path):
    roles_file = tmp_path / "roles.json"
    r = run_cli("roles", shared(MUSCULAR), "-o", str(roles_file))
    assert r.returncode == 0, r.stderr
    assert re.search(r"^upperarm02\.L\s+limb\s+parent upperarm01\.L$", r.stdout, re.M), r.stdout
    roles = json.load(open(roles_file))
    assert len(roles) == 163 and roles["neck01"] == "neck" and roles["spine03"] == "spine"
    # Overrides: the arms off, and the extraction then finds nothing on them (without them it does).
    arms = ("upperarm", "lowerarm")
    default, _ = core.extract_muscles(core.load_character(shared(MUSCULAR)), build_surfaces=False)
    assert [m for m in default if m.region.startswith(arms)]
    for bone, role in list(roles.items()):
        if bone.startswith(arms):
            roles[bone] = "ignore"
    json.dump(roles, open(roles_file, "w"))
    out = tmp_path / "m.json"
    r = run_cli("extract", shared(MUSCULAR), "-o", str(out), "--no-surfaces", "--roles", str(roles_file))
    assert r.returncode == 0, r.stderr
    muscles = json.load(open(out))["muscles"]
    assert muscles and not [m for m in muscles if m["region"].startswith(arms)]
    json.dump({"upperarm01.L": "wing"}, open(roles_file, "w"))
    r = run_cli("extract", shared(MUSCULAR), "-o", str(out), "--roles", str(roles_file))
    assert r.returncode == 1 and "unknown bone role 'wing'" in r.stderr, r.stderr
    json.dump({"tail01": "limb"}, open(roles_file, "w"))
    r = run_cli("roles", shared(MUSCULAR), "--roles", str(roles_file))
    assert r.returncode == 1 and "names no bone: 'tail01'" in r.stderr, r.stderr


def test_extract_says_why_and_fails_when_nothing_could_be_analysed(tmp_path):
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "1")
    assert r.returncode == 0, r.stderr
    arm = str(tmp_path / "arm.obj")
    roles = tmp_path / "roles.json"
    json.dump({b: "ignore" for b in ("clavicle", "upper_arm", "forearm", "hand")}, open(roles, "w"))
    out = tmp_path / "m.json"
    r = run_cli("extract", arm, "-o", str(out), "--roles", str(roles))
    assert r.returncode == 1, r.stdout
    assert "nothing could be analysed" in r.stderr and "no limb chain recognised" in r.stderr, r.stderr
    assert not out.exists()
    # Sections analysed but nothing stands out: exit 0, and the reason printed.
    r = run_cli("extract", arm, "-o", str(out), "--expert", "filters.minEvidence=1000", "--expert",
                "filters.spindleEnds=0", "--no-surfaces")
    assert r.returncode == 0, r.stderr
    assert "no muscles: " in r.stdout and "none kept" in r.stdout, r.stdout
