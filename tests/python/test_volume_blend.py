"""The volume blend (issue 14 item 3, "joints keep their volume"): _core.compute_dqs_share and Skinner(dqs_share=)
through the module, `myoskin deform --volume-blend`, and the issue's targets on characters nothing was tuned on
(tuned on makehuman_muscular_male and the generated biped seed 21): makehuman_neutral, Quaternius' woman soldier and
the generated bipeds 20, 22-27. Target: at the bent joints the band's volume change is at most half of LBS's and no
larger than DQS's, with no more crossings than LBS; the joints the Preserve Volume mode already kept stay as they were
(within 1 point)."""
import json
import os
import sys

import numpy as np
import pytest

from conftest import LOWPOLY, NEUTRAL, run_cli, shared

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import skin_quality  # noqa: E402

SOLDIER = "characters/quaternius_woman_soldier/woman_soldier.glb"


def bend(core, character, degrees, bone="forearm", axis=(1, 0, 0)):
    names = list(character.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    half = np.radians(degrees) / 2
    q[names.index(bone)] = [np.cos(half), *(np.sin(half) * np.asarray(axis, dtype=float))]
    return core.pose_from_rotations(character, q)


# ------------------------------------------------------------------------------------------------
# Module
# ------------------------------------------------------------------------------------------------

def test_shares_are_in_range_deterministic_and_share_0_and_1_are_the_two_modes(core):
    character, _truth = core.make_synthetic_body(seed=22)
    share, joints = core.compute_dqs_share(character, with_joints=True)
    share = np.asarray(share)
    assert share.shape == (character.num_vertices,)
    assert share.min() >= 0.0 and share.max() <= 1.0
    assert np.array_equal(share, np.asarray(core.compute_dqs_share(character)))
    assert joints, "no joint measured"
    assert {"bone", "share", "linear_change", "dual_quat_change", "blend_change", "axis"} <= set(joints[0])
    rest = np.asarray(character.vertices)
    args = (rest, character.weight_joints, character.weight_values, character.num_bones)
    bone_rest = np.asarray(character.bone_rest)
    pose = bend(core, character, 110, bone="shin.L")
    t = core.skeleton_transforms(character, pose)
    linear = core.Skinner(*args).deform(t)
    dq = core.Skinner(*args, preserve_volume=True, rest_matrices=bone_rest).deform(t)
    assert np.abs(linear - dq).max() > 1e-3  # the two modes really differ here
    zero = core.Skinner(*args, dqs_share=np.zeros(len(rest)), rest_matrices=bone_rest)
    one = core.Skinner(*args, dqs_share=np.ones(len(rest)), rest_matrices=bone_rest)
    assert zero.volume_blend and one.volume_blend
    assert np.array_equal(zero.deform(t), linear)
    assert np.array_equal(one.deform(t), dq)
    blend = core.Skinner(*args, dqs_share=share, rest_matrices=bone_rest)
    size = float(np.linalg.norm(np.ptp(rest, axis=0)))
    assert np.abs(blend.deform(core.skeleton_transforms(character, np.asarray(character.bone_rest))) - rest).max() \
        < 1e-6 * size


def test_bad_shares_and_options_are_value_errors(core):
    character, _truth = core.make_synthetic_body(seed=20)
    n = character.num_vertices
    args = (character.vertices, character.weight_joints, character.weight_values, character.num_bones)
    with pytest.raises(ValueError, match=f"{n - 1} dual-quaternion shares for {n} vertices"):
        core.Skinner(*args, dqs_share=np.full(n - 1, 0.5))
    for bad in (np.nan, 1.5, -0.1):
        share = np.full(n, 0.5)
        share[3] = bad
        with pytest.raises(ValueError, match="vertex 3 has a dual-quaternion share"):
            core.Skinner(*args, dqs_share=share)
    with pytest.raises(ValueError, match="dqs_share must be #V values"):
        core.Skinner(*args, dqs_share=np.full((n, 2), 0.5))
    with pytest.raises(ValueError, match="bendDegrees"):
        core.compute_dqs_share(character, bend_degrees=0.0)
    with pytest.raises(ValueError, match="bandRadius"):
        core.compute_dqs_share(character, band_radius=-1.0)
    with pytest.raises(ValueError, match="keepTolerance"):
        core.compute_dqs_share(character, keep_tolerance=2.0)
    with pytest.raises(ValueError, match="up must be"):
        core.compute_dqs_share(character, up=(0.0, 0.0, 0.0))
    rig = core.MuscleRig(character, [])
    with pytest.raises(ValueError, match="come together"):  # Bind's skin: the rig with its hybrid weights
        core.compute_volume_keys(character, np.full(n, 0.5), rig=rig)
    with pytest.raises(ValueError, match="dq_scale must be"):
        core.compute_volume_keys(character, np.full(n, 0.5), dq_scale="linear")


def test_cli_deform_volume_blend_matches_the_module(core, tmp_path):
    assert run_cli("generate", "arm", "-o", str(tmp_path)).returncode == 0
    assert run_cli("extract", str(tmp_path / "arm.obj"), "-o", str(tmp_path / "m.json")).returncode == 0
    character = core.load_character(str(tmp_path / "arm.obj"))
    seq = {"frames": [{"bones": {"forearm": {"rotation_axis_angle": [a, 1, 0, 0]}}} for a in (0, 120)]}
    (tmp_path / "seq.json").write_text(json.dumps(seq))
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "out.pc2"), "--volume-blend")
    assert r.returncode == 0, r.stderr
    assert "volume blend" in r.stdout
    frames = core.read_pc2(str(tmp_path / "out.pc2"))["frames"]
    pose = bend(core, character, 120)
    rig, joints, weights = skin_quality.bound_rig(core, character, core.read_muscles(str(tmp_path / "m.json")))
    t = core.skinning_transforms(character, pose, rig, rig.evaluate(pose)["joint_matrices"])
    rest = core.combined_rest_matrices(character, rig)
    share = core.compute_dqs_share(character)
    keys = core.compute_volume_keys(character, share, rig=rig, weight_joints=joints, weight_values=weights)  # maybe none
    assert f"volume blend with {len(keys)} volume keys" in r.stdout
    keyed = skin_quality.with_volume_keys(core, character, character.vertices, keys, pose)
    expected = core.skin(keyed, joints, weights, t, dqs_share=share, rest_matrices=rest)
    assert np.abs(frames[0] - character.vertices).max() < 1e-6
    assert np.abs(frames[1] - expected).max() < 1e-5
    # --joints-slide off: the rig of MuscleRig(joints_slide=False), its volume keys fitted on it (the add-on's Joints
    # Slide off); its skin differs from the sliding one's
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "fixed.pc2"), "--volume-blend", "--joints-slide", "off")
    assert r.returncode == 0, r.stderr
    fixed = core.read_pc2(str(tmp_path / "fixed.pc2"))["frames"]
    rig_fixed, fj, fw, _, fixed_keys = skin_quality.bind_skin(core, character, core.read_muscles(str(tmp_path / "m.json")),
                                                             rig_options=dict(joints_slide=False))
    assert not rig_fixed.joints_slide and rig.joints_slide
    tf = core.skinning_transforms(character, pose, rig_fixed, rig_fixed.evaluate(pose)["joint_matrices"])
    keyed_fixed = skin_quality.with_volume_keys(core, character, character.vertices, fixed_keys, pose)
    expected_fixed = core.skin(keyed_fixed, fj, fw, tf, dqs_share=share,
                               rest_matrices=core.combined_rest_matrices(character, rig_fixed))
    assert np.abs(fixed[0] - character.vertices).max() < 1e-6
    assert np.abs(fixed[1] - expected_fixed).max() < 1e-5
    assert np.abs(fixed[1] - expected).max() > 1e-4
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "x.pc2"), "--joints-slide", "no")
    assert r.returncode == 1 and "--joints-slide must be on or off" in r.stderr, r.stderr
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "x.pc2"), "--joints-slide", "off")
    assert r.returncode == 1 and "--joints-slide needs --muscles" in r.stderr, r.stderr
    r = run_cli("simulate", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "x.pc2"), "--joints-slide", "off")
    assert r.returncode == 1 and "--joints-slide needs --muscles" in r.stderr, r.stderr
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "x.pc2"), "--method", "anchored", "--joints-slide", "off")
    assert r.returncode == 1 and "--joints-slide is for --method eq3" in r.stderr, r.stderr
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "out.pc2"), "--volume-blend", "--preserve-volume")
    assert r.returncode == 1 and "exclude each other" in r.stderr, r.stderr
    r = run_cli("simulate", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "out.pc2"), "--volume-blend")
    assert r.returncode == 1 and "unknown option '--volume-blend'" in r.stderr, r.stderr



