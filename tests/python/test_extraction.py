"""Muscle extraction through _core and the CLI: the synthetic arm's known muscles, options, errors."""
import json
import os
import re

import numpy as np
import pytest

from conftest import MUSCULAR, run_cli, shared


@pytest.fixture(scope="module")
def arm(core):
    return core.make_synthetic_arm(seed=2)


def test_extract_finds_the_synthetic_arms_muscles(core, arm):
    character, truth = arm
    muscles, report = core.extract_muscles(character)
    acc = core.measure_extraction(muscles, truth)
    print(f"seed 2: {len(muscles)} found, {len(truth)} true, recall {acc['recall']:.2f}, "
          f"precision {acc['precision']:.2f}, centre error {acc['mean_center_error']:.2f} radius")
    # Issue 3's target, as the C++ tier asserts it on seeds 0-3 (test_extraction Measured): all six true muscles
    # matched and nothing else (recall and precision 1.0), centres within 0.35 of the muscle radius.
    assert acc["recall"] >= 0.9 and acc["precision"] >= 0.9, acc
    assert acc["matched"] == 6 and len(muscles) == 6 and acc["true_muscles"] == len(truth), acc
    assert acc["mean_center_error"] < 0.35, acc
    assert report["muscles"] == len(muscles) and report["planes"] >= report["sections"] > 0
    assert set(report["timings"]) >= {"planes", "sections", "bumps", "link", "ends", "surface"}
    for m in muscles:
        v, t = np.asarray(m.surface_vertices), np.asarray(m.surface_triangles)
        assert v.shape[1] == 3 and t.shape[1] == 3 and len(t) == 2 * len(v) - 4  # closed genus-0 surface
        assert np.isfinite(v).all() and 0.0 < m.confidence <= 1.0
        assert m.origin_bone and m.insertion_bone and m.num_sections >= 4


def test_truth_relief_and_visible_length(core, arm):
    """Each true muscle's relief (how far it raises the skin) per centre-line point; measure_extraction judges
    the visible length (relief >= half its peak), or with visible_relief_share=0 the whole length."""
    character, truth = arm
    assert len(truth) == 6
    for t in truth:
        relief = np.asarray(t["relief"])
        assert relief.shape == (len(t["center_line"]),) and (relief >= 0).all()
        assert relief.max() > 0.1 * t["peak_radius"] and min(relief[0], relief[-1]) < 0.5 * relief.max()
    muscles, report = core.extract_muscles(character)
    assert report["twins"] == 0  # one arm: no mirror plane, no twins
    visible = core.measure_extraction(muscles, truth)
    whole = core.measure_extraction(muscles, truth, visible_relief_share=0.0)
    assert visible["matched"] >= whole["matched"] == 6, (visible, whole)
    bad = [dict(truth[0], relief=np.asarray(truth[0]["relief"])[:-1])]
    with pytest.raises(ValueError):
        core.measure_extraction(muscles, bad)
    with pytest.raises(ValueError):
        core.extract_muscles(character, options={"filters.twinReach": -1.0}, build_surfaces=False)


def test_mirror_twins_on_a_generated_biped(core):
    """A limb chain the floors drop is kept when its mirror twin on the other limb passed them (filters.twinReach)."""
    character, truth = core.make_synthetic_body(seed=2, kind="biped")
    with_twins, report = core.extract_muscles(character, build_surfaces=False)
    without, report0 = core.extract_muscles(character, build_surfaces=False, options={"filters.twinReach": 0.0})
    # Measured: 2 (seed 2: 18 true muscles matched, 16 without twins; seed 1's one twin, a tibialis flat on one leg
    # only, is found on both legs since mirrored limbs are resampled from mirrored points)
    assert report["twins"] >= 1 and report0["twins"] == 0
    assert len(with_twins) == len(without) + report["twins"]
    acc, acc0 = core.measure_extraction(with_twins, truth), core.measure_extraction(without, truth)
    assert acc["matched"] > acc0["matched"] and acc["precision"] >= acc0["precision"], (acc, acc0)


def test_smooth_arm_gives_no_muscles(core):
    character, truth = core.make_synthetic_arm(seed=3, muscle_scale=0.0)
    assert truth == []
    muscles, _ = core.extract_muscles(character)
    assert muscles == []


