"""Skin quality at bent joints (benchmarks/skin_quality.py's measures, the figures the README's table shows):
what the default rig (muscle joints + Preserve Volume) achieves against plain LBS and DQS, asserted on
makehuman_muscular_male, on a generated biped the detection was not tuned on and on Quaternius' woman soldier
(held out: nothing was tuned on it)."""
import os
import sys

import numpy as np
import pytest

from conftest import MUSCULAR, shared

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import skin_quality  # noqa: E402


def rows_by_joint(core, character, joints, facing=(0.0, 0.0, 1.0)):
    muscles, _ = core.extract_muscles(character)
    assert len(muscles) >= 4
    rows = {r["label"]: r for r in skin_quality.measure(core, character, muscles, joints, facing=facing)}
    assert rows, "no joint measured"
    for label, r in rows.items():
        print(f"{label}: band LBS {100 * r['lbs']:+.1f} %, DQS {100 * r['dqs']:+.1f} %, Myoskin "
              f"{100 * r['myoskin']:+.1f} %, +PV {100 * r['myoskin_pv']:+.1f} %; bulge over LBS "
              f"{r['bulge'] / r['limb_radius']:.3f} r, +PV over DQS {r['bulge_pv_over_dqs'] / r['limb_radius']:.3f} r; "
              f"crossings {r['crossings_lbs']}/{r['crossings_dqs']}/{r['crossings_myoskin']}/{r['crossings_myoskin_pv']}")
    return rows


@pytest.fixture(scope="module")
def makehuman(core):
    character = core.load_character(shared(MUSCULAR), require_weights=True)
    return rows_by_joint(core, character, skin_quality.MAKEHUMAN_JOINTS)


def test_makehuman_elbow_keeps_volume_bulges_and_folds_less_than_lbs_and_dqs(makehuman):
    elbow = makehuman["elbow flexion"]
    assert elbow["lbs"] < -0.2  # the joint collapses under plain LBS (the measure can fail)
    assert abs(elbow["myoskin_pv"]) <= 0.5 * abs(elbow["lbs"])
    assert abs(elbow["myoskin_pv"]) <= abs(elbow["dqs"])
    assert elbow["crossings_myoskin_pv"] <= elbow["crossings_lbs"]
    assert elbow["bulge_pv_over_dqs"] >= 0.15 * elbow["limb_radius"]  # the biceps rises over the DQS skin
    # linear blending too: the muscles no longer fold the crease deeper than the skeleton alone
    assert abs(elbow["myoskin"]) < abs(elbow["lbs"]) and elbow["bulge"] > 0.1 * elbow["limb_radius"]


def test_makehuman_knee_keeps_volume_and_no_muscle_spikes(makehuman):
    knee = makehuman["knee flexion"]
    assert knee["lbs"] < -0.3
    assert abs(knee["myoskin_pv"]) <= 0.5 * abs(knee["lbs"])
    assert abs(knee["myoskin_pv"]) <= abs(knee["dqs"])  # the calf attaches near the knee: no pinch
    assert knee["crossings_myoskin_pv"] <= knee["crossings_lbs"]
    # the calf crossing the knee does not lift the back of the knee (it lifted it by 0.61 limb radii)
    assert knee["bulge"] < 0.2 * knee["limb_radius"]
    assert knee["bulge_pv_over_dqs"] < 0.2 * knee["limb_radius"]


def test_makehuman_shoulder_and_hip_stay_within_dqs_of_the_skeleton(makehuman):
    """At the shoulder and hip the rig stays close to the skeleton's own mode. The clavicular pectoral (clavicle ->
    humerus) no longer drags the skin the skeleton shares between the trunk and the arm (borderRelief): the
    shoulder band went from -27.6 % with 16 crossings to -25.6 % with 3 (LBS -62.7 % / 6, DQS -24.8 % / 0). Not met
    (issue 14 item 3): the shoulder is still 0.8 points past DQS; the hip keeps DQS's +24.1 % (half of LBS: 12 %)."""
    shoulder, hip = makehuman["shoulder abduction"], makehuman["hip flexion"]
    assert shoulder["lbs"] < -0.4
    assert abs(shoulder["myoskin_pv"]) <= 0.5 * abs(shoulder["lbs"])
    assert abs(shoulder["myoskin_pv"]) <= abs(shoulder["dqs"]) + 0.015
    assert shoulder["crossings_myoskin_pv"] <= shoulder["crossings_lbs"]
    assert abs(shoulder["myoskin"] - shoulder["lbs"]) < 0.02
    assert abs(hip["myoskin_pv"] - hip["dqs"]) < 0.01