def test_cli_deform_volume_blend_applies_the_volume_keys_as_the_module(core, tmp_path):
    """The soldier (skeleton weights, no muscles) with the elbow bent 120 degrees: the CLI's --volume-blend adds its
    volume keys at the core's weights before skinning, as the module does, and they move the skin."""
    path = shared(SOLDIER)
    character = core.load_character(path, require_weights=True)
    share = core.compute_dqs_share(character)
    keys = core.compute_volume_keys(character, share)
    assert any(k["bone"] == "LowerArm.L" for k in keys), [k["bone"] for k in keys]
    for key in keys:  # each key's vertices ascend, one row of offsets each
        vertices = np.asarray(key["vertices"])
        assert vertices.shape == (len(key["offsets"]),) and np.all(np.diff(vertices) > 0), key["bone"]
    half = np.radians(120.0) / 2
    pose_file = tmp_path / "elbow.json"
    pose_file.write_text(json.dumps({"bones": {"LowerArm.L": {"rotation_quaternion": [np.cos(half), np.sin(half),
                                                                                        0.0, 0.0]}}}))
    r = run_cli("deform", path, "--pose", str(pose_file), "-o", str(tmp_path / "out.obj"), "--volume-blend")
    assert r.returncode == 0, r.stderr
    assert f"volume blend with {len(keys)} volume keys" in r.stdout, r.stdout
    written = np.array([[float(x) for x in line.split()[1:4]] for line in (tmp_path / "out.obj").read_text().splitlines()
                        if line.startswith("v ")])
    pose = bend(core, character, 120.0, bone="LowerArm.L")
    keyed = skin_quality.with_volume_keys(core, character, character.vertices, keys, pose)
    moved = np.abs(keyed - np.asarray(character.vertices)).max()
    size = float(np.linalg.norm(np.ptp(np.asarray(character.vertices), axis=0)))
    assert moved > 1e-3 * size  # the elbow's key acts
    expected = core.skin(keyed, character.weight_joints, character.weight_values,
                         core.skeleton_transforms(character, pose), dqs_share=share,
                         rest_matrices=np.asarray(character.bone_rest))
    assert written.shape == np.asarray(expected).shape
    assert np.abs(written - expected).max() < 1e-5 * size