def test_user_control_options(core, arm):
    character, _ = arm
    everything, _ = core.extract_muscles(character)
    limited, report = core.extract_muscles(character, max_per_region=1)
    assert len(limited) < len(everything) and report["dropped_region_limit"] > 0
    assert len({m.region for m in limited}) == len(limited)
    x = np.asarray(character.vertices)[:, 0]
    forearm = core.extract_muscles(character, vertex_mask=x > 0.5)[0]
    assert 0 < len(forearm) < len(everything)
    assert all(np.asarray(m.section_centers)[:, 0].min() > 0.45 for m in forearm)
    none, _ = core.extract_muscles(character, min_confidence=1.0)
    assert none == []
    flat, report = core.extract_muscles(character, options={  # no spindle nor continuous chain kept below it
        "filters.minRelative": 0.5, "filters.spindleEnds": 0.0, "filters.continuousEvidence": 1e9})
    assert flat == [] and report["dropped_flat"] >= len(everything)
    # The evidence floor only removes muscles (no muscle of this arm has 100 sections' worth of significance), but
    # closed spindles are kept below it (filters.spindleEnds): the arm's bellies are such spindles.
    assert core.extract_muscles(character, options={"filters.minEvidence": 100.0, "filters.spindleEnds": 0.0})[0] == []
    spindles, report = core.extract_muscles(character, options={"filters.minEvidence": 100.0})
    assert 0 < len(spindles) <= len(everything) and report["spindles"] >= len(spindles)
    assert len(core.extract_muscles(character, options={"filters.minEvidence": 0.0})[0]) >= len(everything)
    # Hysteresis (the default) measures at least as well as none on this arm (seed 2: precision 1.0 vs 0.83).
    strict, _ = core.extract_muscles(character, options={"sectionBumps.weakFraction": 1.0})
    with_h, without = core.measure_extraction(everything, arm[1]), core.measure_extraction(strict, arm[1])
    assert len(strict) > 0
    assert with_h["recall"] >= without["recall"] and with_h["precision"] >= without["precision"]


def test_makehuman_trunk_is_mirror_consistent(core):
    character = core.load_character(shared(MUSCULAR))
    muscles, report = core.extract_muscles(character, build_surfaces=False)
    assert report["split"] > 10 and report["mirrored"] == report["split"], report
    centres = np.array([np.asarray(m.section_centers).mean(axis=0) for m in muscles])
    mirrored = centres * [-1.0, 1.0, 1.0]
    nearest = np.linalg.norm(centres[:, None, :] - mirrored[None, :, :], axis=2).min(axis=1)
    assert nearest.max() < 0.01, nearest  # every muscle has a mirror image within 1 cm
    # The trunk's height floor was removed (it changed nothing, bench_floor_ablation): its key is unknown now.
    with pytest.raises(ValueError, match="unknown expert extraction option 'filters.minRelativeTrunk'"):
        core.extract_muscles(character, options={"filters.minRelativeTrunk": 0.05})
    # Muscles whose ends lie on different bones of a chain wrap round the joint between them by default.
    crossing = [m for m in muscles if m.origin_bone != m.insertion_bone and m.wrap_type == "joint"]
    assert crossing and all(m.wrap_radius > 0 for m in crossing)
    straight, _ = core.extract_muscles(character, build_surfaces=False, joint_wrap=0.0)
    assert len(straight) == len(muscles) and all(m.wrap_type == "none" for m in straight)
    with pytest.raises(ValueError, match="joint_wrap"):
        core.extract_muscles(character, joint_wrap=-0.1)
    # Opt-in: mirrored limb profiles averaged too, so every muscle's mirror image is exact (to rounding).
    twins, twin_report = core.extract_muscles(character, build_surfaces=False, options={"profiles.mirrorLimbs": True})
    assert twin_report["mirrored"] > twin_report["split"]
    c = np.array([np.asarray(m.section_centers).mean(axis=0) for m in twins])
    assert np.linalg.norm(c[:, None, :] - (c * [-1.0, 1.0, 1.0])[None, :, :], axis=2).min(axis=1).max() < 1e-3


