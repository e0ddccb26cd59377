# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier for hybrid skinning: the rig built in Blender with rig_io (muscle joints as deform bones,
combined weights as vertex groups, posed joint matrices on pose bones) is skinned by Blender's own
Armature modifier exactly as the core's Equation 3 skinner does (1e-5 relative to the character's size),
on the generated arm and on makehuman_muscular_male, in several poses with non-uniform joint scale;
PC2 caches written by the core play back through the Mesh Cache modifier.

Run (ctest does this with the environment set):
    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_skinning.py
"""
import os
import sys
import tempfile

import bpy
from mathutils import Quaternion
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402

blender_io, core_loader, rig_io = (runner.addon_module(n) for n in ("blender_io", "core_loader", "rig_io"))

MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TOLERANCE = 1e-5  # Blender (float32) against the core, relative to the character's bounding-box diagonal


# ------------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------------

def core():
    return core_loader.core()


def clear_scene():
    if bpy.context.object is not None and bpy.context.object.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for coll in (bpy.data.meshes, bpy.data.armatures):
        for block in list(coll):
            if block.users == 0:
                coll.remove(block)
    bpy.context.scene.frame_set(1)


def synthetic_arm_in_blender():
    """(armature_obj, mesh_obj, character read back from Blender) for the generated arm."""
    clear_scene()
    character, _truth = core().make_synthetic_arm(seed=1)
    arm_obj, mesh_obj = blender_io.character_to_blender(character, "Arm")
    return arm_obj, mesh_obj, blender_io.character_from_blender(mesh_obj, arm_obj)


def makehuman_in_blender():
    """The MakeHuman character through Blender's glTF importer, read back as a core character."""
    path = runner.shared_file(MUSCULAR)
    clear_scene()
    runner.addon_module("gltf_io").import_gltf(path)
    mesh_obj = next(o for o in bpy.context.scene.objects if o.type == 'MESH')
    arm_obj = blender_io.find_armature(mesh_obj)
    for mod in mesh_obj.modifiers:  # the comparison needs the linear (non preserve-volume) modifier
        if mod.type == 'ARMATURE':
            mod.use_deform_preserve_volume = False
            mod.use_bone_envelopes = False
    return arm_obj, mesh_obj, blender_io.character_from_blender(mesh_obj, arm_obj)


def extent(character):
    lo, hi = character.bounding_box()
    return float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))


def set_pose(arm_obj, rotations):
    """rotations: {bone name: (w, x, y, z)}; every other bone at rest. Returns #B by 4 by 4 PoseBone.matrix
    in the character's bone order after the update."""
    for pb in arm_obj.pose.bones:
        pb.rotation_mode = 'QUATERNION'
        pb.rotation_quaternion = rotations.get(pb.name, (1.0, 0.0, 0.0, 0.0))
        pb.location = (0.0, 0.0, 0.0)
        pb.scale = (1.0, 1.0, 1.0)
    bpy.context.view_layer.update()


def axis_angle(axis, degrees):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    half = np.radians(degrees) / 2
    return (float(np.cos(half)), *(float(v) for v in np.sin(half) * axis))


def compare(arm_obj, mesh_obj, character, combined_names, joints, weights, joint_names=(), joint_matrices=None,
            bind=None):
    """Max |Blender - core| / extent for the current pose (skeleton pose read from Blender, joints written)."""
    skeleton_names = list(character.bone_names)
    pose = rig_io.pose_bone_matrices(arm_obj, skeleton_names)
    if len(joint_names):
        rig_io.write_joint_matrices(arm_obj, joint_names, joint_matrices,
                                    {n: pose[i] for i, n in enumerate(skeleton_names)})
        bpy.context.view_layer.update()
    transforms = core().skeleton_transforms(character, pose)
    if len(joint_names):
        transforms = np.concatenate([transforms, np.asarray(joint_matrices) @ np.linalg.inv(bind)])
    expected = core().Skinner(character.vertices, joints, weights, len(combined_names)).deform(transforms)
    got = blender_io.evaluated_vertices(mesh_obj, arm_obj)
    moved = float(np.abs(expected - np.asarray(character.vertices)).max())
    return float(np.abs(got - expected).max()) / extent(character), moved