def test_makehuman_ankle_plantar_flexion_keeps_volume(makehuman):
    """Plantar flexion (45 degrees, toes down): the ankle band keeps its volume and does not fold, and the calf,
    carried onto the heel (EndOptions::spanDistal), rises over LBS: 0.030 limb radii (0.008 when it ended on the
    lower leg). Its bulge inside the band adds 0.1 point of volume over DQS's (+1.0 % against +0.9 %)."""
    ankle = makehuman["ankle plantar flexion"]
    assert ankle["lbs"] < -0.02
    assert abs(ankle["myoskin_pv"]) <= 0.5 * abs(ankle["lbs"])
    assert abs(ankle["myoskin_pv"]) <= abs(ankle["dqs"]) + 0.005
    assert ankle["crossings_myoskin_pv"] <= ankle["crossings_lbs"]
    assert ankle["bulge"] >= 0.02 * ankle["limb_radius"]  # the calf shortens on plantar flexion
    assert ankle["bulge_pv_over_dqs"] < 0.1 * ankle["limb_radius"]  # what holds: no spike from the muscles


def test_held_out_soldier_elbow_and_knee_within_dqs(core):
    """Quaternius' woman soldier (held out). Measured: elbow LBS -49.0 %, DQS -28.4 %, +PV -27.8 % (half of LBS,
    24.5 %, not met); knee LBS -30.8 %, DQS +18.8 %, +PV +19.6 % (the muscles add 0.8 points to DQS's bulge)."""
    character = core.load_character(shared("characters/quaternius_woman_soldier/woman_soldier.glb"),
                                    require_weights=True)
    rows = rows_by_joint(core, character, skin_quality.QUATERNIUS_JOINTS)
    elbow, knee = rows["elbow flexion"], rows["knee flexion"]
    assert elbow["lbs"] < -0.3 and knee["lbs"] < -0.2
    assert abs(elbow["myoskin_pv"]) <= abs(elbow["dqs"])
    assert abs(elbow["myoskin_pv"]) <= 0.6 * abs(elbow["lbs"])
    assert abs(knee["myoskin_pv"] - knee["dqs"]) < 0.02
    for r in (elbow, knee):
        assert r["crossings_myoskin_pv"] <= r["crossings_lbs"], r["label"]


@pytest.mark.figures
def test_generated_biped_elbow_and_knee(core):
    """A held-out generated body (seed 21; the generator's acceptance seeds are 20-27): Z up, facing -Y."""
    character, _truth = core.make_synthetic_body(seed=21)
    rows = rows_by_joint(core, character, skin_quality.SYNTHETIC_BODY_JOINTS, facing=(0.0, -1.0, 0.0))
    for label in ("elbow flexion", "knee flexion"):
        r = rows[label]
        assert r["lbs"] < -0.2, label
        assert abs(r["myoskin_pv"]) <= 0.5 * abs(r["lbs"]), label
        assert r["crossings_myoskin_pv"] <= r["crossings_lbs"], label
        assert np.isfinite(r["bulge"]) and r["bulge"] < 0.3 * r["limb_radius"], label  # no spike
    assert rows["elbow flexion"]["bulge"] > 0.05 * rows["elbow flexion"]["limb_radius"]
    ankle = rows["ankle plantar flexion"]  # LBS -9.5 %, DQS and +PV -2.1 %: no muscle crosses the ankle
    assert ankle["lbs"] < -0.05
    assert abs(ankle["myoskin_pv"]) <= 0.5 * abs(ankle["lbs"])
    assert abs(ankle["myoskin_pv"]) <= abs(ankle["dqs"]) + 1e-3
    assert ankle["crossings_myoskin_pv"] <= ankle["crossings_lbs"]