def test_muscles_round_trip_through_json(core, arm):
    muscles, _ = core.extract_muscles(arm[0], build_surfaces=False)
    again = core.muscles_from_json(core.muscles_to_json(muscles))
    assert [m.name for m in again] == [m.name for m in muscles]
    for a, b in zip(again, muscles):
        assert np.allclose(a.root_curve, b.root_curve, atol=1e-12)
        assert np.allclose(a.section_a, b.section_a, atol=1e-12)


def test_bad_input_raises_value_error(core, arm):
    character, _ = arm
    with pytest.raises(ValueError, match="vertex mask has 3 entries"):
        core.extract_muscles(character, vertex_mask=np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match="spacing"):
        core.extract_muscles(character, spacing=-1.0)
    with pytest.raises(ValueError, match="in limb radii"):  # a value in metres
        core.extract_muscles(character, spacing=0.02)
    with pytest.raises(ValueError, match="sectionBumps.weakFraction"):
        core.extract_muscles(character, options={"sectionBumps.weakFraction": 0.0})
    with pytest.raises(ValueError, match="filters.minRelative"):
        core.extract_muscles(character, options={"filters.minRelative": float("nan")})
    with pytest.raises(ValueError, match="sectionBumps.faintRelative"):
        core.extract_muscles(character, options={"sectionBumps.faintRelative": 1.5})
    with pytest.raises(ValueError, match="filters.minEvidence"):
        core.extract_muscles(character, options={"filters.minEvidence": -1.0})
    with pytest.raises(ValueError, match="levels"):
        core.subdivide(character, -1)


def test_subdivide_keeps_shape_and_weights(core):
    character, _ = core.make_synthetic_arm(seed=1, rings_per_metre=60, segments_around=24)
    fine = core.subdivide(character, 1)
    assert fine.num_triangles == 4 * character.num_triangles
    assert abs(fine.volume() - character.volume()) < 1e-12 * 1e6
    assert np.array_equal(np.asarray(fine.vertices)[: character.num_vertices], np.asarray(character.vertices))


def test_cli_extract_writes_muscles_json(tmp_path):
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "2")
    assert r.returncode == 0, r.stderr
    out = tmp_path / "muscles.json"
    r = run_cli("extract", str(tmp_path / "arm.obj"), "--skeleton", str(tmp_path / "arm.skeleton.json"), "-o", str(out))
    assert r.returncode == 0, r.stderr
    data = json.loads(out.read_text())
    assert data["format"] == "myoskin.muscles" and data["version"] == 1
    assert len(data["muscles"]) >= 1 and f"extracted {len(data['muscles'])} muscles" in r.stdout
    r = run_cli("extract", str(tmp_path / "arm.obj"), "--skeleton", str(tmp_path / "arm.skeleton.json"),
                "-o", str(out), "--spacing", "abc")
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "--spacing needs a number" in r.stderr


def test_cli_extract_makehuman(tmp_path):
    out = tmp_path / "mh.json"
    r = run_cli("extract", shared(MUSCULAR), "-o", str(out), "--no-surfaces")
    assert r.returncode == 0, r.stderr
    # the C++ tier's floor on this body (test_extraction MakeHumanMuscularVersusNeutral; measured 20-22)
    assert len(json.loads(out.read_text())["muscles"]) >= 12


def test_continuous_floor_keeps_the_quadriceps(core):
    # On the muscular male the quadriceps stand out only 0.061-0.074 of the thigh radius, in every plane of the
    # front thigh: kept by the continuous floor (one bump's floor, bumps.minRelativeProtrusion 0.05, instead of
    # filters.minRelative 0.09), dropped without it (the rule off: no chain reaches the evidence it then asks for).
    character = core.load_character(shared(MUSCULAR))
    default, _ = core.extract_muscles(character, build_surfaces=False)
    off, report = core.extract_muscles(character, build_surfaces=False, options={"filters.continuousEvidence": 1e9})
    names = {m.name for m in default} - {m.name for m in off}
    assert len(off) < len(default) and report["dropped_flat"] > 0
    assert {"quadriceps.L", "quadriceps.R"} <= names, names
    with pytest.raises(ValueError, match="continuous"):
        core.extract_muscles(character, build_surfaces=False, options={"filters.continuousEvidence": -1.0})
    # continuousFraction was replaced by the bump floor: an unknown key now
    with pytest.raises(ValueError, match="unknown expert extraction option"):
        core.extract_muscles(character, build_surfaces=False, options={"filters.continuousFraction": 0.6})