# ------------------------------------------------------------------------------------------------
# The targets, held out
# ------------------------------------------------------------------------------------------------

def rows_by_joint(core, character, joints, facing=(0.0, 0.0, 1.0)):
    muscles, _ = core.extract_muscles(character)
    rows = {r["label"]: r for r in skin_quality.measure(core, character, muscles, joints, facing=facing)}
    assert rows, "no joint measured"
    for label, r in rows.items():
        print(f"{label}: band LBS {100 * r['lbs']:+.1f} %, DQS {100 * r['blender_dqs']:+.1f} %, +PV "
              f"{100 * r['myoskin_pv']:+.1f} %, +VB {100 * r['myoskin_vb']:+.1f} %; crossings LBS/DQS/PV/VB "
              f"{r['crossings_lbs']}/{r['crossings_dqs']}/{r['crossings_myoskin_pv']}/{r['crossings_myoskin_vb']}")
    return rows


def meets_target(r):
    return (abs(r["myoskin_vb"]) <= 0.5 * abs(r["lbs"]) and abs(r["myoskin_vb"]) <= abs(r["blender_dqs"]) + 1e-3
            and r["crossings_myoskin_vb"] <= r["crossings_lbs"])


def test_held_out_soldier_knee_keeps_its_volume_where_dqs_bulges(core):
    """Quaternius' woman soldier: knee 120 LBS -30.8 %, DQS +18.8 %, +PV +19.6 %; the volume blend -7.6 % (measured)."""
    character = core.load_character(shared(SOLDIER), require_weights=True)
    rows = rows_by_joint(core, character, skin_quality.QUATERNIUS_JOINTS)
    knee = rows["knee flexion"]
    assert knee["lbs"] < -0.2 and knee["blender_dqs"] > 0.1  # LBS collapses, DQS bulges (the measure can fail)
    assert meets_target(knee), knee
    assert abs(knee["myoskin_vb"]) < 0.5 * abs(knee["myoskin_pv"])
    for label in ("elbow flexion", "hip flexion"):  # Preserve Volume's figures kept
        assert abs(rows[label]["myoskin_vb"] - rows[label]["myoskin_pv"]) < 0.005, label
    shoulder = rows["shoulder abduction"]  # -21.1 % -> -21.8 %
    assert abs(shoulder["myoskin_vb"]) <= abs(shoulder["myoskin_pv"]) + 0.01
    assert shoulder["crossings_myoskin_vb"] <= shoulder["crossings_lbs"]