def _assert_joint_targets(rows, labels):
    """Issue 14 item 3 on the default Bind (volume blend + volume keys: myoskin_vk): the band's change at most half of
    LBS's and no larger than DQS's (to 0.1 point: DQS here is numpy's, the blend the core's skinner), no more
    self-intersecting triangle pairs than LBS."""
    checked = 0
    for label in labels:
        r = rows[label]
        print(f"{label}: LBS {100 * r['lbs']:+.1f} %, DQS {100 * r['dqs']:+.1f} %, volume blend "
              f"{100 * r['myoskin_vb']:+.1f} %, + keys {100 * r['myoskin_vk']:+.1f} %; crossings LBS "
              f"{r['crossings_lbs']}, + keys {r['crossings_myoskin_vk']}")
        assert r["lbs"] < -0.1, label  # the joint really collapses under LBS (the measure can fail)
        assert meets_joint_target(r), label
        checked += 1
    assert checked == len(labels) > 0


def meets_joint_target(r):
    return (r["lbs"] < -0.1 and abs(r["myoskin_vk"]) <= 0.5 * abs(r["lbs"]) and abs(r["myoskin_vk"]) <= abs(r["dqs"]) + 1e-3
            and r["crossings_myoskin_vk"] <= r["crossings_lbs"])


def test_bend_sweep_agrees_with_the_measure_and_makehumans_knee_and_shoulder_never_fold_more_than_lbs(core, makehuman):
    """The benchmark's bend sweep (skin_quality.fold_sweep: Bind done once, each joint bent 30-150 degrees by 15) gives
    at the table's angle (120) what measure gives, and on MakeHuman the knee and the shoulder fold no more than LBS at
    any angle of the sweep. Measured: knee 0-17 pairs (LBS 0-26), shoulder 0 (LBS 0-8); the elbow folds 23 pairs at 75
    degrees where LBS folds 20 (not asserted)."""
    character = core.load_character(shared(MUSCULAR), require_weights=True)
    muscles, _ = core.extract_muscles(character)
    table = [j for j in skin_quality.MAKEHUMAN_JOINTS if j[0] in ("elbow flexion", "knee flexion", "shoulder abduction")]
    swept = skin_quality.fold_sweep(core, character, muscles, table)
    sweep = {j["label"]: j["rows"] for j in swept}
    at_rest_of = {j["label"]: j["crossings_at_rest"] for j in swept}
    assert list(sweep) == ["elbow flexion", "knee flexion", "shoulder abduction"]
    for label, rows in sweep.items():
        assert [r["degrees"] for r in rows] == list(range(30, 151, 15))
        row, r = rows[6], makehuman[label]  # 120 degrees, the table's angle for all three
        assert (row["crossings_lbs"], row["crossings_myoskin_vk"]) == (r["crossings_lbs"], r["crossings_myoskin_vk"])
        assert (row["crumples_lbs"], row["crumples_myoskin_vk"]) == (r["crumples_lbs"], r["crumples_myoskin_vk"])
        assert row["lbs"] == pytest.approx(r["lbs"], abs=1e-9)
        assert row["myoskin_vk"] == pytest.approx(r["myoskin_vk"], abs=1e-9)
        at_rest = at_rest_of[label]
        for q in rows:  # crumples are new crossings (none of the rest's)
            assert 0 <= q["crumples_lbs"] <= q["crossings_lbs"] + at_rest
            assert 0 <= q["crumples_myoskin_vk"] <= q["crossings_myoskin_vk"] + at_rest
        if label != "elbow flexion":
            assert max(q["crossings_lbs"] for q in rows) > 0  # LBS itself folds somewhere in the sweep (it can fail)
            for q in rows:
                assert q["crossings_myoskin_vk"] <= q["crossings_lbs"], (label, q)