def test_bone_roles_and_the_report_say_what_was_analysed(core, arm):
    arm = arm[0]  # (character, truth)
    roles = core.bone_roles(arm)
    assert roles["upper_arm"] == "limb" and roles["forearm"] == "limb" and roles["hand"] == "ignore"
    muscles, report = core.extract_muscles(arm, build_surfaces=False)
    assert len(muscles) >= 5 and report["diagnosis"] == "" and report["analysed"]
    assert 0.03 < report["limb_radius"] < 0.06 and report["scale"] == 1.0 and report["excluded"] == []
    assert report["scale_note"] == ""  # near the reference size (0.74-0.83 of it)
    # Overrides reach the core; with every bone ignored the report says why.
    off = {name: "ignore" for name in roles}
    assert set(core.bone_roles(arm, off).values()) == {"ignore"}
    muscles, report = core.extract_muscles(arm, bone_roles=off, build_surfaces=False)
    assert muscles == [] and not report["analysed"]
    assert "no limb chain recognised" in report["diagnosis"]
    with pytest.raises(ValueError, match="unknown bone role 'wing'"):
        core.extract_muscles(arm, bone_roles={"forearm": "wing"})
    with pytest.raises(ValueError, match="names no bone"):
        core.bone_roles(arm, {"tail": "limb"})


def test_several_meshes_load_as_one_character_or_one_by_name(core):
    path = shared("characters/quaternius_woman_soldier/woman_soldier.glb")
    whole = core.load_character(path, require_weights=True)
    assert [p[0] for p in whole.pieces] == ["Soldier_Body", "Soldier_Feet", "Soldier_Head", "Soldier_Legs"]
    assert sum(p[2] for p in whole.pieces) == whole.source_vertex_count == 15836
    # Every stored vertex maps to a welded one and every welded vertex has one (an array of one repeated index, as a
    # 1-D numpy array built with pybind11 2.10's count constructor gave, fails here).
    welded = np.asarray(whole.source_to_welded)
    assert welded.shape == (15836,) and np.array_equal(np.unique(welded), np.arange(whole.num_vertices))
    feet = core.load_character(path, require_weights=True, mesh="Soldier_Feet")
    assert feet.source_vertex_count == 2096 and [p[0] for p in feet.pieces] == ["Soldier_Feet"]
    muscles, report = core.extract_muscles(whole, build_surfaces=False)
    assert report["excluded"] and {e["reason"] for e in report["excluded"]} <= {"small", "rigid"}
    assert all(e["bone"] == "Head" for e in report["excluded"])


def test_make_synthetic_body_kinds_names_and_errors(core):
    """The varied characters of issue 13 from Python: truth per kind, names per scheme, split meshes, bad options."""
    character, truth = core.make_synthetic_body(seed=1, kind="quadruped", naming="german", split=True)
    assert len(truth) == 16 and len(character.pieces) == 3
    assert "Oberschenkel.L" in character.bone_names and truth[0]["bone"] in character.bone_names
    assert np.asarray(truth[0]["center_line"]).shape[1] == 3
    _, smooth = core.make_synthetic_body(seed=1, muscle_scale=0.0)
    assert smooth == []
    for bad in (dict(kind="snake"), dict(naming="klingon"), dict(scale=0.0), dict(muscle_scale=-1.0)):
        with pytest.raises(ValueError):
            core.make_synthetic_body(**bad)


ANATOMICAL = {"biceps": {"biceps", "brachialis"}, "triceps": {"triceps"}, "quadriceps": {"quadriceps"},
              "hamstrings": {"hamstrings"}, "calf": {"gastrocnemius"}, "tibialis_anterior": {"tibialis_anterior"}}


def _stem_and_side(name):
    stem, _, side = name.rpartition(".") if "." in name else (name, "", "")
    return re.sub(r"_\d+$", "", stem), side


def _nearest_true_muscle(truth, muscle):
    """The true muscle whose centre line lies nearest, on average, to the found muscle's section centres."""
    centres = np.asarray(muscle.section_centers)
    return min(truth, key=lambda t: np.mean(
        [np.min(np.linalg.norm(np.asarray(t["center_line"]) - p, axis=1)) for p in centres]))