def test_a_key_whose_band_gains_then_loses_volume_keeps_it_at_every_sample(core):
    """Quaternius' woman soldier (held out), Bind's keys: where the band gains volume at a small bend and loses it at a
    deep one (the knee, the ankle, the wrist: muscles swelling before the joint collapses) the key's weight changes
    sign with the bend, pulling the skin in, then pushing it out, so every sample keeps its volume. Measured (change
    without -> with the key at 45 / 90 / 135 degrees): LowerLeg +7.4 / +1.7 / -13.3 -> +2.9 / -1.7 / -0.6 %, Foot
    +6.9 / +2.8 / -15.9 -> +1.0 / -0.5 / +0.1 %, Hand +2.5 / +0.1 / -5.5 -> +0.8 / -0.3 / +0.1 %; a key that only
    pushed out had left the gains (LowerLeg +7.8 / +5.9 / -2.4 %)."""
    character = core.load_character(shared(SOLDIER), require_weights=True)
    muscles, _ = core.extract_muscles(character)
    keys = skin_quality.bind_skin(core, character, muscles)[4]
    mixed = [k for k in keys if max(k["change_without"]) > 0.01 and min(k["change_without"]) < -0.01]
    assert len(mixed) >= 4, [(k["bone"], k["change_without"]) for k in keys]
    names = list(character.bone_names)
    for k in mixed:
        without, with_ = np.abs(k["change_without"]), np.abs(k["change_with"])
        assert with_.max() <= 0.5 * without.max(), (k["bone"], k["change_without"], k["change_with"])
        assert np.all(with_ <= without + 0.005), (k["bone"], k["change_without"], k["change_with"])
        # the weight changes sign over the bend: s (k1 + k2 s) negative for small s, positive at s = 1, or the reverse
        assert k["k1"] * (k["k1"] + k["k2"]) < 0.0, (k["bone"], k["k1"], k["k2"])
        rotations = np.tile([1.0, 0.0, 0.0, 0.0], (2, len(names), 1))
        for row, degrees in enumerate((45.0, 135.0)):
            half = np.radians(degrees) / 2
            rotations[row, names.index(k["bone"])] = [np.cos(half), np.sin(half), 0.0, 0.0]
        w = [core.volume_key_weights([k], rotations[row])[0] for row in range(2)]
        assert w[0] * w[1] < 0.0, (k["bone"], w)