@pytest.mark.figures
def test_sliding_muscle_joints_crumple_an_elbow_that_lbs_does_not_unless_their_slide_is_limited(core):
    """Generated biped 11's elbow at 60 and 90 degrees (the bend sweep's diagnosis, README "Joints that do not slide"):
    LBS crumples nothing there; Bind's skin with freely sliding muscle joints crumples (the upper arm's muscles carry
    skin towards the shoulder: measured 12 and 31 pairs), with joints_slide=False far less (7 and 7), and so with the
    slide limits Bind gives sliding joints (core.slide_limits: no further than the skin they carry follows unfolded)."""
    character, _truth = core.make_synthetic_body(seed=11)
    muscles, _ = core.extract_muscles(character)
    elbow = [j for j in skin_quality.SYNTHETIC_BODY_JOINTS if j[0] == "elbow flexion"]
    crumpled = {}
    for name, rig_options, limit in (("free", {}, False), ("limited", {}, True), ("off", dict(joints_slide=False), True)):
        bound = skin_quality.bind_skin(core, character, muscles, rig_options=rig_options, slide_limit=limit)
        assert (np.asarray(bound[0].slide_limits) > 0).any() == (name == "limited"), name
        (sweep,) = skin_quality.fold_sweep(core, character, muscles, elbow, facing=(0.0, -1.0, 0.0), degrees=(60, 90),
                                           bound=bound)
        assert [r["degrees"] for r in sweep["rows"]] == [60, 90]
        assert all(r["crumples_lbs"] == 0 for r in sweep["rows"])
        crumpled[name] = [r["crumples_myoskin_vk"] for r in sweep["rows"]]
    print(f"biped 11's elbow at 60 / 90 degrees, crumpled pairs: {crumpled}")
    assert crumpled["free"][1] >= 10
    assert sum(crumpled["off"]) <= 0.5 * sum(crumpled["free"])
    assert sum(crumpled["limited"]) <= 0.5 * sum(crumpled["free"])


@pytest.mark.figures
def test_slide_limits_take_out_most_crumples_of_held_out_bipeds_and_leave_makehuman(core):
    """The slide limits (core.slide_limits, on in Bind) on generated bipeds nothing was tuned on: over the elbow and
    knee sweeps (30-150 degrees) the crumples (skin folding on itself) fall by more than half, and no more (joint,
    angle) cases fold more than LBS than with free joints. On makehuman_muscular_male, whose coarse skin's muscle
    weights fade over more than a limb radius, the limits are at least half a limb radius and its elbow's band and
    biceps bulge stay within 0.5 point and 0.005 limb radii of the free joints'."""
    knee_elbow = [j for j in skin_quality.SYNTHETIC_BODY_JOINTS if j[0] in ("elbow flexion", "knee flexion")]
    totals = {False: [0, 0], True: [0, 0]}
    for seed in (20, 22, 25):
        character, _truth = core.make_synthetic_body(seed=seed)
        muscles, _ = core.extract_muscles(character)
        for limit in (False, True):
            bound = skin_quality.bind_skin(core, character, muscles, slide_limit=limit)
            sweep = skin_quality.fold_sweep(core, character, muscles, knee_elbow, facing=(0.0, -1.0, 0.0), bound=bound)
            assert len(sweep) == 2
            rows = [r for joint in sweep for r in joint["rows"]]
            totals[limit][0] += sum(r["crumples_myoskin_vk"] for r in rows)
            totals[limit][1] += sum(r["crossings_myoskin_vk"] > r["crossings_lbs"] for r in rows)
    print(f"held-out bipeds 20, 22, 25, elbow and knee sweeps: crumples free {totals[False][0]}, limited "
          f"{totals[True][0]}; cases folding more than LBS free {totals[False][1]}, limited {totals[True][1]}")
    assert totals[True][0] <= 0.5 * totals[False][0]
    assert totals[True][1] <= totals[False][1]
    character = core.load_character(shared(MUSCULAR), require_weights=True)
    muscles, report = core.extract_muscles(character)
    elbow = [j for j in skin_quality.MAKEHUMAN_JOINTS if j[0] == "elbow flexion"]
    free, limited = (skin_quality.measure(core, character, muscles, elbow, bound=skin_quality.bind_skin(
        core, character, muscles, slide_limit=limit))[0] for limit in (False, True))
    limits = np.asarray(skin_quality.bind_skin(core, character, muscles)[0].slide_limits)
    assert (limits > 0).any()
    assert limits[limits > 0].min() >= 0.5 * report["limb_radius"]
    assert abs(limited["myoskin_pv"] - free["myoskin_pv"]) <= 0.005
    assert abs(limited["bulge"] - free["bulge"]) <= 0.005 * report["limb_radius"]


