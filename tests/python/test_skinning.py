"""Skinning from Python: the Skinner against numpy, ValueErrors naming the offending index, poses, PC2,
quality measures and the `myoskin deform` CLI."""
import json
import os
import sys

import numpy as np
import pytest

from conftest import run_cli

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import skin_quality  # noqa: E402


@pytest.fixture(scope="module")
def arm(core):
    character, _truth = core.make_synthetic_arm(seed=1)
    return character


def numpy_lbs(rest, joints, weights, transforms):
    """Float64 Equation 3 with Blender's semantics (normalise; weight sum <= 1e-4 stays at rest)."""
    out = np.array(rest, dtype=np.float64)
    homog = np.hstack([rest, np.ones((len(rest), 1))])
    acc = np.zeros_like(out)
    total = np.zeros(len(rest))
    for k in range(joints.shape[1]):
        used = joints[:, k] >= 0
        t = transforms[joints[used, k]]
        acc[used] += weights[used, k, None] * np.einsum("vij,vj->vi", t[:, :3, :], homog[used])
        total[used] += weights[used, k]
    moving = total > 1e-4
    out[moving] = acc[moving] / total[moving, None]
    return out


def bend(core, character, degrees, bone="forearm", axis=(0, 0, 1)):
    names = list(character.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    half = np.radians(degrees) / 2
    q[names.index(bone)] = [np.cos(half), *(np.sin(half) * np.asarray(axis, dtype=float))]
    return core.pose_from_rotations(character, q)


def test_skinner_matches_numpy_with_scaled_joints_and_threads(core, arm):
    rng = np.random.default_rng(4)
    nv = arm.num_vertices
    joints = rng.integers(-1, 12, size=(nv, 8)).astype(np.int32)
    joints[:, 0] = rng.integers(0, 12, size=nv)
    weights = rng.uniform(0.0, 2.0, size=(nv, 8))
    transforms = np.tile(np.eye(4), (12, 1, 1))
    for j in range(12):
        angle = rng.uniform(-1, 1)
        c, s = np.cos(angle), np.sin(angle)
        transforms[j, :3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag(rng.uniform(0.7, 1.4, 3))
        transforms[j, :3, 3] = rng.uniform(-0.1, 0.1, 3)
    skinner = core.Skinner(arm.vertices, joints, weights, 12, grain_size=512, threads=1)
    one = skinner.deform(transforms)
    assert one.dtype == np.float32 and one.shape == (nv, 3)
    expected = numpy_lbs(np.asarray(arm.vertices), joints, weights, transforms)
    assert np.abs(one - expected).max() < 2e-6
    skinner.threads = 2
    out = np.empty((nv, 3), dtype=np.float32)
    skinner.deform_into(transforms, out)
    assert np.array_equal(one, out)
    assert np.abs(core.skin(arm.vertices, joints, weights, transforms) - expected).max() < 2e-6


def test_rest_pose_reproduces_the_skin(core, arm):
    transforms = core.skeleton_transforms(arm, core.rest_pose(arm))
    skinner = core.Skinner(arm.vertices, arm.weight_joints, arm.weight_values, arm.num_bones)
    assert np.abs(skinner.deform(transforms) - arm.vertices).max() < 1e-6


def test_bad_arrays_raise_value_errors_naming_the_index(core, arm):
    v, j, w = np.asarray(arm.vertices), np.array(arm.weight_joints), np.array(arm.weight_values)
    nb = arm.num_bones
    bad = w.copy()
    bad[123, 1] = -0.2
    with pytest.raises(ValueError, match="vertex 123 slot 1 has a negative weight"):
        core.Skinner(v, j, bad, nb)
    bad[123, 1] = np.nan
    with pytest.raises(ValueError, match="vertex 123 slot 1 has a NaN"):
        core.Skinner(v, j, bad, nb)
    badj = j.copy()
    badj[77, 0] = nb
    with pytest.raises(ValueError, match=f"vertex 77 slot 0 uses joint {nb}, outside 0..{nb - 1}"):
        core.Skinner(v, badj, w, nb)
    with pytest.raises(ValueError, match="must be #N by 3"):
        core.Skinner(v[:, :2], j, w, nb)
    with pytest.raises(ValueError, match="same shape"):
        core.Skinner(v, j[:, :2], w, nb)
    with pytest.raises(ValueError, match="rows for"):
        core.Skinner(v, j[:-1], w[:-1], nb)
    unnormalised = w.copy()
    unnormalised[321] *= 0.5
    core.Skinner(v, j, unnormalised, nb)  # normalised at deform time, like Blender
    with pytest.raises(ValueError, match="vertex 321 weights sum to 0.5"):
        core.Skinner(v, j, unnormalised, nb, sum_tolerance=1e-6)
    skinner = core.Skinner(v, j, w, nb)
    with pytest.raises(ValueError, match="N by 4 by 4"):
        skinner.deform(np.zeros((nb, 3, 4)))
    with pytest.raises(ValueError, match=f"3 transforms for {nb} joints"):
        skinner.deform(np.tile(np.eye(4), (3, 1, 1)))
    t = np.tile(np.eye(4), (nb, 1, 1))
    t[2, 0, 1] = np.inf
    with pytest.raises(ValueError, match="transform 2"):
        skinner.deform(t)
    with pytest.raises(ValueError, match="out must be"):
        skinner.deform_into(np.tile(np.eye(4), (nb, 1, 1)), np.empty((5, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="out must be"):  # float64: no silent copy that stays unfilled
        skinner.deform_into(np.tile(np.eye(4), (nb, 1, 1)), np.empty((skinner.num_vertices, 3)))
    with pytest.raises(ValueError, match="one quaternion"):
        core.pose_from_rotations(arm, np.tile([1.0, 0, 0, 0], (nb + 1, 1)))
    with pytest.raises(ValueError, match="quaternion of bone '.*' is not usable"):
        core.pose_from_rotations(arm, np.array([[1.0, 0, 0, 0], [0, 0, 0, 0]] + [[1.0, 0, 0, 0]] * (nb - 2)))


def test_elbow_bend_volume_and_bulge_measures(core, arm):
    """Plain LBS measures: bulge ~0 where a vertex follows one bone; volume change is finite and printed."""
    pose = bend(core, arm, 90)
    t = core.skeleton_transforms(arm, pose)
    posed = core.skin(arm.vertices, arm.weight_joints, arm.weight_values, t)
    v0 = core.enclosed_volume(arm.vertices, arm.triangles)
    v1 = core.enclosed_volume(posed, arm.triangles)
    bulge = core.local_bulge(arm.vertices, arm.triangles, posed, arm.weight_joints, arm.weight_values, t)
    rigid = np.asarray(arm.weight_values)[:, 0] > 0.999
    print(f"LBS 90 deg: volume change {100 * (v1 - v0) / v0:+.2f} %, max |bulge| on rigid vertices "
          f"{np.abs(bulge[rigid]).max():.2e} m")
    assert np.abs(bulge[rigid]).max() < 1e-6  # float32 skinning
    labels = np.argmax(np.asarray(arm.weight_values), axis=1).astype(np.int32)
    labels = np.asarray(arm.weight_joints)[np.arange(arm.num_vertices), labels].astype(np.int32)
    change = core.region_volume_change(arm.vertices, posed, arm.triangles, labels, arm.num_bones)
    assert len(change) == arm.num_bones and np.isfinite(change).all()


def test_self_intersections_of_a_folded_elbow(core, arm):
    """The rest skin crosses nowhere; bent far past its range, LBS folds the elbow's skin through itself."""
    assert core.self_intersections(arm.vertices, arm.triangles) == 0
    pose = bend(core, arm, 170)
    posed = core.skin(arm.vertices, arm.weight_joints, arm.weight_values, core.skeleton_transforms(arm, pose))
    crossings = core.self_intersections(posed, arm.triangles)
    none = core.self_intersections(posed, arm.triangles, np.zeros(arm.num_triangles, bool))
    print(f"LBS 170 deg: {crossings} crossing triangle pairs")
    assert crossings > 0 and none == 0
    with pytest.raises(ValueError, match="entries"):
        core.self_intersections(posed, arm.triangles, np.ones(3, bool))
    # The pairs themselves locate the fold: as many as counted, sorted, and never two triangles one bone moves
    # rigidly (rigid motion keeps the rest skin's no crossings), so each pair has skin of both segments or the crease.
    pairs = core.self_intersecting_pairs(posed, arm.triangles)
    tris = np.asarray(arm.triangles)
    assert pairs.shape == (crossings, 2) and (pairs[:, 0] < pairs[:, 1]).all()
    assert (np.diff(pairs[:, 0]) >= 0).all()
    values, joints = np.asarray(arm.weight_values), np.asarray(arm.weight_joints)
    rigid_bone = np.where(values.max(1) > 0.999, joints[np.arange(len(joints)), values.argmax(1)], -1)
    bone_of = [set(rigid_bone[t]) for t in tris]  # {b}: the triangle moves rigidly with bone b
    same_rigid = [len(bone_of[a]) == 1 and bone_of[a] == bone_of[b] and -1 not in bone_of[a] for a, b in pairs]
    assert not any(same_rigid)
    assert any(len(bone_of[a]) == 1 and -1 not in bone_of[a] for a, _ in pairs)  # the check above has rigid skin to see
    assert len(core.self_intersecting_pairs(posed, arm.triangles, np.zeros(arm.num_triangles, bool))) == 0


def test_pc2_round_trip(core, arm, tmp_path):
    frames = np.stack([np.asarray(arm.vertices, dtype=np.float32) + i for i in range(3)])
    path = str(tmp_path / "x.pc2")
    core.write_pc2(path, frames, start_frame=5.0)
    back = core.read_pc2(path)
    assert back["start_frame"] == 5.0 and back["num_points"] == arm.num_vertices
    assert np.array_equal(back["frames"], frames)
    with pytest.raises(ValueError, match="#frames by #V by 3"):
        core.write_pc2(path, frames[0])
    (tmp_path / "bad.pc2").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="too short"):
        core.read_pc2(str(tmp_path / "bad.pc2"))


def test_cli_deform_obj_and_pc2(core, tmp_path):
    assert run_cli("generate", "arm", "-o", str(tmp_path)).returncode == 0
    character = core.load_character(str(tmp_path / "arm.obj"))
    pose = {"format": "myoskin.pose", "version": 1, "bones": {"forearm": {"rotation_axis_angle": [60, 0, 0, 1]}}}
    (tmp_path / "pose.json").write_text(json.dumps(pose))
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "pose.json"), "-o",
                str(tmp_path / "out.obj"))
    assert r.returncode == 0, r.stderr
    out = core.load_character(str(tmp_path / "out.obj"), skeleton_path=str(tmp_path / "arm.skeleton.json"))
    expected = core.skin(character.vertices, character.weight_joints, character.weight_values,
                         core.skeleton_transforms(character, bend(core, character, 60)))
    assert np.abs(np.asarray(out.vertices) - expected).max() < 1e-5
    seq = {"start_frame": 1, "frames": [{"bones": {"forearm": {"rotation_axis_angle": [a, 0, 0, 1]}}}
                                        for a in (0, 70, 140)]}
    (tmp_path / "seq.json").write_text(json.dumps(seq))
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "out.pc2"))
    assert r.returncode == 0, r.stderr
    cache = core.read_pc2(str(tmp_path / "out.pc2"))
    assert cache["frames"].shape == (3, character.num_vertices, 3) and cache["start_frame"] == 1.0
    assert np.abs(cache["frames"][0] - character.vertices).max() < 1e-6
    last = core.skin(character.vertices, character.weight_joints, character.weight_values,
                     core.skeleton_transforms(character, bend(core, character, 140)))
    assert np.abs(cache["frames"][2] - last).max() < 1e-5
    # Bad input: one line, non-zero exit.
    for bad, message in [({"bones": {"elbow": {}}}, "bone 'elbow' is not in the skeleton"),
                         ({"bones": {"forearm": {"rotation_quaternion": [0, 0, 0, 0]}}}, "is zero"),
                         ({"bones": {"forearm": {"scale": [1, 1, 1]}}}, "unknown key 'scale'"),
                         ({"frames": []}, "non-empty list")]:
        (tmp_path / "bad.json").write_text(json.dumps(bad))
        r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "bad.json"), "-o",
                    str(tmp_path / "bad.obj"))
        assert r.returncode == 1 and message in r.stderr and r.stderr.count("\n") == 1, (bad, r.stderr)
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "x.obj"))
    assert r.returncode == 1 and "write them to a .pc2" in r.stderr
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "pose.json"), "-o",
                str(tmp_path / "x.ply"))
    assert r.returncode == 1 and ".obj or .pc2" in r.stderr