def scaled_extra_joints(character, per_bone=3, seed=0):
    """Extra joints on the character's most-weighted bones (bind = the bone frame moved along the bone),
    and weights: the skeleton weights with 40 % moved to the nearest extra joint of the vertex's main bone.
    Returns (joint names, bind #J x 4 x 4, parent names, joints #V x K+1, weights #V x K+1)."""
    rest = np.asarray(character.bone_rest)
    names = list(character.bone_names)
    wj, wv = np.asarray(character.weight_joints), np.asarray(character.weight_values)
    totals = np.bincount(wj[wj >= 0], weights=wv[wj >= 0], minlength=len(names))
    chosen = np.argsort(-totals)[:6]
    jnames, bind, parents, owner = [], [], [], []
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    for b in chosen:
        for k in range(per_bone):
            m = rest[b].copy()
            m[:3, 3] = heads[b] + (tails[b] - heads[b]) * (k + 0.5) / per_bone
            jnames.append(f"extra_{b}.j{k}")
            bind.append(m)
            parents.append(names[b])
            owner.append(b)
    bind = np.array(bind)
    owner = np.array(owner)
    nv, K = wj.shape
    joints = np.concatenate([wj, np.full((nv, 1), -1, np.int32)], axis=1)
    weights = np.concatenate([wv, np.zeros((nv, 1))], axis=1)
    main = wj[np.arange(nv), np.argmax(wv, axis=1)]
    verts = np.asarray(character.vertices)
    for j0 in range(0, len(jnames), per_bone):
        b = owner[j0]
        mask = main == b
        if not mask.any():
            continue
        d = np.linalg.norm(verts[mask][:, None, :] - bind[j0:j0 + per_bone, None, :3, 3].transpose(1, 0, 2), axis=2)
        nearest = j0 + np.argmin(d, axis=1)
        weights[mask, :K] *= 0.6
        joints[mask, K] = len(names) + nearest
        weights[mask, K] = 0.4 * weights[mask, :K].sum(axis=1) / 0.6
    return jnames, bind, parents, joints.astype(np.int32), weights


def posed_extra_joints(character, pose, bind, parents, seed):
    """Joint matrices following their parent bone, with a non-uniform scale diag(s, lambda, s)."""
    rng = np.random.default_rng(seed)
    names = list(character.bone_names)
    rest = np.asarray(character.bone_rest)
    out = np.empty_like(bind)
    for j, p in enumerate(parents):
        b = names.index(p)
        s, lam = rng.uniform(0.8, 1.3), rng.uniform(0.7, 1.2)
        out[j] = pose[b] @ np.linalg.inv(rest[b]) @ bind[j] @ np.diag([s, lam, s, 1.0])
    return out


# ------------------------------------------------------------------------------------------------
# Equation 3 in Blender == the core
# ------------------------------------------------------------------------------------------------

def check_extra_joint_rig(arm_obj, mesh_obj, character, poses):
    jnames, bind, parents, joints, weights = scaled_extra_joints(character)
    assert rig_io.create_muscle_bones(arm_obj, jnames, bind, parents) == jnames
    bones = arm_obj.data.bones
    for n, p in zip(jnames, parents):
        b = bones[n]
        assert b.use_deform and b.bbone_segments == 1 and not b.use_envelope_multiply and b.parent.name == p
        assert rig_io.in_muscle_layer(b)
    combined = list(character.bone_names) + jnames
    rig_io.write_combined_weights(mesh_obj, combined, joints, weights)
    errors = []
    assert poses
    for i, rotations in enumerate(poses):
        set_pose(arm_obj, rotations)
        pose = rig_io.pose_bone_matrices(arm_obj, list(character.bone_names))
        err, moved = compare(arm_obj, mesh_obj, character, combined, joints, weights, jnames,
                             posed_extra_joints(character, pose, bind, parents, seed=i), bind)
        assert moved > 1e-3, "the pose should move the skin"
        errors.append(err)
    print(f"  Blender vs core, {len(poses)} poses with scaled joints: max relative error {max(errors):.2e}")
    assert max(errors) < TOLERANCE, errors
    assert rig_io.remove_muscle_bones(arm_obj) == len(jnames)
    assert not any(n in arm_obj.data.bones for n in jnames)
    assert not any(g.name in jnames for g in mesh_obj.vertex_groups)


