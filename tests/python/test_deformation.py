"""Muscle deformation through _core: MuscleRig on muscles extracted from the synthetic arm."""
import math

import numpy as np
import pytest

from conftest import MUSCULAR, shared


@pytest.fixture(scope="module")
def arm_rig(core):
    character, _ = core.make_synthetic_arm(seed=1)
    muscles, _ = core.extract_muscles(character)
    assert muscles, "the default arm has muscles to rig"
    return character, muscles, core.MuscleRig(character, muscles)


def quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return [math.cos(angle / 2), *(math.sin(angle / 2) * axis)]


def elbow_pose(core, character, angle):
    q = np.tile([1.0, 0, 0, 0], (character.num_bones, 1))
    q[character.bone_names.index("forearm")] = quat([1, 0, 0], angle)
    return core.pose_from_rotations(character, q)


def test_pose_from_channels(core, arm_rig):
    """Blender's pose-bone channels -> FK: rest at default channels, quaternions equal pose_from_rotations,
    an XYZ Euler equals the same rotation as a quaternion, bad input is a ValueError."""
    character = arm_rig[0]
    nb = character.num_bones
    loc, scale = np.zeros((nb, 3)), np.ones((nb, 3))
    rot = np.tile([1.0, 0, 0, 0], (nb, 1))
    np.testing.assert_allclose(core.pose_from_channels(character, loc, [0] * nb, rot, scale),
                               core.rest_pose(character), atol=1e-12)
    fore = character.bone_names.index("forearm")
    rot[fore] = quat([1, 0, 0], 1.2)
    expected = core.pose_from_rotations(character, rot)
    np.testing.assert_allclose(core.pose_from_channels(character, loc, [0] * nb, rot, scale), expected, atol=1e-12)
    modes = [0] * nb
    modes[fore] = 1  # Euler XYZ
    rot[fore] = [1.2, 0.0, 0.0, 0.0]
    np.testing.assert_allclose(core.pose_from_channels(character, loc, modes, rot, scale), expected, atol=1e-12)
    with pytest.raises(ValueError, match="rotation mode 7"):
        core.pose_from_channels(character, loc, [7] * nb, rot, scale)
    with pytest.raises(ValueError, match="rows"):
        core.pose_from_channels(character, loc[1:], modes, rot, scale)
    scale[0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        core.pose_from_channels(character, loc, modes, rot, scale)


def test_rest_pose_gives_bind_matrices_and_rest_surfaces(core, arm_rig):
    character, muscles, rig = arm_rig
    assert rig.num_muscles == len(muscles)
    assert rig.num_joints == sum(m.joints for m in muscles) == len(rig.joint_names)
    out = rig.evaluate(core.rest_pose(character), with_surfaces=True)
    bind = rig.bind_matrices
    assert out["joint_matrices"].shape == (rig.num_joints, 4, 4)
    np.testing.assert_allclose(out["joint_matrices"], bind, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["stretch"], 1.0, atol=1e-12)
    assert len(out["surfaces"]) == len(muscles) > 0
    for i, s in enumerate(out["surfaces"]):
        np.testing.assert_allclose(s, rig.rest_surface(i)[0], atol=1e-12)
    # Bind matrices are rigid, joints are parented to their muscle's origin bone.
    r = bind[:, :3, :3]
    np.testing.assert_allclose(np.einsum("nji,njk->nik", r, r), np.tile(np.eye(3), (len(r), 1, 1)), atol=1e-12)
    for j, name in enumerate(rig.joint_names):
        mu = muscles[rig.joint_muscle[j]]
        assert name.startswith(mu.name + ".j")
        assert character.bone_names[rig.joint_parent_bone[j]] == mu.origin_bone


def test_flexion_shortens_and_bulges_muscles_across_the_elbow(core, arm_rig):
    character, muscles, rig = arm_rig
    out = rig.evaluate(elbow_pose(core, character, math.radians(120)), with_surfaces=True)
    crossing = [i for i, m in enumerate(muscles) if m.origin_bone != m.insertion_bone]
    assert crossing, "some extracted muscle spans the elbow"
    shortened = [i for i in crossing if out["stretch"][i] < 0.95]
    assert shortened, "flexing the elbow 120 degrees shortens a muscle across it"
    for i in crossing:
        if i in shortened:
            j = rig.joint_offset(i) + rig.joint_count(i) // 2
            s = np.linalg.norm(out["joint_matrices"][j][:3, 0])
            assert s > 1.0, "a shortened muscle thickens"
        v, t = out["surfaces"][i], rig.rest_surface(i)[1]
        assert np.isfinite(v).all() and v.shape == rig.rest_surface(i)[0].shape


def test_wrap_settings_and_bad_input(core, arm_rig):
    character, muscles, _ = arm_rig
    m = muscles[0]
    m.wrap_type, m.wrap_bone, m.wrap_radius = "joint", "forearm", 1e-4
    rig = core.MuscleRig(character, [m], joints_override=3)
    assert rig.num_joints == 3
    m.wrap_radius = 0.0
    with pytest.raises(ValueError, match="radius"):
        core.MuscleRig(character, [m])
    m.wrap_type = "none"
    m.origin_bone = "no_such_bone"
    with pytest.raises(ValueError, match="no_such_bone"):
        core.MuscleRig(character, [m])
    rig = core.MuscleRig(character, muscles[1:])
    with pytest.raises(ValueError, match="4 by 4"):
        rig.evaluate(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="bones"):
        rig.evaluate(np.tile(np.eye(4), (character.num_bones + 1, 1, 1)))
    bad = core.rest_pose(character)
    bad[1, 0, 3] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        rig.evaluate(bad)
    with pytest.raises(ValueError, match="quaternion"):
        core.pose_from_rotations(character, np.zeros((character.num_bones, 4)))


def test_makehuman_muscles_rig_and_follow_a_pose(core):
    character = core.load_character(shared(MUSCULAR))
    muscles, _ = core.extract_muscles(character)
    assert len(muscles) >= 12  # the C++ tier's floor on this body (test_extraction MakeHumanMuscularVersusNeutral)
    rig = core.MuscleRig(character, muscles)
    rest = rig.evaluate(core.rest_pose(character))["joint_matrices"]
    np.testing.assert_allclose(rest, rig.bind_matrices, atol=1e-9)
    q = np.tile([1.0, 0, 0, 0], (character.num_bones, 1))
    bent = [name for name in character.bone_names
            if "lowerarm" in name or "forearm" in name or "lowerleg" in name or "shin" in name]
    assert bent, "the elbows and knees are posed"
    for name in bent:
        q[character.bone_names.index(name)] = quat([1, 0, 0], 0.8)
    out = rig.evaluate(core.pose_from_rotations(character, q))
    assert np.isfinite(out["joint_matrices"]).all()
    # the muscles across the bent elbows and knees change length (a rig that ignored the pose stays at 1)
    assert np.abs(np.asarray(out["stretch"]) - 1.0).max() > 0.05
    print(f"makehuman_muscular_male: {rig.num_muscles} muscles, {rig.num_joints} joints, "
          f"stretch range {out['stretch'].min():.3f}-{out['stretch'].max():.3f}")


def test_results_are_copies_and_deterministic(core, arm_rig):
    character, _, rig = arm_rig
    a = rig.evaluate(elbow_pose(core, character, 1.0), with_surfaces=True)
    keep = a["joint_matrices"].copy(), a["surfaces"][0].copy()
    b = rig.evaluate(elbow_pose(core, character, 2.0), with_surfaces=True)
    np.testing.assert_array_equal(a["joint_matrices"], keep[0])
    np.testing.assert_array_equal(a["surfaces"][0], keep[1])
    assert not np.allclose(b["joint_matrices"], a["joint_matrices"])
    c = rig.evaluate(elbow_pose(core, character, 1.0), with_surfaces=True)
    np.testing.assert_array_equal(c["joint_matrices"], keep[0])


@pytest.mark.parametrize("seed", [1, 26])
def test_rig_does_not_jump_when_blender_rounds_the_pose_to_float32(core, seed):
    """Blender hands the rig float32 pose matrices. A parent bone turned while the limbs stay straight (the rest pose of
    the generated arm and bodies) brought a wrapped muscle's origin, joint centre and insertion into line, where its
    wrap plane swung round the joint with the rounding: the same pose in float64 and float32 moved the skin by up to
    6.3 mm (arm) and 5.8 mm (biped 26). Now the muscle's side holds the plane there (paths::jointWrapWays)."""
    character = core.make_synthetic_arm(seed=1)[0] if seed == 1 else core.make_synthetic_body(seed=seed)[0]
    muscles, _ = core.extract_muscles(character)
    rig = core.MuscleRig(character, muscles)
    hj, hw = core.hybrid_weights(character, rig)
    rest = np.asarray(character.vertices)
    size = np.ptp(rest, axis=0).max()
    parents, heads = np.asarray(character.bone_parents), np.asarray(character.bone_heads)
    bone_rest = np.asarray(character.bone_rest)
    rng = np.random.default_rng(seed)
    turned = [b for b in range(len(parents)) if (parents == b).any()]
    assert turned and len(muscles) >= 4
    worst = 0.0
    for b in turned[:12]:
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        t = np.radians(rng.uniform(5, 30))
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        m = np.eye(4)
        m[:3, :3] = np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k
        m[:3, 3] = heads[b] - m[:3, :3] @ heads[b]
        moved = np.zeros(len(parents), bool)
        for i in range(len(parents)):  # parents come first
            moved[i] = i == b or (parents[i] >= 0 and moved[parents[i]])
        pose = bone_rest.copy()
        pose[moved] = m @ bone_rest[moved]
        skins = []
        for p in (pose, pose.astype(np.float32).astype(np.float64)):
            joints = rig.evaluate(p)["joint_matrices"]
            skins.append(np.asarray(core.skin(rest, hj, hw, core.skinning_transforms(character, p, rig, joints))))
        worst = max(worst, np.abs(skins[0] - skins[1]).max())
    assert worst < 1e-5 * size, f"float32 rounding moved the skin by {worst:.3g} (size {size:.3g})"