def test_held_out_makehuman_neutral_hip_keeps_its_volume_and_the_rest_stays(core):
    """makehuman_neutral: hip flexion 90 LBS -40.8 %, DQS +9.0 %, +PV +9.0 %; the volume blend -1.3 % (measured)."""
    character = core.load_character(shared(NEUTRAL), require_weights=True)
    rows = rows_by_joint(core, character, skin_quality.MAKEHUMAN_JOINTS)
    hip = rows["hip flexion"]
    assert hip["lbs"] < -0.2 and hip["blender_dqs"] > 0.05
    assert meets_target(hip), hip
    assert abs(hip["myoskin_vb"]) < 0.5 * abs(hip["myoskin_pv"])
    for label in ("elbow flexion", "knee flexion", "shoulder abduction"):
        r = rows[label]
        assert abs(r["myoskin_vb"] - r["myoskin_pv"]) < 0.01, label
        assert r["crossings_myoskin_vb"] <= r["crossings_myoskin_pv"], label


# Seed 20 also on the second Python's tier, whose core is the other Debian release's build (the `figures` marker).
@pytest.mark.parametrize("seed", [20] + [pytest.param(s, marks=pytest.mark.figures) for s in (22, 23, 24, 25, 26, 27)])
def test_held_out_generated_bipeds_keep_preserve_volumes_figures(core, seed):
    """Generated bipeds (their dual quaternions already keep elbow, knee and ankle within a few points): the volume
    blend changes no figure by more than a point and adds no crossing."""
    character, _truth = core.make_synthetic_body(seed=seed)
    rows = rows_by_joint(core, character, skin_quality.SYNTHETIC_BODY_JOINTS, facing=(0.0, -1.0, 0.0))
    assert {"elbow flexion", "knee flexion"} <= set(rows)
    for label, r in rows.items():
        assert abs(r["myoskin_vb"] - r["myoskin_pv"]) < 0.01, label
        assert r["crossings_myoskin_vb"] <= r["crossings_myoskin_pv"], label
    for label in ("elbow flexion", "knee flexion"):
        assert rows[label]["lbs"] < -0.2 and abs(rows[label]["myoskin_vb"]) <= 0.5 * abs(rows[label]["lbs"]), label


# ------------------------------------------------------------------------------------------------
# The body's own frame: the same shares however the character is turned
# ------------------------------------------------------------------------------------------------

def turned(core, character, rotation):
    """The character turned by the 3 by 3 `rotation` about the origin (skin, bones, rest matrices; same weights)."""
    r4 = np.eye(4)
    r4[:3, :3] = rotation
    return core.character_from_arrays(
        character.name, np.asarray(character.vertices) @ rotation.T, np.asarray(character.triangles),
        list(character.bone_names), np.asarray(character.bone_parents), np.asarray(character.bone_heads) @ rotation.T,
        np.asarray(character.bone_tails) @ rotation.T, r4 @ np.asarray(character.bone_rest),
        np.asarray(character.weight_joints), np.asarray(character.weight_values))