def test_blender_equals_core_on_the_arm_with_scaled_joints():
    arm_obj, mesh_obj, character = synthetic_arm_in_blender()
    check_extra_joint_rig(arm_obj, mesh_obj, character, [
        {"forearm": axis_angle((0, 0, 1), 90)},
        {"forearm": axis_angle((0, 0, 1), 140), "upper_arm": axis_angle((1, 0, 0), 30)},
        {"hand": axis_angle((1, 1, 0), 45), "clavicle": axis_angle((0, 1, 0), 10)},
    ])


def test_joint_matrices_with_bones_in_euler_rotation():
    """write_joint_matrices leaves a skeleton bone in Euler mode as the user set it, and poses a joint bone
    switched to Euler mode through matrix_basis: Blender still equals the core."""
    arm_obj, mesh_obj, character = synthetic_arm_in_blender()
    jnames, bind, parents, joints, weights = scaled_extra_joints(character)
    rig_io.create_muscle_bones(arm_obj, jnames, bind, parents)
    combined = list(character.bone_names) + jnames
    rig_io.write_combined_weights(mesh_obj, combined, joints, weights)
    set_pose(arm_obj, {"forearm": axis_angle((1, 0, 0), 80)})
    hand = arm_obj.pose.bones["hand"]
    hand.rotation_mode = 'XYZ'
    hand.rotation_euler = (0.4, 0.0, 0.2)
    arm_obj.pose.bones[jnames[1]].rotation_mode = 'ZXY'
    bpy.context.view_layer.update()
    pose = rig_io.pose_bone_matrices(arm_obj, list(character.bone_names))
    err, moved = compare(arm_obj, mesh_obj, character, combined, joints, weights, jnames,
                         posed_extra_joints(character, pose, bind, parents, seed=5), bind)
    assert moved > 1e-3 and err < TOLERANCE, (err, moved)
    assert tuple(hand.rotation_euler) == tuple(np.float32([0.4, 0.0, 0.2]))  # left as the user set it


def test_blender_equals_core_on_makehuman_with_scaled_joints():
    arm_obj, mesh_obj, character = makehuman_in_blender()
    names = list(character.bone_names)
    pick = [n for n in names if any(k in n.lower() for k in ("upperarm", "lowerarm", "thigh", "calf", "spine"))]
    pick = pick or names[1:6]
    rng = np.random.default_rng(3)
    poses = [{n: axis_angle(rng.normal(size=3), rng.uniform(10, 60)) for n in pick[i::3]} for i in range(3)]
    check_extra_joint_rig(arm_obj, mesh_obj, character, poses)


def check_muscle_rig(arm_obj, mesh_obj, character, muscles, poses):
    """The hybrid rig (extracted muscles, MuscleRig, hybrid weights) built in Blender with rig_io equals the
    core in every pose; returns the largest relative error and the largest |s - lambda| of a joint."""
    rig = core().MuscleRig(character, muscles)
    joints, weights = core().hybrid_weights(character, rig)
    skeleton_names = list(character.bone_names)
    joint_names = list(rig.joint_names)
    assert rig_io.create_rig_bones(arm_obj, rig, skeleton_names) == joint_names
    assert set(rig_io.muscle_bone_names(arm_obj)) == set(joint_names)
    bones = arm_obj.data.bones
    parent_index = np.asarray(rig.joint_parent_bone)
    assert len(parent_index) == len(joint_names) > 0
    for n, p in zip(joint_names, parent_index):
        assert bones[n].parent.name == skeleton_names[p] and bones[n].use_deform
    combined = skeleton_names + joint_names
    rig_io.write_combined_weights(mesh_obj, combined, joints, weights)
    back_joints, back_weights = rig_io.read_combined_weights(mesh_obj, combined)
    dense = np.zeros((len(joints), len(combined)))
    back = np.zeros_like(dense)
    rows = np.arange(len(joints))[:, None]
    np.add.at(dense, (np.broadcast_to(rows, joints.shape)[joints >= 0], joints[joints >= 0]), weights[joints >= 0])
    np.add.at(back, (np.broadcast_to(rows, back_joints.shape)[back_joints >= 0], back_joints[back_joints >= 0]),
              back_weights[back_joints >= 0])
    assert np.abs(dense - back).max() < 1e-6  # vertex groups hold the combined weights (float32)
    errors, anisotropy = [], 0.0
    assert poses
    for rotations in poses:
        set_pose(arm_obj, rotations)
        pose = rig_io.pose_bone_matrices(arm_obj, skeleton_names)
        matrices = rig.evaluate(pose)["joint_matrices"]
        scale = np.linalg.norm(matrices[:, :3, :3], axis=1)  # column norms: (s, lambda, s)
        anisotropy = max(anisotropy, float(np.abs(scale[:, 0] - scale[:, 1]).max()))
        rig_io.write_joint_matrices(arm_obj, joint_names, matrices, {n: pose[i] for i, n in enumerate(skeleton_names)})
        bpy.context.view_layer.update()
        assert np.abs(rig_io.pose_bone_matrices(arm_obj, joint_names) - matrices).max() < 1e-5
        transforms = core().skinning_transforms(character, pose, rig, matrices)
        expected = core().Skinner(character.vertices, joints, weights, len(combined)).deform(transforms)
        got = blender_io.evaluated_vertices(mesh_obj, arm_obj)
        assert np.abs(expected - np.asarray(character.vertices)).max() > 1e-3, "the pose should move the skin"
        errors.append(float(np.abs(got - expected).max()) / extent(character))
    print(f"  {rig.num_muscles} muscles, {rig.num_joints} joints as bones, {len(poses)} poses: max relative "
          f"error {max(errors):.2e}, largest |s - lambda| of a joint {anisotropy:.3f}")
    assert max(errors) < TOLERANCE, errors
    assert anisotropy > 0.05, "some pose should scale a muscle joint non-uniformly"
    return max(errors), anisotropy