def test_volume_keys_keep_makehumans_joints(makehuman):
    """MakeHuman: elbow and knee at 120 degrees, shoulder abduction 120, hip flexion 90 (the keys sample 45, 90 and
    135 degrees, fitted on Bind's skin). Measured: elbow +0.8 % (LBS -45.5; crossings 30, LBS 61), knee +0.6 %
    (-61.3; crossings 13, LBS 14), shoulder -17.1 % (-62.7; DQS -24.8), hip -3.2 % (-24.1)."""
    _assert_joint_targets(makehuman, ["elbow flexion", "knee flexion", "shoulder abduction", "hip flexion"])


@pytest.mark.parametrize("name, path, joints", [
    ("soldier", "characters/quaternius_woman_soldier/woman_soldier.glb",
     ["elbow flexion", "knee flexion", "shoulder abduction", "hip flexion"]),
    ("horse", "characters/quaternius_horse/horse.glb", ["front knee", "hind hock"]),
])
def test_volume_keys_keep_the_joints_of_characters_nobody_here_made(core, name, path, joints):
    """Quaternius' soldier (four meshes, x100) and horse (a quadruped, x100). Measured: soldier elbow -0.7 % (LBS
    -49.0), knee -0.9 % (-30.8), shoulder abduction 60 degrees -6.5 % (-28.6), hip +1.1 % (-26.8); horse front knee
    -8.4 % (-42.9), hind hock -4.1 % (-22.8; the blend alone -15.3)."""
    character = core.load_character(shared(path), require_weights=True)
    table = skin_quality.HORSE_JOINTS if name == "horse" else skin_quality.QUATERNIUS_JOINTS
    rows = rows_by_joint(core, character, table)
    _assert_joint_targets(rows, joints)
    if name == "horse":  # the hock's key gives back most of what the blend loses (the outer side's swell alone: -4.9 %;
        # stop 40's key +1.4 %: the key chosen by its 45 / 90 / 135-degree samples leaves more at 60, a regression)
        assert abs(rows["hind hock"]["myoskin_vk"]) <= 0.3 * abs(rows["hind hock"]["myoskin_vb"])
        assert rows["hind hock"]["myoskin_vk"] > -0.045


@pytest.mark.figures
def test_volume_keys_keep_held_out_generated_bipeds_joints(core):
    """Issue 14 item 3 on the generated bipeds nothing was tuned on (seeds 20-27): elbow and knee 120, shoulder
    abduction 90 degrees (their hips lie deeper inside the pelvis than 1.5 body limb radii from any skin: the band
    measure has nothing to measure there). Measured: 21 of the 24 joints meet the target; every joint of bipeds 20, 21,
    22, 26 and 27 does (22's elbow since the slide limits: 210 -> 169 crossing pairs, LBS 191; they cost 24's elbow, +0.3 %
    against DQS's -0.2 %) (21's shoulder -22.5 %, LBS -51.1, DQS -27.8; 27's elbow +0.1 % with LBS's 158 crossings, once
    its elbow bends forward: `test_an_a_pose_arm_bends_forward_and_a_leg_backward`; 27's knee +0.9 -> -0.0 % and 25's
    +1.3 -> -0.0 % since a key also takes back volume a band gains; 24's elbow -0.9 -> -0.1 % and knee +0.4 -> +0.0 %
    since a key may move the skin away from the joint and is chosen by the volume it keeps). The misses: the shoulders
    of 23 (-29.5 %, half of LBS 28.2) and 25 (the blend alone folds more than LBS) and 24's elbow."""
    met, per_seed = 0, {}
    for seed in range(20, 28):
        character, _truth = core.make_synthetic_body(seed=seed)
        rows = rows_by_joint(core, character, skin_quality.SYNTHETIC_BODY_JOINTS, facing=(0.0, -1.0, 0.0))
        joints = [rows[label] for label in ("elbow flexion", "knee flexion", "shoulder abduction")]
        per_seed[seed] = sum(meets_joint_target(r) for r in joints)
        met += per_seed[seed]
    print(f"held-out bipeds: {met} of 24 joints meet the target; per seed {per_seed}")
    assert len(per_seed) == 8
    assert met >= 21
    assert per_seed[20] == per_seed[21] == per_seed[22] == per_seed[26] == per_seed[27] == 3 and per_seed[25] >= 2