@pytest.mark.figures
def test_anatomical_names_agree_with_the_generators_truth(core):
    """Held-out generated bodies (seeds 20-23, biped and quadruped): a muscle named for its place (biceps.L,
    calf.R, ...) lies nearest a true muscle of that name and side (the generator's brachialis, in front of the
    humerus, counts as biceps; its gastrocnemius is the calf)."""
    checked, wrong = 0, []
    for kind in ("biped", "quadruped"):
        for seed in range(20, 24):
            character, truth = core.make_synthetic_body(seed=seed, kind=kind)
            muscles, _ = core.extract_muscles(character, build_surfaces=False)
            for m in muscles:
                stem, side = _stem_and_side(m.name)
                if stem not in ANATOMICAL:
                    continue
                nearest = _nearest_true_muscle(truth, m)
                true_stem, true_side = nearest["name"].rsplit(".", 1)
                checked += 1
                if true_stem not in ANATOMICAL[stem] or true_side != side:
                    wrong.append((kind, seed, m.name, nearest["name"]))
    print(f"{checked} anatomical names checked, {len(wrong)} disagree: {wrong}")
    assert checked >= 60 and len(wrong) <= 0.05 * checked, wrong


REGION_OF_TRUTH = {"biceps": "upper_arm", "brachialis": "upper_arm", "triceps": "upper_arm",
                   "forearm_extensors": "forearm", "forearm_flexors": "forearm", "quadriceps": "thigh",
                   "hamstrings": "thigh", "gastrocnemius": "shin", "tibialis_anterior": "shin"}
REGION_NAME = re.compile(r"^(?:(upper_arm|forearm|hand|thigh|shin|foot|shoulder|neck)_(?:front|back|outer|inner|top|bottom)"
                         r"|chest|back|belly|flank)$")


@pytest.mark.figures
def test_muscles_no_place_names_anatomically_are_named_by_region_and_side(core):
    """Held-out generated bodies (seeds 20-23, biped and quadruped): every muscle has an anatomical or a region name
    (forearm_front.L, shin_outer.R, flank.L: never the bone and its axis), and a limb region names the segment and
    side of the true muscle nearest to it."""
    checked, wrong = 0, []
    for kind in ("biped", "quadruped"):
        for seed in range(20, 24):
            character, truth = core.make_synthetic_body(seed=seed, kind=kind)
            muscles, _ = core.extract_muscles(character, build_surfaces=False)
            assert muscles
            for m in muscles:
                stem, side = _stem_and_side(m.name)
                if stem in ANATOMICAL or stem in ("pectoral", "deltoid", "abdominal", "back"):
                    continue
                match = REGION_NAME.match(stem)
                assert match, (kind, seed, m.name)
                if match.group(1) not in ("upper_arm", "forearm", "thigh", "shin"):
                    continue
                nearest = _nearest_true_muscle(truth, m)
                true_stem, true_side = nearest["name"].rsplit(".", 1)
                checked += 1
                if REGION_OF_TRUTH.get(true_stem) != match.group(1) or true_side != side:
                    wrong.append((kind, seed, m.name, nearest["name"]))
    print(f"{checked} region names checked, {len(wrong)} disagree: {wrong}")
    assert checked >= 20 and len(wrong) <= 0.05 * checked, wrong


def test_makehuman_muscles_are_named_anatomically(core):
    character = core.load_character(shared(MUSCULAR))
    names = {m.name for m in core.extract_muscles(character, build_surfaces=False)[0]}
    print(sorted(names))
    for stem in ("biceps", "triceps", "quadriceps", "calf", "pectoral"):
        assert {stem + ".L", stem + ".R"} <= names, stem
    assert len(names) == len(core.extract_muscles(character, build_surfaces=False)[0])  # unique


@pytest.mark.parametrize("relative", ["characters/quaternius_horse/horse.glb",
                                      "characters/quaternius_woman_soldier/woman_soldier.glb", MUSCULAR])