def test_blender_equals_core_with_the_muscle_rig_on_the_arm():
    arm_obj, mesh_obj, character = synthetic_arm_in_blender()
    muscles, _report = core().extract_muscles(character)
    assert len(muscles) == 6  # seed 1's six muscles, as the core tiers find them
    check_muscle_rig(arm_obj, mesh_obj, character, muscles, [
        {"forearm": axis_angle((1, 0, 0), 70)},
        {"forearm": axis_angle((1, 0, 0), 140)},
        {"forearm": axis_angle((1, 0, 0), 100), "upper_arm": axis_angle((0, 0, 1), 40),
         "hand": axis_angle((1, 0, 0), -30)},
    ])


def test_blender_equals_core_with_the_muscle_rig_on_makehuman():
    arm_obj, mesh_obj, character = makehuman_in_blender()
    muscles, _report = core().extract_muscles(character)
    assert len(muscles) >= 12, len(muscles)  # the core tiers' floor on this body (measured 20)
    names = list(character.bone_names)
    spanned = sorted({m.insertion_bone for m in muscles if m.insertion_bone != m.origin_bone} |
                     {m.origin_bone for m in muscles})
    rng = np.random.default_rng(7)
    poses = [{n: axis_angle(rng.normal(size=3), rng.uniform(20, 70)) for n in spanned[i::2]} for i in range(2)]
    poses.append({n: axis_angle((1, 0, 0), 60) for n in names if "lowerarm" in n.lower() or "calf" in n.lower()})
    check_muscle_rig(arm_obj, mesh_obj, character, muscles, poses)


def test_joint_bones_from_1_mm_to_100_m_and_up_to_1_km_away_bind():
    """Blender re-derives matrix_local from float32 head, tail and roll: a short bone far from the origin
    comes back off by more than a fixed 1e-5; the check follows float32 precision (rig_io.rest_tolerance)."""
    arm_obj, _mesh, _character = synthetic_arm_in_blender()
    rng = np.random.default_rng(3)
    worst = largest = 0.0
    for length in (1e-3, 1e-2, 1.0, 100.0):
        for distance in (0.0, 1.0, 30.0, 1000.0):
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            bind = np.eye(4)
            bind[:3, :3] = np.array(Quaternion(q).to_matrix())
            direction = rng.normal(size=3)
            bind[:3, 3] = distance * direction / np.linalg.norm(direction)
            name = f"j_{length:g}_{distance:g}"
            assert rig_io.create_muscle_bones(arm_obj, [name], bind[None], ["forearm"], [length]) == [name]
            bone = arm_obj.data.bones[name]
            err = float(np.abs(np.array(bone.matrix_local) - bind)[:3, :3].max())
            rot_tol, _ = rig_io.rest_tolerance(bind, length)
            assert err <= rot_tol, (name, err, rot_tol)
            worst = max(worst, err / max(1.0, distance / length))
            largest = max(largest, err)
            rig_io.remove_muscle_bones(arm_obj, [name])
    # round-off relative to distance / length stays small, far from a real rotation error; the fixed 1e-5
    # this replaces refused some of these bones
    assert worst < 1e-4 and largest > 1e-5, (worst, largest)