def quarter_turn(axis):
    """Rotation by 90 degrees about a coordinate axis (0, 1, 2): exact in floating point."""
    r = np.zeros((3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    r[axis, axis], r[j, i], r[i, j] = 1.0, 1.0, -1.0
    return r


def knee_band_change(core, character, share, facing, hinge, shin, radius):
    """Band change (1.5 `radius`) of the knee bent 120 degrees backward under the volume blend of the skeleton weights
    with `share`, in float64 (the skinner's per-vertex affine maps on the rest positions)."""
    rest = np.asarray(character.vertices)
    pose = skin_quality.bent_pose(character, shin, hinge, "backward", 120.0, facing)
    skinner = core.Skinner(rest, character.weight_joints, character.weight_values, character.num_bones,
                           dqs_share=share, rest_matrices=np.asarray(character.bone_rest))
    maps = np.asarray(core.vertex_transforms(skinner, core.skeleton_transforms(character, pose)))
    posed = np.einsum("vij,vj->vi", maps[:, :, :3], rest) + maps[:, :, 3]
    b = list(character.bone_names).index(shin)
    return skin_quality.band_volume_change(rest, posed, np.asarray(character.triangles),
                                           np.asarray(character.bone_heads)[b], pose[b][:3, 3], 1.5 * radius)


@pytest.mark.parametrize("name", ["soldier", "lowpoly", "horse", "biped 22"])
def test_shares_follow_the_body_not_its_coordinates(core, name):
    """computeDqsShare takes left-right from the skeleton's mirror plane and the facing from the feet (or the neck),
    not from the X axis: the same character turned a quarter about its vertical, and a Y-up import turned Z-up (as
    Blender's glTF import does), gets the same shares to 1e-9 and the same band figures (the reference bends' and the
    knee's at 120 degrees). Held out: Quaternius' soldier (Y up, facing +Z), the Godot low-poly male (Y up, facing +X
    with Z across: the case the X rule bent the wrong way), Quaternius' horse (front knee) and a generated biped (Z up,
    facing -Y)."""
    if name == "soldier":
        character = core.load_character(shared(SOLDIER), require_weights=True)
        up, facing, hinge, shin = 1, (0.0, 0.0, 1.0), "UpperLeg.L", "LowerLeg.L"
    elif name == "lowpoly":
        character = core.load_character(shared(LOWPOLY), require_weights=True)
        up, facing, hinge, shin = 1, (1.0, 0.0, 0.0), "thigh.L", "shin.L"
    elif name == "horse":  # no feet below its legs' last bones: the facing from the neck
        character = core.load_character(shared("characters/quaternius_horse/horse.glb"), require_weights=True)
        up, facing, hinge, shin = 1, (0.0, 0.0, 1.0), "FrontUpperLeg.L", "FrontLowerLeg.L"
    else:
        character, _truth = core.make_synthetic_body(seed=22)
        up, facing, hinge, shin = 2, (0.0, -1.0, 0.0), "thigh.L", "shin.L"
    share, joints = core.compute_dqs_share(character, with_joints=True)
    share = np.asarray(share)
    assert len(joints) >= 4, "too few joints measured"
    assert 0.0 < share.mean() < 1.0  # a real mix of the two blends (the comparison can fail)
    radius = joints[0]["radius"]
    knee = knee_band_change(core, character, share, facing, hinge, shin, radius)
    assert np.isfinite(knee)
    for rotation in (quarter_turn(up), quarter_turn(0)):  # about the vertical; about X (Y up -> Z up)
        other = turned(core, character, rotation)
        turned_share, turned_joints = core.compute_dqs_share(other, with_joints=True)
        assert np.abs(np.asarray(turned_share) - share).max() <= 1e-9
        assert [j["bone"] for j in turned_joints] == [j["bone"] for j in joints]
        for a, b in zip(joints, turned_joints):
            for key in ("share", "linear_change", "dual_quat_change", "blend_change"):
                assert abs(a[key] - b[key]) <= 1e-9, (a["bone"], key)
            assert np.abs(rotation @ np.asarray(a["axis"]) - np.asarray(b["axis"])).max() <= 1e-9, a["bone"]
        turned_knee = knee_band_change(core, other, np.asarray(turned_share), rotation @ np.asarray(facing), hinge, shin,
                                       radius)
        assert abs(turned_knee - knee) <= 1e-9, (knee, turned_knee)


# ------------------------------------------------------------------------------------------------
# Which way a joint bends: an arm's forward however far it hangs, a leg's knee backward
# ------------------------------------------------------------------------------------------------

def flexion_swings(core, character, facing):
    """Per measured joint (compute_dqs_share's joints): where its bone's tail moves under the joint's reference
    flexion (axis x bone direction), along `facing`."""
    names = list(character.bone_names)
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    _share, joints = core.compute_dqs_share(character, with_joints=True)
    swings = {}
    for joint in joints:
        b = names.index(joint["bone"])
        direction = (tails[b] - heads[b]) / np.linalg.norm(tails[b] - heads[b])
        swings[joint["bone"]] = float(np.cross(np.asarray(joint["axis"]), direction) @ np.asarray(facing))
    return swings


@pytest.mark.parametrize("seed", [20, 24, 27])
def test_an_a_pose_arm_bends_forward_and_a_leg_backward(core, seed):
    """The generated bipeds hang their arms 31-46 degrees below the horizontal (an A-pose) and face -Y (the
    independent answer: their feet and heads point there). Flexion alternates down a limb (hip forward, knee backward)
    only on a leg, a limb whose skin reaches the ground: bipeds 24, 26 and 27, whose shoulder to upper arm is a twist
    split, used to get the knee's backward bend at the elbow (20 at the shoulder and its right elbow), and Bind's elbow
    key, fitted on that bend, added volume to biped 24's elbow flexed forward: +2.5 % at 120 degrees where the blend
    alone keeps -0.4 % (then no key: -0.4 %; since keys may move the skin away from the joint, -0.1 %; with the slide
    limits +0.3 %)."""
    character, _truth = core.make_synthetic_body(seed=seed)
    swings = flexion_swings(core, character, (0.0, -1.0, 0.0))
    arm = [bone for bone in ("upper_arm.L", "forearm.L", "upper_arm.R", "forearm.R") if bone in swings]
    assert {"forearm.L", "forearm.R", "shin.L", "shin.R"} <= set(swings), sorted(swings)
    assert len(arm) >= 2, sorted(swings)
    for bone in arm:
        assert swings[bone] > 0.9, (bone, swings[bone])
    for bone in ("shin.L", "shin.R"):
        assert swings[bone] < -0.9, (bone, swings[bone])
    if seed == 24:
        muscles, _ = core.extract_muscles(character)
        elbow = [joint for joint in skin_quality.SYNTHETIC_BODY_JOINTS if joint[0] == "elbow flexion"]
        (row,) = skin_quality.measure(core, character, muscles, elbow, facing=(0.0, -1.0, 0.0))
        assert row["lbs"] < -0.2
        assert abs(row["myoskin_vk"]) <= 0.01, row["myoskin_vk"]
        # the key leaves the band no further from rest than the blend alone (the backward-fitted key added 2.9 points)
        assert abs(row["myoskin_vk"]) <= abs(row["myoskin_vb"]) + 1e-3, (row["myoskin_vk"], row["myoskin_vb"])
        # (+0.3 % since the slide limits hold the joints' slide that drew the crease's skin in: DQS -0.2 %)
        assert row["myoskin_vk"] <= 0.005, row["myoskin_vk"]


def test_a_horses_legs_alternate(core):
    """Quaternius' horse (held out; Y up, facing +Z): all four legs stand on the ground, so their joints alternate:
    the front knee bends backward and the hind hock forward (skin_quality.HORSE_JOINTS bend them so)."""
    character = core.load_character(shared("characters/quaternius_horse/horse.glb"), require_weights=True)
    swings = flexion_swings(core, character, (0.0, 0.0, 1.0))
    for side in (".L", ".R"):
        assert swings["FrontLowerLeg" + side] < -0.9, swings
        assert swings["BackLowerLeg" + side] > 0.9, swings