def test_mirror_twins_share_one_name(core, relative):
    """A muscle and its mirror image on the other side get one name, number included (what pairs .L with .R by
    name sees one muscle): every X.L has an X.R whose mean section centre mirrors its own (these bodies mirror
    about x = 0) within the larger of the two muscles' mean semi-axes a. Before, the horse's upper arms were biceps.L
    and upper_arm_inner.R (its neck turns 1 degree sideways, which tilted the axes the names are read in), and on all
    three the numbers crossed over (MakeHuman's triceps.L, 5 sections, was the mirror of triceps_2.R)."""
    character = core.load_character(shared(relative))
    muscles = core.extract_muscles(character, build_surfaces=False)[0]
    by_name = {m.name: m for m in muscles}
    sided = [n for n in by_name if n.endswith((".L", ".R"))]
    print(sorted(sided))
    assert len(sided) >= 6
    for name in sided:
        twin = name[:-2] + (".R" if name.endswith(".L") else ".L")
        assert twin in by_name, (name, sorted(by_name))
        a, b = by_name[name], by_name[twin]
        centre = np.asarray(a.section_centers).mean(axis=0)
        mirrored = np.asarray(b.section_centers).mean(axis=0) * [-1.0, 1.0, 1.0]
        reach = max(np.mean(a.section_a), np.mean(b.section_a))
        assert np.linalg.norm(centre - mirrored) < reach, (name, twin, centre, mirrored, reach)
    # And the other way: muscles that are each other's nearest mirror image within that reach share one name.
    centres = {m.name: np.asarray(m.section_centers).mean(axis=0) for m in muscles}
    reach = {m.name: float(np.mean(m.section_a)) for m in muscles}

    def nearest_mirror(name):
        others = [o for o in centres if centres[o][0] * centres[name][0] < 0]
        distance = {o: np.linalg.norm(centres[o] * [-1.0, 1.0, 1.0] - centres[name]) for o in others}
        best = min(distance, key=distance.get, default=None)
        return best if best is not None and distance[best] < max(reach[name], reach[best]) else None

    pairs = [(n, nearest_mirror(n)) for n in centres if nearest_mirror(n) and nearest_mirror(nearest_mirror(n)) == n]
    assert len(pairs) >= 6
    for name, twin in pairs:
        assert name[:-2] == twin[:-2], (name, twin)


USER_FACING = ("spacing", "min_confidence", "min_sections", "max_per_region", "joint_wrap")


def test_extract_muscles_has_five_documented_user_facing_options(core):
    """At most 6 user-facing numeric options, each documented; masks, roles and surfaces are data; the rest expert."""
    doc = core.extract_muscles.__doc__
    signature = doc.splitlines()[0]
    numeric = [a.split(":")[0].strip() for a in signature.split("(", 1)[1].split(", ")
               if ": float" in a or ": int" in a]
    assert tuple(numeric) == USER_FACING and len(numeric) <= 6, signature
    for name in USER_FACING + ("vertex_mask", "forced_regions", "bone_roles", "build_surfaces", "options"):
        assert f"  {name}:" in doc or f"{name} (" in doc or f"{name}: " in doc, name
    assert "limb radii" in doc  # spacing is body-relative
    expert = core.extraction_options()
    assert len(expert) > 40 and expert["filters.minEvidence"] == 6.6 and expert["ends.spanDistal"] is True
    assert not {"filters.minConfidence", "link.minSections", "ends.jointWrapFraction", "scale.spacing"} & set(expert)


def test_continuous_scale_reaches_the_core(core):
    """options={"scale.continuous": True}: the body is analysed at the reference limb radius exactly (the horse, 2.5
    times it: the default report notes that, the continuous one does not)."""
    horse = core.load_character(shared("characters/quaternius_horse/horse.glb"))
    default, report = core.extract_muscles(horse, build_surfaces=False)
    muscles, continuous = core.extract_muscles(horse, build_surfaces=False, options={"scale.continuous": True})
    assert report["scale"] == 1.0 and "scale.continuous" in report["scale_note"]
    assert abs(continuous["scale"] * continuous["limb_radius"] - 0.0554) < 1e-12 and continuous["scale_note"] == ""
    assert len(default) > 0 and len(muscles) > 0