def test_rig_io_bad_input():
    arm_obj, mesh_obj, character = synthetic_arm_in_blender()
    bind = np.tile(np.eye(4), (2, 1, 1))
    for kwargs, message in [
        (dict(joint_names=["a", "a"], bind_matrices=bind, parent_bones=["forearm"] * 2), "unique"),
        (dict(joint_names=["a", "b"], bind_matrices=bind[:1], parent_bones=["forearm"] * 2), "2 by 4 by 4"),
        (dict(joint_names=["a", "b"], bind_matrices=bind, parent_bones=["nope", "forearm"]), "'nope'"),
        (dict(joint_names=["a", "b"], bind_matrices=bind * np.nan, parent_bones=["forearm"] * 2), "NaN"),
    ]:
        try:
            rig_io.create_muscle_bones(arm_obj, **kwargs)
        except ValueError as e:
            assert message in str(e), (message, str(e))
        else:
            raise AssertionError(f"no error for {kwargs}")
    scaled = bind.copy()
    scaled[0] = np.diag([2.0, 1.0, 1.0, 1.0])
    try:
        rig_io.create_muscle_bones(arm_obj, ["a", "b"], scaled, ["forearm"] * 2)
    except RuntimeError as e:
        assert "rigid" in str(e)
    else:
        raise AssertionError("a scaled bind matrix must be refused")
    rig_io.remove_muscle_bones(arm_obj)
    nv = len(mesh_obj.data.vertices)
    names = list(character.bone_names)
    for joints, weights, message in [
        (np.full((nv, 1), 9), np.ones((nv, 1)), "vertex 0 slot 0 uses joint 9"),
        (np.zeros((nv, 1)), -np.ones((nv, 1)), "vertex 0 slot 0 has weight -1"),
        (np.zeros((nv, 2)), np.ones((nv, 1)), "must both be #V by K"),
        (np.zeros((3, 1)), np.ones((3, 1)), "3 weight rows"),
    ]:
        try:
            rig_io.write_combined_weights(mesh_obj, names, joints, weights)
        except ValueError as e:
            assert message in str(e), (message, str(e))
        else:
            raise AssertionError(f"no error for {message}")
    try:
        rig_io.write_joint_matrices(arm_obj, ["forearm"], np.zeros((2, 4, 4)))
    except ValueError as e:
        assert "1 by 4 by 4" in str(e)
    else:
        raise AssertionError("wrong joint matrix count must be refused")
    try:
        rig_io.pose_bone_matrices(mesh_obj)
    except ValueError as e:
        assert "not an armature" in str(e)
    else:
        raise AssertionError("a mesh is not an armature")


# ------------------------------------------------------------------------------------------------
# PC2 through Blender's Mesh Cache modifier
# ------------------------------------------------------------------------------------------------

def test_pc2_plays_back_through_mesh_cache():
    arm_obj, mesh_obj, character = synthetic_arm_in_blender()
    frames = []
    for degrees in (0, 70, 140):
        set_pose(arm_obj, {"forearm": axis_angle((0, 0, 1), degrees)})
        pose = rig_io.pose_bone_matrices(arm_obj, list(character.bone_names))
        frames.append(core().Skinner(character.vertices, character.weight_joints, character.weight_values,
                                     character.num_bones).deform(core().skeleton_transforms(character, pose)))
    path = os.path.join(tempfile.mkdtemp(prefix="myoskin_pc2_"), "arm.pc2")
    core().write_pc2(path, np.stack(frames), start_frame=1.0)
    cached = bpy.data.objects.new("Cached", mesh_obj.data.copy())
    bpy.context.scene.collection.objects.link(cached)
    mod = cached.modifiers.new("Cache", 'MESH_CACHE')
    mod.cache_format = 'PC2'
    mod.filepath = path
    mod.frame_start = 1.0
    for i in range(3):
        bpy.context.scene.frame_set(1 + i)
        got = blender_io.evaluated_vertices(cached)
        err = float(np.abs(got - frames[i]).max())
        assert err < 1e-6, (i, err)


runner.run()
