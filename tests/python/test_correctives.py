"""Pose-space correctives through the Python module: the per-vertex affine maps equal the skinner, a sculpt mapped
back with rest_space_offsets reproduces itself (linear and Preserve Volume with the muscle joints), the radial
basis functions are 1 at their poses, 0 at rest and beyond the falloff, and bad input is a ValueError."""
import math

import numpy as np
import pytest

_core = pytest.importorskip("_core")


@pytest.fixture(scope="module")
def arm():
    c, _truth = _core.make_synthetic_arm(seed=1)
    muscles, _report = _core.extract_muscles(c)
    rig = _core.MuscleRig(c, muscles)
    joints, weights = _core.hybrid_weights(c, rig)
    rest = np.asarray(c.vertices)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    return c, rig, np.asarray(joints), np.asarray(weights), size


def pose_of(c, bones):
    """bones {name: (degrees, axis)} -> #B by 4 by 4 pose."""
    names = list(c.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    for name, (degrees, axis) in bones.items():
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        half = math.radians(degrees) / 2
        q[names.index(name)] = [math.cos(half), *(math.sin(half) * axis)]
    return _core.pose_from_rotations(c, q)


def transforms_of(c, rig, pose):
    return _core.skinning_transforms(c, pose, rig, rig.evaluate(pose)["joint_matrices"])


def skinners(c, rig, joints, weights, t, rest=None):
    rest = np.asarray(c.vertices) if rest is None else rest
    yield "linear", _core.Skinner(rest, joints, weights, len(t))
    yield "preserve volume", _core.Skinner(rest, joints, weights, len(t), preserve_volume=True,
                                           rest_matrices=_core.combined_rest_matrices(c, rig))


def test_vertex_transforms_are_the_deform(arm):
    c, rig, joints, weights, size = arm
    t = transforms_of(c, rig, pose_of(c, {"forearm": (110, (1, 0, 0)), "upper_arm": (40, (0, 0, 1))}))
    rest = np.asarray(c.vertices)
    for mode, skinner in skinners(c, rig, joints, weights, t):
        m = _core.vertex_transforms(skinner, t)
        assert m.shape == (len(rest), 3, 4)
        mapped = np.einsum("vij,vj->vi", m[:, :, :3], rest) + m[:, :, 3]
        assert np.abs(mapped - skinner.deform(t)).max() < 1e-6 * size, mode


def test_sculpt_reproduced_rest_untouched_far_poses_untouched(arm):
    c, rig, joints, weights, size = arm
    names = list(c.bone_names)
    forearm = names.index("forearm")
    pose = pose_of(c, {"forearm": (100, (1, 0, 0))})
    t = transforms_of(c, rig, pose)
    rest = np.asarray(c.vertices)
    q = _core.bone_local_rotations(c, pose)
    drivers = _core.CorrectiveDrivers([{"name": "elbow", "bone": forearm,
                                        "direction": _core.bone_direction(q[forearm])}])
    assert drivers.names == ["elbow"] and len(drivers.bones) == 1
    assert drivers.weights(q)[0] == pytest.approx(1.0, abs=1e-12)
    assert drivers.weights(_core.bone_local_rotations(c, _core.rest_pose(c)))[0] == 0.0
    far = _core.bone_local_rotations(c, pose_of(c, {"forearm": (-100, (1, 0, 0))}))
    assert drivers.weights(far)[0] == 0.0
    for mode, skinner in skinners(c, rig, joints, weights, t):
        posed = skinner.deform(t).astype(np.float64)
        elbow = np.asarray(c.bone_heads)[forearm]
        near = np.linalg.norm(rest - elbow, axis=1) < 0.15 * size
        assert near.sum() > 10
        sculpt = posed.copy()
        sculpt[near] += 0.02 * size * np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
        offsets = _core.rest_space_offsets(skinner, t, rest, sculpt)
        again = dict(skinners(c, rig, joints, weights, t, rest=rest + offsets))[mode]
        err = np.abs(again.deform(t) - sculpt).max() / size
        assert err < 1e-6, (mode, err)
        assert np.abs(offsets[~near]).max() < 1e-6 * size  # unsculpted skin gets no offset


def test_bad_input_is_a_value_error(arm):
    c, rig, joints, weights, size = arm
    forearm = list(c.bone_names).index("forearm")
    pose = pose_of(c, {"forearm": (90, (1, 0, 0))})
    t = transforms_of(c, rig, pose)
    skinner = _core.Skinner(np.asarray(c.vertices), joints, weights, len(t))
    posed = skinner.deform(t).astype(np.float64)
    with pytest.raises(ValueError, match="vertices"):
        _core.rest_space_offsets(skinner, t, np.asarray(c.vertices), posed[:-1])
    posed[3, 0] = np.nan
    with pytest.raises(ValueError, match="vertex 3"):
        _core.rest_space_offsets(skinner, t, np.asarray(c.vertices), posed)
    direction = _core.bone_direction(_core.bone_local_rotations(c, pose)[forearm])
    with pytest.raises(ValueError, match="same pose"):
        _core.CorrectiveDrivers([{"name": "a", "bone": forearm, "direction": direction},
                                 {"name": "b", "bone": forearm, "direction": direction}])
    with pytest.raises(ValueError, match="rest direction"):
        _core.CorrectiveDrivers([{"name": "a", "bone": forearm, "direction": [0.0, 1.0, 0.0]}])
    with pytest.raises(ValueError, match="falloff"):
        _core.CorrectiveDrivers([{"name": "a", "bone": forearm, "direction": direction}], falloff=0.0)


def test_makehuman_elbow_and_knee_sculpts_reproduced_with_the_muscle_joints_and_preserve_volume():
    """The reference character: extracted muscles as joints, Preserve Volume (Bind's default), correctives at
    two elbow poses and one knee pose; each sculpt reproduced, rest exact."""
    from conftest import MUSCULAR, shared
    c = _core.load_character(shared(MUSCULAR))
    muscles, _report = _core.extract_muscles(c)
    rig = _core.MuscleRig(c, muscles)
    joints, weights = _core.hybrid_weights(c, rig)
    joints, weights = np.asarray(joints), np.asarray(weights)
    rest = np.asarray(c.vertices)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    names = list(c.bone_names)
    elbow, knee = names.index("lowerarm01.L"), names.index("lowerleg01.L")
    rest_matrices = _core.combined_rest_matrices(c, rig)
    cases = [("elbow_70", elbow, {"lowerarm01.L": (70, (1, 0, 0))}),
             ("elbow_120", elbow, {"lowerarm01.L": (120, (1, 0, 0))}),
             ("knee_100", knee, {"lowerleg01.L": (100, (1, 0, 0))})]
    poses, offsets, sculpts = [], [], []
    for name, bone, rotations in cases:
        pose = pose_of(c, rotations)
        t = transforms_of(c, rig, pose)
        q = _core.bone_local_rotations(c, pose)
        poses.append({"name": name, "bone": bone, "direction": _core.bone_direction(q[bone])})
        offsets.append(np.zeros_like(rest))
        w = _core.CorrectiveDrivers(poses, falloff=math.radians(70)).weights(q)
        base = rest + np.einsum("k,kvj->vj", w, np.asarray(offsets))
        skinner = _core.Skinner(base, joints, weights, len(t), preserve_volume=True, rest_matrices=rest_matrices)
        posed = skinner.deform(t).astype(np.float64)
        head = np.asarray(c.bone_heads)[bone]
        head_posed = (pose[bone] @ np.linalg.inv(np.asarray(c.bone_rest)[bone]) @ np.append(head, 1.0))[:3]
        near = np.linalg.norm(posed - head_posed, axis=1) < 0.05 * size
        assert near.sum() > 20
        sculpt = posed.copy()
        sculpt[near] += 0.005 * size * (1.0 - (np.linalg.norm(posed[near] - head_posed, axis=1) / (0.05 * size)) ** 2)[:, None] ** 3
        sculpts.append(sculpt)
        offsets[-1] = _core.rest_space_offsets(skinner, t, base, sculpt)
    drivers = _core.CorrectiveDrivers(poses, falloff=math.radians(70))
    assert len(sculpts) == len(cases) > 0
    for (name, _bone, rotations), sculpt in zip(cases, sculpts):
        pose = pose_of(c, rotations)
        t = transforms_of(c, rig, pose)
        w = drivers.weights(_core.bone_local_rotations(c, pose))
        base = rest + np.einsum("k,kvj->vj", w, np.asarray(offsets))
        skinner = _core.Skinner(base, joints, weights, len(t), preserve_volume=True, rest_matrices=rest_matrices)
        err = np.linalg.norm(skinner.deform(t) - sculpt, axis=1).max() / size
        print(f"makehuman_muscular_male {name}: sculpt reproduced to {err:.2e} of the size, weights {np.round(w, 3)}")
        assert err < 1e-6, (name, err)
    assert np.abs(drivers.weights(_core.bone_local_rotations(c, _core.rest_pose(c)))).max() == 0.0