def test_expert_options_reach_the_core(core):
    """An expert override changes the result on a real character; passing every default changes nothing."""
    character = core.load_character(shared(MUSCULAR))
    default, report = core.extract_muscles(character, build_surfaces=False)
    same, _ = core.extract_muscles(character, build_surfaces=False, options=core.extraction_options())
    assert len(default) > 0 and [m.name for m in same] == [m.name for m in default]
    assert all(np.array_equal(a.root_curve, b.root_curve) for a, b in zip(same, default))
    strict, strict_report = core.extract_muscles(character, build_surfaces=False,
                                                 options={"filters.minEvidence": 12.0, "filters.spindleEnds": 0.0})
    assert len(strict) < len(default), (len(strict), len(default))
    assert strict_report["dropped_short"] > report["dropped_short"]
    # Spacing in limb radii: the automatic one (1/80 of the extent) is about 0.4 limb radii on this body.
    coarse, coarse_report = core.extract_muscles(character, build_surfaces=False, spacing=3.0)
    assert 0 < coarse_report["planes"] < report["planes"], (coarse_report["planes"], report["planes"])


def test_old_expert_keywords_raise_type_error_bad_values_value_error(core, arm):
    character, _ = arm
    for old, key in (("min_evidence", "filters.minEvidence"), ("twin_reach", "filters.twinReach"),
                     ("mirror_limbs", "profiles.mirrorLimbs"), ("span_distal", "ends.spanDistal"),
                     ("weak_fraction", "sectionBumps.weakFraction")):
        with pytest.raises(TypeError, match=key):
            core.extract_muscles(character, **{old: 1.0})
    with pytest.raises(TypeError, match="no_such_option"):
        core.extract_muscles(character, no_such_option=1.0)
    with pytest.raises(TypeError, match="continuous_fraction' was removed"):
        core.extract_muscles(character, continuous_fraction=0.6)
    with pytest.raises(ValueError, match="unknown expert extraction option"):
        core.extract_muscles(character, options={"filters.nothing": 1.0})
    with pytest.raises(ValueError, match="integer"):
        core.extract_muscles(character, options={"link.maxGap": 2.5})
    with pytest.raises(ValueError, match="number or a bool"):
        core.extract_muscles(character, options={"filters.minEvidence": "high"})
    with pytest.raises(ValueError, match="number or a bool"):
        core.extract_muscles(character, options={"filters.minEvidence": None})
    # numpy scalars are numbers (as read from an array of settings): the same muscles as the Python numbers give
    plain, _ = core.extract_muscles(character, build_surfaces=False, options={"link.maxGap": 2, "filters.minEvidence": 5.0})
    typed, _ = core.extract_muscles(character, build_surfaces=False,
                                    options={"link.maxGap": np.int64(2), "filters.minEvidence": np.float32(5.0)})
    assert [m.name for m in typed] == [m.name for m in plain]
    with pytest.raises(TypeError, match="dict"):
        core.extract_muscles(character, options=[("filters.minEvidence", 1.0)])
    for bad in (dict(min_confidence=1.5), dict(min_sections=0), dict(max_per_region=-1), dict(joint_wrap=-0.1),
                dict(spacing=float("nan"))):
        with pytest.raises(ValueError, match=next(iter(bad))):
            core.extract_muscles(character, **bad)


def test_the_round_off_blenders_importer_leaves_moves_no_muscle(core):
    """Issue 13 item 2 (the CLI and the add-on give the same muscles for the same file), without Blender: Blender's
    glTF importer hands the add-on makehuman_muscular_male's skin re-posed in float32, a 8e-6 scale along the body's
    height, and bone tails 1.2e-7 m off their joints (benchmarks/bench_roundoff.py applies each to the character
    the core loads). Every muscle stays within 1 % of the limb radius. Until a clipped (shoulder) profile's base
    support faded over a margin of its tolerance, the 8e-6 scale moved pectoral.R 0.059 limb radii: whether one vertex
    lay within the tolerance sent one section's base refits another way."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "bench_roundoff", os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks", "bench_roundoff.py"))
    bench_roundoff = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_roundoff)

    c = core.load_character(shared(MUSCULAR), require_weights=True)
    base, report = core.extract_muscles(c)
    assert len(base) >= 12, [m.name for m in base]
    rows = []
    for what, perturbed in bench_roundoff.perturbations(c):
        muscles, _ = core.extract_muscles(perturbed)
        rows.append((what,) + tuple(bench_roundoff.compare(base, muscles, report["limb_radius"])))
    print("\n".join(f"  {what}: largest move {worst:.2e} limb radii, names differ {names}, over 1 % {over}"
                    for what, names, worst, over in rows))
    assert len(rows) == 3
    for what, names, worst, over in rows:
        assert not names and not over and worst <= 0.01, (what, names, worst, over)