def test_hybrid_weights_rest_pose_and_bad_input(core, arm):
    muscles, _report = core.extract_muscles(arm)
    rig = core.MuscleRig(arm, muscles)
    joints, weights = core.hybrid_weights(arm, rig)
    nb = arm.num_bones
    assert joints.shape == weights.shape == (arm.num_vertices, 8)
    assert np.abs(weights.sum(axis=1) - 1).max() < 1e-12
    assert joints.max() < nb + rig.num_joints and ((joints >= nb) & (weights > 0.5)).any()
    rest = core.rest_pose(arm)
    transforms = core.skinning_transforms(arm, rest, rig, rig.evaluate(rest)["joint_matrices"])
    assert transforms.shape == (nb + rig.num_joints, 4, 4)
    skinner = core.Skinner(arm.vertices, joints, weights, nb + rig.num_joints)
    assert np.abs(skinner.deform(transforms) - arm.vertices).max() < 1e-6
    off = core.hybrid_weights(arm, rig, dominance=0.0)
    assert (off[0] < nb).all()
    one = muscles[0].name
    without = core.hybrid_weights(arm, rig, muscle_dominance={one: 0.0})[0]
    first, count = rig.joint_offset(0), rig.joint_count(0)
    assert not ((without >= nb + first) & (without < nb + first + count)).any()
    with pytest.raises(ValueError, match="unknown muscle 'nope'"):
        core.hybrid_weights(arm, rig, muscle_dominance={"nope": 1.0})
    with pytest.raises(ValueError, match="dominance must be in"):
        core.hybrid_weights(arm, rig, dominance=2.0)
    every = core.hybrid_weights(arm, rig, min_weight=0.0)  # no pruning: more influences, same row sums
    assert (every[1] > 0).sum() > (weights > 0).sum() and np.abs(every[1].sum(axis=1) - 1).max() < 1e-12
    with pytest.raises(ValueError, match="minWeight must be in"):
        core.hybrid_weights(arm, rig, min_weight=0.5)
    with pytest.raises(ValueError, match="joint matrices for"):
        core.skinning_transforms(arm, rest, rig, rig.evaluate(rest)["joint_matrices"][:-1])