@pytest.mark.figures
def test_a_volume_key_takes_back_the_volume_a_knee_gains(core):
    """Volume keys keep the band's volume both ways: where the volume blend gains volume in a joint's band (held-out
    biped 25's knee: the muscles over it add 1.3 points at 120 degrees, where DQS keeps 0.0), the joint's key pulls
    the skin in along its rest normals instead of pushing it out. Measured: +1.3 % -> -0.0 %, crossings 96 (LBS
    138)."""
    character, _truth = core.make_synthetic_body(seed=25)
    r = rows_by_joint(core, character, skin_quality.SYNTHETIC_BODY_JOINTS, facing=(0.0, -1.0, 0.0))["knee flexion"]
    assert r["myoskin_vb"] > 0.005  # the blend alone gains volume here (the measure can fail)
    assert abs(r["myoskin_vk"]) <= 0.2 * r["myoskin_vb"]
    assert meets_joint_target(r)
    # The knee's key moves the skin inward: its offsets point against the rest normals.
    muscles, _ = core.extract_muscles(character)
    keys = [k for k in skin_quality.bind_skin(core, character, muscles)[4] if k["bone"].startswith("shin")]
    assert len(keys) == 2, [k["bone"] for k in keys]
    normals = np.asarray(core.vertex_normals(np.asarray(character.vertices), np.asarray(character.triangles)))
    for k in keys:
        along = np.einsum("ij,ij->i", np.asarray(k["offsets"]), normals[np.asarray(k["vertices"])])
        assert (along < 0).mean() > 0.9, k["bone"]
        assert max(k["change_without"]) > 0.0 and max(abs(c) for c in k["change_with"]) < max(k["change_without"])


@pytest.mark.figures
@pytest.mark.parametrize("seed", [26, 27])
def test_held_out_biped_calves_span_the_ankle_and_bulge_on_plantar_flexion(core, seed):
    """Issue 14 items 1-2, calves to the heel (EndOptions::spanDistal), on generated bipeds nothing was tuned on
    (tuned on MakeHuman, biped 21 and the soldier): each shin's calf inserts on the foot behind the ankle, so
    plantar flexion (45 degrees, toes down) shortens it and the calf's skin rises over LBS."""
    character, _truth = core.make_synthetic_body(seed=seed)
    facing = np.array([0.0, -1.0, 0.0])  # the generator's bodies face -Y
    names = list(character.bone_names)
    heads = np.asarray(character.bone_heads)
    muscles, _ = core.extract_muscles(character)
    for side in (".L", ".R"):
        ankle = heads[names.index("foot" + side)]
        calves = [m for m in muscles if m.region == "shin" + side and m.insertion_bone == "foot" + side
                  and np.dot(np.asarray(m.insertion) - ankle, facing) < 0]  # behind the ankle: the heel
        assert calves, f"no muscle of shin{side} inserts on the heel"
    ankle_joint = [j for j in skin_quality.SYNTHETIC_BODY_JOINTS if j[0] == "ankle plantar flexion"]
    assert ankle_joint
    on = skin_quality.measure(core, character, muscles, ankle_joint, facing=tuple(facing))
    off_muscles, _ = core.extract_muscles(character, options={"ends.spanDistal": False})
    off = skin_quality.measure(core, character, off_muscles, ankle_joint, facing=tuple(facing))
    assert len(on) == 1 and len(off) == 1
    r, r_off = on[0], off[0]
    radius = r["limb_radius"]
    print(f"seed {seed}: calf bulge over LBS {r['bulge'] / radius:.3f} r (without the carry "
          f"{r_off['bulge'] / radius:.3f} r); band LBS {100 * r['lbs']:+.1f} %, DQS {100 * r['dqs']:+.1f} %, "
          f"+PV {100 * r['myoskin_pv']:+.1f} %, crossings {r['crossings_lbs']}/{r['crossings_myoskin_pv']}")
    assert r["bulge"] >= 0.05 * radius  # the calf rises (biped 21: 0.109 r; the elbow target is 0.15 r)
    assert r["bulge"] >= r_off["bulge"] + 0.03 * radius  # ... because it spans the ankle now
    assert r["bulge"] < 0.3 * radius  # no spike
    assert r["lbs"] < -0.05
    assert abs(r["myoskin_pv"]) <= 0.5 * abs(r["lbs"])
    assert r["crossings_myoskin_pv"] <= r["crossings_lbs"]
