"""Preserve volume (Blender's dual quaternion skinning) from Python and the CLI: the Skinner against a numpy
float64 reference, rest pose exact, ValueErrors, and `myoskin deform --preserve-volume` equal to the module."""
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


def quat_from_matrix(m):
    """(w, x, y, z) of a rotation matrix (Shepperd's method, float64)."""
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        return np.array([0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s])
    i = int(np.argmax(np.diag(m)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = np.empty(4)
    q[0] = (m[k, j] - m[j, k]) / s
    q[1 + i] = 0.25 * s
    q[1 + j] = (m[j, i] + m[i, j]) / s
    q[1 + k] = (m[k, i] + m[i, k]) / s
    return q


def qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def qrot(q, v):
    return qmul(qmul(q, np.r_[0.0, v]), q * [1, -1, -1, -1])[1:]


def joint_rotation(transform, rest):
    """Blender's blended rotation of a joint: its posed frame made orthonormal about Y, back in rest frame."""
    p = (transform @ rest)[:3, :3]
    y = p[:, 1] / np.linalg.norm(p[:, 1])
    x = p[:, 0] - p[:, 0].dot(y) * y
    x /= np.linalg.norm(x)
    b = rest[:3, :3] / np.linalg.norm(rest[:3, :3], axis=0)
    return quat_from_matrix(np.column_stack([x, y, np.cross(x, y)]) @ b.T)


def numpy_dqs(rest_vertices, joints, weights, transforms, rest):
    """Float64 dual quaternion skinning: per joint the rigid motion (q_j, t_j) that carries the vertex to
    T_j v, blended with aligned signs, normalised. Weight sum <= 1e-4 stays at rest."""
    rot = [joint_rotation(t, r) for t, r in zip(transforms, rest)]
    out = np.array(rest_vertices, dtype=np.float64)
    for v, co in enumerate(out.copy()):
        sq, sd, total = np.zeros(4), np.zeros(4), 0.0
        for j, w in zip(joints[v], weights[v]):
            if j < 0 or w <= 0:
                continue
            total += w
            q = rot[j]
            t = (transforms[j] @ np.r_[co, 1.0])[:3] - qrot(q, co)
            d = 0.5 * qmul(np.r_[0.0, t], q)
            if q.dot(sq) < 0:
                w = -w
            sq += w * q
            sd += w * d
        if total <= 1e-4:
            continue
        n = np.linalg.norm(sq)
        q, d = sq / n, sd / n
        out[v] = qrot(q, co) + 2.0 * qmul(d, q * [1, -1, -1, -1])[1:]
    return out


def bend(core, character, degrees, bone="forearm", axis=(1, 0, 0)):
    names = list(character.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    half = np.radians(degrees) / 2
    q[names.index(bone)] = [np.cos(half), *(np.sin(half) * np.asarray(axis, dtype=float))]
    return core.pose_from_rotations(character, q)


def test_hybrid_rig_matches_numpy_with_bulging_joints_and_rest_is_exact(core, arm):
    muscles, _report = core.extract_muscles(arm)
    rig = core.MuscleRig(arm, muscles)
    joints, weights = core.hybrid_weights(arm, rig)
    rest = core.combined_rest_matrices(arm, rig)
    nb = arm.num_bones
    assert rest.shape == (nb + rig.num_joints, 4, 4)
    assert np.array_equal(rest[:nb], arm.bone_rest) and np.array_equal(rest[nb:], rig.bind_matrices)
    skinner = core.Skinner(arm.vertices, joints, weights, len(rest), preserve_volume=True, rest_matrices=rest)
    assert skinner.preserve_volume
    size = float(np.linalg.norm(np.ptp(np.asarray(arm.vertices), axis=0)))
    at_rest = core.rest_pose(arm)
    t = core.skinning_transforms(arm, at_rest, rig, rig.evaluate(at_rest)["joint_matrices"])
    assert np.abs(skinner.deform(t) - arm.vertices).max() < 1e-6 * size
    pose = bend(core, arm, 120)
    matrices = rig.evaluate(pose)["joint_matrices"]
    scale = np.linalg.norm(matrices[:, :3, :3], axis=1)
    assert np.abs(scale - 1).max() > 0.02, "the muscle joints should bulge (scale) at 120 degrees"
    t = core.skinning_transforms(arm, pose, rig, matrices)
    got = skinner.deform(t)
    ref = numpy_dqs(arm.vertices, joints, weights, t, rest)
    assert np.abs(got - ref).max() < 1e-6 * size
    one_shot = core.skin(arm.vertices, joints, weights, t, preserve_volume=True, rest_matrices=rest)
    assert np.abs(one_shot - got).max() < 1e-7
    linear = core.skin(arm.vertices, joints, weights, t)
    assert np.abs(linear - got).max() > 1e-3 * size  # the elbow blends differently


def test_bad_preserve_volume_arguments_raise_value_errors(core, arm):
    args = (arm.vertices, arm.weight_joints, arm.weight_values, arm.num_bones)
    with pytest.raises(ValueError, match="only used with preserve_volume"):
        core.Skinner(*args, rest_matrices=arm.bone_rest)
    with pytest.raises(ValueError, match="joint rest matrices for"):
        core.Skinner(*args, preserve_volume=True, rest_matrices=arm.bone_rest[:-1])
    singular = np.array(arm.bone_rest)
    singular[0, :3, :3] = 0.0
    with pytest.raises(ValueError, match="singular"):
        core.Skinner(*args, preserve_volume=True, rest_matrices=singular)
    with pytest.raises(ValueError):
        core.Skinner(*args, preserve_volume=True, rest_matrices=np.eye(3))
    skinner = core.Skinner(*args, preserve_volume=True)
    with pytest.raises(ValueError, match="dq_scale must be"):
        core.Skinner(*args, preserve_volume=True, dq_scale="legacy")
    with pytest.raises(ValueError, match="transforms for"):
        skinner.deform(np.tile(np.eye(4), (arm.num_bones + 1, 1, 1)))


def test_cli_deform_preserve_volume_matches_the_module(core, tmp_path):
    assert run_cli("generate", "arm", "-o", str(tmp_path)).returncode == 0
    assert run_cli("extract", str(tmp_path / "arm.obj"), "-o", str(tmp_path / "m.json")).returncode == 0
    character = core.load_character(str(tmp_path / "arm.obj"))
    seq = {"frames": [{"bones": {"forearm": {"rotation_axis_angle": [a, 1, 0, 0]}}} for a in (0, 120)]}
    (tmp_path / "seq.json").write_text(json.dumps(seq))
    for muscles in (False, True):
        extra = ["--muscles", str(tmp_path / "m.json")] if muscles else []
        r = run_cli("deform", str(tmp_path / "arm.obj"), *extra, "--pose", str(tmp_path / "seq.json"), "-o",
                    str(tmp_path / "out.pc2"), "--preserve-volume")
        assert r.returncode == 0, r.stderr
        assert "preserve volume" in r.stdout
        frames = core.read_pc2(str(tmp_path / "out.pc2"))["frames"]
        pose = bend(core, character, 120)
        if muscles:
            rig, joints, weights = skin_quality.bound_rig(core, character, core.read_muscles(str(tmp_path / "m.json")))
            t = core.skinning_transforms(character, pose, rig, rig.evaluate(pose)["joint_matrices"])
            rest = core.combined_rest_matrices(character, rig)
        else:
            joints, weights = character.weight_joints, character.weight_values
            t = core.skeleton_transforms(character, pose)
            rest = core.combined_rest_matrices(character)
        expected = core.skin(character.vertices, joints, weights, t, preserve_volume=True, rest_matrices=rest)
        assert np.abs(frames[0] - character.vertices).max() < 1e-6
        assert np.abs(frames[1] - expected).max() < 1e-5
        assert np.abs(frames[1] - core.skin(character.vertices, joints, weights, t)).max() > 1e-3
    # Blender 3.x's scale handling: the muscle joints scale, so the two modes differ at 120 degrees
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--muscles", str(tmp_path / "m.json"), "--pose",
                str(tmp_path / "seq.json"), "-o", str(tmp_path / "b.pc2"), "--preserve-volume", "--dq-scale", "blended")
    assert r.returncode == 0, r.stderr
    blended = core.read_pc2(str(tmp_path / "b.pc2"))["frames"][1]
    expected = core.skin(character.vertices, joints, weights, t, preserve_volume=True, rest_matrices=rest,
                         dq_scale="blended")
    assert np.abs(blended - expected).max() < 1e-5 and np.abs(blended - frames[1]).max() > 1e-4
    for bad, message in [(["--dq-scale", "blended"], "--dq-scale needs --preserve-volume"),
                         (["--preserve-volume", "--dq-scale", "x"], "--dq-scale must be")]:
        r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                    str(tmp_path / "out.pc2"), *bad)
        assert r.returncode == 1 and message in r.stderr, r.stderr
    r = run_cli("deform", str(tmp_path / "arm.obj"), "--pose", str(tmp_path / "seq.json"), "-o",
                str(tmp_path / "out.pc2"), "--preserve-volum")
    assert r.returncode == 1 and "unknown option '--preserve-volum'" in r.stderr and r.stderr.count("\n") == 1