def test_cli_deform_with_muscles_matches_the_module(core, tmp_path):
    assert run_cli("generate", "arm", "-o", str(tmp_path)).returncode == 0
    assert run_cli("extract", str(tmp_path / "arm.obj"), "-o", str(tmp_path / "m.json")).returncode == 0
    character = core.load_character(str(tmp_path / "arm.obj"))
    seq = {"frames": [{"bones": {"forearm": {"rotation_axis_angle": [a, 1, 0, 0]}}} for a in (0, 140)]}
    (tmp_path / "seq.json").write_text(json.dumps(seq))
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "out.pc2"))
    assert r.returncode == 0, r.stderr
    assert "muscle joints" in r.stdout
    frames = core.read_pc2(str(tmp_path / "out.pc2"))["frames"]
    rig, joints, weights = skin_quality.bound_rig(core, character, core.read_muscles(str(tmp_path / "m.json")))
    assert (np.asarray(rig.slide_limits) > 0).any()  # Bind's: how far each joint may slide
    pose = bend(core, character, 140, axis=(1, 0, 0))
    transforms = core.skinning_transforms(character, pose, rig, rig.evaluate(pose)["joint_matrices"])
    expected = core.Skinner(character.vertices, joints, weights, transforms.shape[0]).deform(transforms)
    assert np.abs(frames[0] - character.vertices).max() < 1e-6
    assert np.abs(frames[1] - expected).max() < 1e-5
    plain = core.skin(character.vertices, character.weight_joints, character.weight_values,
                      core.skeleton_transforms(character, pose))
    assert np.abs(frames[1] - plain).max() > 1e-3  # the muscles change the result


def test_body_relative_smoothing_gives_a_coarse_and_a_fine_mesh_the_same_weights(core):
    """HybridWeightOptions::smoothingDistance: the muscle weights of makehuman_neutral (held out: the distance was
    measured on makehuman_muscular_male and generated biped 21) and of the same skin subdivided once (4x the
    triangles, the original vertices kept first) agree at the original vertices, where the fixed pass count does not.
    Measured: mean difference on the muscles' skin 0.073 with 24 passes, 0.021 at 0.7 radii, 0.012 at 1.5 radii."""
    from conftest import NEUTRAL, shared
    coarse = core.load_character(shared(NEUTRAL), require_weights=True)
    fine = core.subdivide(coarse, 1)
    nv, nb = len(coarse.vertices), len(coarse.bone_names)
    assert len(fine.vertices) > 3 * nv
    np.testing.assert_array_equal(np.asarray(fine.vertices)[:nv], np.asarray(coarse.vertices))
    muscles, _ = core.extract_muscles(coarse)
    assert len(muscles) >= 4
    rigs = core.MuscleRig(coarse, muscles), core.MuscleRig(fine, muscles)

    def muscle_share(options):  # per original vertex: its weight on muscle joints, coarse and fine
        shares = []
        for character, rig in zip((coarse, fine), rigs):
            joints, weights = (np.asarray(a) for a in core.hybrid_weights(character, rig, **options))
            shares.append((weights * (joints >= nb)).sum(1)[:nv])
        return shares

    def difference(options):
        a, b = muscle_share(options)
        on_muscles = (a > 0.05) | (b > 0.05)
        assert on_muscles.sum() > 100  # the muscles weigh a good part of the skin
        return float(np.abs(a - b)[on_muscles].mean())

    passes, relative = difference({}), difference({"smoothing_distance": 1.0})
    print(f"mean muscle-weight difference coarse/fine: 24 passes {passes:.3f}, 1 radius {relative:.3f}")
    assert relative < 0.03
    assert relative < 0.4 * passes  # the pass count spreads the coarse mesh's weights further
    with pytest.raises(ValueError, match="smoothingDistance"):
        core.hybrid_weights(coarse, rigs[0], smoothing_distance=-1.0)
