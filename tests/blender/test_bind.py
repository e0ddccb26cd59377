# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: Bind / live update / Unbind / Bake / export — the hybrid rig inside Blender.

Asserts: rest pose unchanged to 1e-6 m; Blender's skin equals the core's Equation 3 to 1e-5 m; the biceps
bulges on flexion; IK pose == the equivalent FK pose (no lag); save/reload gives identical coordinates;
Unbind restores the weights exactly; bad input gives clear messages and loses no weights.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_bind.py
"""
import json
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, evaluated, operator_error, weights_of  # noqa: E402

MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TMP = tempfile.mkdtemp(prefix="myoskin_test_bind_")




def bound_arm(seed=1):
    """The synthetic arm, extracted and bound; returns (arm, skin, state, original weights)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=seed, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    original = weights_of(skin)
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    return arm, skin, arm.myoskin, original


def flex(arm, degrees, bone="forearm"):
    pb = arm.pose.bones[bone]
    pb.rotation_mode = 'XYZ'
    pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)


def key_elbow(arm, keys):
    """Key the forearm's flexion: keys = ((frame, degrees), ...). Returns the forearm's pose bone."""
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in keys:
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    return pb


def joint_names(state):
    return json.loads(state.bind_text.as_string())["joint_names"]


def core_skin(arm, skin, state):
    """The core's Equation 3 for the current evaluated skeleton pose, in the mesh object's space, in the mode
    Blender skins it with (Preserve Volume by default)."""
    live = module("live")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    rig_io = module("rig_io")
    names = rig.bone_names + rig.joint_names
    joints, weights = rig_io.read_combined_weights(skin, names)
    io = module("blender_io")
    to_mesh = np.linalg.inv(io.mesh_to_armature_matrix(skin, arm))[:3, :3]
    # the volume keys (shape keys before the Armature modifiers) at the core's weights for this pose
    rest = io.mesh_vertices(skin.data) + module("volume_keys").pose_offsets(skin, arm, rig.character, pose) @ to_mesh.T
    joint_matrices = rig.rig.evaluate(pose)["joint_matrices"]
    transforms = np.concatenate([pose @ np.linalg.inv(np.asarray(rig.character.bone_rest)),
                                 joint_matrices @ np.linalg.inv(np.asarray(rig.rig.bind_matrices))])
    return module("binding").skinner_for(skin, arm, rig, rest, joints, weights).deform(transforms)


# ------------------------------------------------------------------------------------------------
# Bind
# ------------------------------------------------------------------------------------------------

def influence_counts(skin):
    """Bones and muscle joints per vertex (the volume blend's share and linear groups are no influence)."""
    skip = {skin.vertex_groups[n].index for n in module("binding").MIX_GROUPS if n in skin.vertex_groups}
    return np.array([sum(g.weight > 0 for g in v.groups if g.group not in skip) for v in skin.data.vertices])


def test_max_influences_caps_every_vertex_and_blender_still_equals_the_core():
    arm, skin, state, _ = bound_arm()
    counts = influence_counts(skin)
    assert state.max_influences == 8 and counts.max() > 4, counts.max()  # the arm reaches 7
    state.max_influences = 4
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    counts = influence_counts(skin)
    assert counts.max() == 4, counts.max()
    state.max_influences = 2
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    counts = influence_counts(skin)
    assert counts.max() == 2, counts.max()
    names = joint_names(state)
    assert sum(1 for v in skin.data.vertices for g in v.groups if skin.vertex_groups[g.group].name in names) > 100
    key_elbow(arm, ((1, 0.0), (5, 100.0)))
    bpy.context.scene.frame_set(4)
    err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
    assert err < 1e-5, err


def test_bind_creates_joint_bones_weights_and_keeps_the_modifier():
    arm, skin, state, original = bound_arm()
    names = joint_names(state)
    rig_io = module("rig_io")
    assert names and set(names) == set(rig_io.muscle_bone_names(arm))
    enabled = [m.name for m in state.muscles if m.enabled]
    assert {n.rsplit(".j", 1)[0] for n in names} == set(enabled)
    for n in names:
        bone = arm.data.bones[n]
        assert bone.use_deform and rig_io.in_muscle_layer(bone)
        assert bone.parent is not None and not bone.parent.get("myoskin_joint")
        assert n in skin.vertex_groups
    weights = weights_of(skin)
    assert sum(len(weights[n]) for n in names) > 100  # muscle joints carry real weight
    binding = module("binding")
    mods = [m for m in skin.modifiers if m.type == 'ARMATURE']
    # the character's own modifier, then (Volume Blend, the default) the blend's second one
    assert len(mods) == 2 and mods[0].object == arm and not binding.is_volume_blend_modifier(mods[0])
    assert binding.is_volume_blend_modifier(mods[1]) and mods[1].object == arm
    # the first modifier deforms the vertices the blend mixes linear into (its linear group, weight 1)
    assert mods[0].vertex_group == binding.LINEAR_GROUP and not mods[0].invert_vertex_group
    share, linear = weights.pop(binding.VOLUME_BLEND_GROUP), weights.pop(binding.LINEAR_GROUP)  # no influences
    assert linear and set(linear.values()) == {1.0} and len(linear) < len(skin.data.vertices), len(linear)
    assert share and all(0.0 < w <= 1.0 for w in share.values())
    # every vertex's weights still sum to 1 (skeleton + muscles)
    total = np.zeros(len(skin.data.vertices))
    for group in weights.values():
        for v, w in group.items():
            total[v] += w
    assert np.abs(total - 1.0).max() < 1e-4
    # the original weights are saved in the file
    assert "myoskin_original_weights" in skin and state.bound and not state.dirty


def test_rest_pose_unchanged():
    arm, skin, state, _ = bound_arm()
    rest = module("blender_io").mesh_vertices(skin.data)
    err = np.abs(evaluated(skin) - rest).max()
    assert err < 1e-6, f"bound skin at rest moved by {err:.3g} m"


def test_blender_equals_core_when_posed():
    arm, skin, state, _ = bound_arm()
    flex(arm, 100.0)
    arm.pose.bones["upper_arm"].rotation_mode = 'XYZ'
    arm.pose.bones["upper_arm"].rotation_euler = (0.2, 0.1, 0.5)
    blender = evaluated(skin)
    reference = core_skin(arm, skin, state)
    err = np.abs(blender - reference).max()
    assert err < 1e-5, f"Blender's skin differs from the core's Equation 3 by {err:.3g} m"
    assert np.abs(blender - module("blender_io").mesh_vertices(skin.data)).max() > 0.05


def test_biceps_bulges_on_flexion():
    arm, skin, state, original = bound_arm()
    flex(arm, 120.0)
    bound = evaluated(skin)
    live = module("live")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    result = rig.rig.evaluate(pose)
    stretch = np.asarray(result["stretch"])
    shortened = int(np.argmin(stretch))
    assert stretch[shortened] < 0.95, stretch
    # plain LBS with the original skeleton weights, same pose
    character = module("blender_io").character_from_blender(skin, arm)
    lbs = core().skin(np.asarray(character.vertices), np.asarray(character.weight_joints),
                      np.asarray(character.weight_values), core().skeleton_transforms(character, pose))
    # skin over the shortened muscle's belly moves outward (along the posed normal) against plain LBS
    muscle = rig.rig.muscles[shortened]
    centers, radii = np.asarray(muscle.section_centers), np.asarray(muscle.section_a)
    mid = len(centers) // 2
    rest = np.asarray(character.vertices)
    belly = np.linalg.norm(rest - centers[mid], axis=1) < 1.5 * radii[mid]
    assert belly.sum() > 20, belly.sum()
    normals = core().vertex_normals(lbs, np.asarray(character.triangles))
    outward = np.einsum("ij,ij->i", bound - lbs, normals)[belly]
    print(f"  bulge over the belly of {muscle.name} (stretch {stretch[shortened]:.3f}): "
          f"max {outward.max() * 1000:.2f} mm, median {np.median(outward) * 1000:.2f} mm")
    # guards the bulge itself (a rig that only followed the skeleton gives 0 here); measured on blender 3.4: 14.5 mm
    # max, 9.3 mm median at stretch 0.68
    assert outward.max() > 0.002 and np.median(outward) > 0.0005


# ------------------------------------------------------------------------------------------------
# Live update: animation, IK, save/reload
# ------------------------------------------------------------------------------------------------

def test_frame_change_has_no_lag():
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    key_elbow(arm, ((1, 0.0), (10, 110.0), (20, 30.0)))
    for frame in (10, 15, 20, 3):
        scene.frame_set(frame)
        blender = module("blender_io").evaluated_vertices(skin)
        err = np.abs(blender - core_skin(arm, skin, state)).max()
        assert err < 1e-5, f"frame {frame}: skin lags the pose by {err:.3g} m"


def test_ik_pose_equals_fk_pose():
    arm, skin, state, _ = bound_arm()
    target = bpy.data.objects.new("ik_target", None)
    bpy.context.scene.collection.objects.link(target)
    forearm = arm.data.bones["forearm"]
    target.location = np.array(forearm.head_local) + np.array([0.0, 0.12, 0.18])
    ik = arm.pose.bones["forearm"].constraints.new('IK')
    ik.target, ik.chain_count = target, 2
    bpy.context.view_layer.update()
    with_ik = module("blender_io").evaluated_vertices(skin)
    ik_pose = {n: np.array(arm.pose.bones[n].matrix) for n in ("upper_arm", "forearm")}
    moved = np.abs(ik_pose["forearm"] - np.array(forearm.matrix_local)).max()
    assert moved > 0.05, "the IK did not move the forearm"
    assert np.abs(with_ik - core_skin(arm, skin, state)).max() < 1e-5
    # the same pose as plain FK
    arm.pose.bones["forearm"].constraints.remove(ik)
    for n in ("upper_arm", "forearm"):
        arm.pose.bones[n].matrix = ik_pose_matrix(ik_pose[n])
        bpy.context.view_layer.update()
    fk = module("blender_io").evaluated_vertices(skin)
    err = np.abs(fk - with_ik).max()
    assert err < 1e-5, f"IK and the equivalent FK pose differ by {err:.3g} m"


def ik_pose_matrix(m):
    from mathutils import Matrix
    return Matrix(m.tolist())


def test_save_reload_gives_identical_coordinates():
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    key_elbow(arm, ((1, 0.0), (10, 90.0)))
    scene.frame_set(7)
    before = module("blender_io").evaluated_vertices(skin)
    names = (arm.name, skin.name)
    path = os.path.join(TMP, "bound.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    bpy.context.scene.frame_set(1)
    bpy.context.scene.frame_set(7)
    after = module("blender_io").evaluated_vertices(skin)
    assert np.abs(after - before).max() < 1e-6
    bpy.context.scene.frame_set(10)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, arm.myoskin)).max() < 1e-5


def test_muscle_surfaces_follow_the_pose():
    arm, skin, state, _ = bound_arm()
    flex(arm, 110.0)
    bpy.context.view_layer.update()
    live = module("live")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    surfaces = rig.rig.evaluate(pose, with_surfaces=True)["surfaces"]
    enabled = [m for m in state.muscles if m.enabled]
    assert len(enabled) == len(surfaces) > 0
    for item, expected in zip(enabled, surfaces):
        co = np.empty(3 * len(item.surface.data.vertices), dtype=np.float32)
        item.surface.data.vertices.foreach_get("co", co)
        assert np.abs(co.reshape(-1, 3) - expected).max() < 1e-5, item.name
    # hidden muscles are not written (no cost while they are not shown)
    state.collection.hide_viewport = True
    first = enabled[0].surface
    co0 = np.empty(3 * len(first.data.vertices), dtype=np.float32)
    first.data.vertices.foreach_get("co", co0)
    flex(arm, 30.0)
    bpy.context.view_layer.update()
    co1 = np.empty_like(co0)
    first.data.vertices.foreach_get("co", co1)
    assert np.array_equal(co0, co1)


def test_bulge_edit_after_bind_applies_live():
    arm, skin, state, _ = bound_arm()
    flex(arm, 110.0)
    before = evaluated(skin)
    enabled = [m for m in state.muscles if m.enabled]
    for item in enabled:
        item.bulge = 3.0
    assert not state.dirty  # same joints and bind matrices: no new bind needed
    after = evaluated(skin)
    assert np.abs(after - core_skin(arm, skin, state)).max() < 1e-5
    assert np.abs(after - before).max() > 1e-4  # the new bulge shows
    record = json.loads(state.bind_text.as_string())
    assert all(abs(m.bulge - 3.0) < 1e-12 for m in core().muscles_from_json(record["muscles"]))
    # a change of the joint count does change the joints: bind again
    enabled[0].joints = 6
    assert state.dirty


def test_edits_after_bind_ask_for_a_new_bind():
    arm, skin, state, _ = bound_arm()
    assert not state.dirty
    state.muscles[0].insertion_locator.location.z += 0.01
    bpy.context.view_layer.update()
    assert state.dirty
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from fake_layout import draw_panel
    text = draw_panel(bpy.types.MYOSKIN_PT_bind).text()
    assert "Bind again" in text, text
    assert bpy.ops.myoskin.bind() == {'FINISHED'} and not state.dirty
    record = json.loads(state.bind_text.as_string())
    moved = core().muscles_from_json(record["muscles"])[0]
    assert abs(np.asarray(moved.insertion)[2] - np.array(state.muscles[0].insertion_locator.location)[2]) < 1e-9


def test_locator_move_on_a_bound_rig_binds_again_when_still():
    """Auto Rebind: the locator watcher schedules a timer; once the locators are still it binds again, so the
    muscle's joint bones follow the new insertion, the rest pose stays exact and Unbind still restores the
    original weights. (Timers do not run inside a background script: the test calls the timer itself.)"""
    arm, skin, state, original = bound_arm()
    handlers = module("handlers")
    first = joint_names(state)[0]
    muscle0 = first.rsplit(".j", 1)[0]
    names0 = [n for n in joint_names(state) if n.rsplit(".j", 1)[0] == muscle0]
    before = {n: np.array(arm.data.bones[n].matrix_local) for n in names0}
    item = next(m for m in state.muscles if m.name == muscle0)
    item.insertion_locator.location.z += 0.015
    bpy.context.view_layer.update()
    assert state.dirty and bpy.app.timers.is_registered(handlers.rebind_pending)
    assert handlers.rebind_pending() is not None  # not still long enough yet: the timer waits
    assert handlers.rebind_pending(force=True) is None
    assert not state.dirty and state.bound
    after = {n: np.array(arm.data.bones[n].matrix_local) for n in names0}
    assert max(np.abs(after[n] - before[n]).max() for n in names0) > 1e-3  # the joints moved
    record = core().muscles_from_json(json.loads(state.bind_text.as_string())["muscles"])
    moved = next(m for m in record if m.name == muscle0)
    assert abs(np.asarray(moved.insertion)[2] - np.array(item.insertion_locator.location)[2]) < 1e-9
    io = module("blender_io")
    assert np.abs(io.evaluated_vertices(skin) - io.mesh_vertices(skin.data)).max() < 1e-6  # rest exact
    flex(arm, 80.0)
    bpy.context.view_layer.update()
    assert np.abs(io.evaluated_vertices(skin) - core_skin(arm, skin, state)).max() < 1e-5
    # Auto Rebind off: the move only marks the rig
    state.auto_rebind = False
    flex(arm, 0.0)
    item.insertion_locator.location.z -= 0.01
    bpy.context.view_layer.update()
    assert state.dirty
    assert bpy.ops.myoskin.unbind() == {'FINISHED'} and weights_of(skin) == original


def test_two_bound_characters_in_one_scene():
    arm1, skin1, state1, _ = bound_arm(seed=1)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=2, **runner.LIGHT_ARM) == {'FINISHED'}
    skin2 = bpy.context.view_layer.objects.active
    arm2 = skin2.parent
    arm2.location = (1.0, 0.0, 0.0)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'} and bpy.ops.myoskin.bind() == {'FINISHED'}
    assert state1.collection != arm2.myoskin.collection
    flex(arm1, 100.0)
    flex(arm2, 50.0)
    bpy.context.view_layer.update()
    for arm, skin in ((arm1, skin1), (arm2, skin2)):
        assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, arm.myoskin)).max() < 1e-5
        assert len(arm.myoskin.muscles) > 0
        for item in arm.myoskin.muscles:
            assert item.surface.parent == arm and item.surface.name in arm.myoskin.collection.objects


# ------------------------------------------------------------------------------------------------
# Unbind, bake, export
# ------------------------------------------------------------------------------------------------

def test_unbind_restores_original_weights_exactly():
    arm, skin, state, original = bound_arm()
    bones_before = len(arm.data.bones)
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert weights_of(skin) == original
    assert not module("rig_io").muscle_bone_names(arm) and len(arm.data.bones) < bones_before
    assert not state.bound and "myoskin_original_weights" not in skin
    flex(arm, 60.0)
    rest = module("blender_io").character_from_blender(skin, arm)
    assert rest.num_bones == len(arm.data.bones)
    # binding again after an unbind works and gives the same joints
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    assert bpy.ops.myoskin.unbind() == {'FINISHED'} and weights_of(skin) == original


def test_bake_action_plays_without_the_handlers():
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    pb = key_elbow(arm, ((1, 0.0), (5, 100.0)))
    scene.frame_set(4)
    live_result = module("blender_io").evaluated_vertices(skin)
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=5) == {'FINISHED'}
    fcurves = module("anim_compat").object_fcurves(arm.animation_data)
    for n in joint_names(state):
        fc = fcurves.find(f'pose.bones["{n}"].scale', index=1)
        assert fc is not None and len(fc.keyframe_points) == 5 and not fc.mute
    assert not state.live  # the baked Action plays
    calls = dict(module("live").stats)
    scene.frame_set(1)
    scene.frame_set(4)
    assert module("live").stats == calls  # no handler work
    baked = module("blender_io").evaluated_vertices(skin)
    assert np.abs(baked - live_result).max() < 1e-5
    # edit the animation: live update follows it (baked keys muted), the stale bake does not
    pb.rotation_euler = (np.radians(40.0), 0.0, 0.0)
    pb.keyframe_insert("rotation_euler", frame=5)
    state.live = True
    assert fcurves.find(f'pose.bones["{joint_names(state)[0]}"].scale', index=1).mute
    scene.frame_set(4)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max() < 1e-5
    state.live = False
    scene.frame_set(1)
    scene.frame_set(4)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max() > 1e-4
    # baking again replaces the keys and the result is exact again
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=5) == {'FINISHED'}
    scene.frame_set(4)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max() < 1e-5


def test_baked_action_moves_the_muscle_surfaces_too():
    """Live update off (baked): the joints play from the Action and the muscle surfaces still follow."""
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    key_elbow(arm, ((1, 0.0), (5, 120.0)))
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=5) == {'FINISHED'}
    assert not state.live
    live = module("live")
    enabled = [m for m in state.muscles if m.enabled]

    def surfaces_now():
        out = []
        for item in enabled:
            co = np.empty(3 * len(item.surface.data.vertices), dtype=np.float32)
            item.surface.data.vertices.foreach_get("co", co)
            out.append(co.reshape(-1, 3).astype(np.float64))
        return out

    seen = []
    for frame in (5, 1, 5):
        scene.frame_set(frame)
        rig = live.live_rig(arm)
        pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
        expected = rig.rig.evaluate(pose, with_surfaces=True)["surfaces"]
        got = surfaces_now()
        assert len(enabled) == len(got) == len(expected) > 0
        for item, g, e in zip(enabled, got, expected):
            assert np.abs(g - e).max() < 1e-5, (frame, item.name)
        seen.append(got)
    assert max(np.abs(a - b).max() for a, b in zip(seen[0], seen[1])) > 1e-3  # they moved between frames


def test_fk_playback_needs_one_evaluation_ik_is_corrected():
    """F-curve-only skeletons are predicted in frame_change_pre (no second evaluation); an animated IK
    target is corrected from the evaluated pose (exact, no lag)."""
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'QUATERNION'
    for frame, deg in ((1, 0.0), (10, 120.0)):
        pb.rotation_quaternion = (np.cos(np.radians(deg) / 2), np.sin(np.radians(deg) / 2), 0.0, 0.0)
        pb.keyframe_insert("rotation_quaternion", frame=frame)
    stats = module("live").stats
    scene.frame_set(1)
    before = dict(stats)
    for frame in range(2, 10):
        scene.frame_set(frame)
        assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max() < 1e-5
    assert stats["predicted"] - before["predicted"] == 8 and stats["written"] == before["written"], stats
    # a bone without F-curves posed by hand between frames: caught in that frame, predicted again after
    hand = arm.pose.bones["hand"]
    hand.rotation_mode = 'QUATERNION'
    hand.rotation_quaternion = (0.9, 0.3, 0.0, 0.1)
    before = dict(stats)
    for frame in (5, 6):
        scene.frame_set(frame)
        assert np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max() < 1e-5
    assert stats["written"] - before["written"] == 1 and stats["predicted"] - before["predicted"] == 2, stats
    # an IK chain whose target is animated
    target = bpy.data.objects.new("ik_target", None)
    scene.collection.objects.link(target)
    head = np.array(arm.data.bones["forearm"].head_local)
    for frame, offset in ((1, (0.0, 0.25, 0.05)), (10, (0.0, 0.1, 0.2))):
        target.location = head + np.array(offset)
        target.keyframe_insert("location", frame=frame)
    ik = arm.pose.bones["forearm"].constraints.new('IK')
    ik.target, ik.chain_count = target, 2
    scene.frame_set(1)
    before = dict(stats)
    for frame in (3, 6, 9, 4):
        scene.frame_set(frame)
        err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
        assert err < 1e-5, f"frame {frame} with IK: {err:.3g} m"
        assert len(skin.modifiers) >= 2 and all(m.show_viewport for m in skin.modifiers)
        assert not module("runtime").deferred
    assert stats["written"] - before["written"] == 4 and stats["predicted"] == before["predicted"], stats
    # from Blender 4.3 the first pass of each of those frames skipped the skinning (live.defer_skinning)
    deferring = module("live").DEFER_SKINNING
    assert deferring == (bpy.app.version >= (4, 3, 0))
    assert stats["deferred"] - before["deferred"] == (4 if deferring else 0), stats


def test_deferred_skinning_spares_simulations_user_switches_and_saved_files():
    """The first pass of an IK-driven frame skips the skinning only where nothing keeps state from it: a skin
    with a Collision modifier (cloth colliding with it) is skinned in both passes; a modifier the user
    switched off stays off; a file saved between the two passes keeps its modifiers on; every frame equals
    the core."""
    arm, skin, state, _ = bound_arm()
    scene, live, runtime = bpy.context.scene, module("live"), module("runtime")
    stats = live.stats
    limit = arm.pose.bones["forearm"].constraints.new('LIMIT_ROTATION')  # unpredictable: read after evaluation
    limit.use_limit_x, limit.min_x, limit.max_x = True, 0.0, 1.2
    key_elbow(arm, ((1, 0.0), (10, 100.0)))
    scene.frame_set(9)  # the limit acts: a prediction cached before the constraint existed is dropped here

    def play(frames, exact=True):
        assert frames
        before = stats["deferred"]
        for frame in frames:
            scene.frame_set(frame)
            if exact:
                err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
                assert err < 1e-5, f"frame {frame}: {err:.3g} m"
            assert not runtime.deferred
        return stats["deferred"] - before

    expected = 3 if live.DEFER_SKINNING else 0
    count = play((4, 8, 6))
    assert count == expected, (count, expected)
    collision = skin.modifiers.new("Collision", 'COLLISION')
    assert play((3, 7, 5)) == 0
    skin.modifiers.remove(collision)
    garment = bpy.data.objects.new("Garment", bpy.data.meshes.new("Garment"))  # a cloth elsewhere in the scene
    scene.collection.objects.link(garment)
    garment.modifiers.new("Cloth", 'CLOTH')
    assert play((4, 8, 6)) == 0
    bpy.data.objects.remove(garment)
    assert play((3, 7, 5)) == expected
    blend = module("binding").volume_blend_modifier(skin, arm)
    blend.show_viewport = False  # the user's switch: not deferred, not switched back on
    assert play((2, 9), exact=False) == (2 if live.DEFER_SKINNING else 0)
    assert not blend.show_viewport
    blend.show_viewport = True
    if live.DEFER_SKINNING:  # a save between the passes (frame_change_pre alone) saves the modifiers on
        live.on_frame_change_pre(scene)
        assert runtime.deferred and not module("binding").armature_modifier(skin, arm).show_viewport
        path = os.path.join(TMP, "deferred.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path)
        assert not runtime.deferred and len(skin.modifiers) >= 2 and all(m.show_viewport for m in skin.modifiers)
        name = skin.name
        bpy.ops.wm.open_mainfile(filepath=path)
        reloaded = bpy.data.objects[name]
        assert len(reloaded.modifiers) >= 2 and all(m.show_viewport for m in reloaded.modifiers)


def test_fk_prediction_covers_rotation_modes_location_and_scale():
    """The frame_change_pre prediction reads every rotation mode, location and scale channel as Blender
    does: every frame predicted, none rewritten from the evaluated pose, Blender equals the core; a
    constraint added after the prediction was cached is caught in the same frame (exact, no lag)."""
    arm, skin, state, _ = bound_arm()
    scene = bpy.context.scene
    keys = {  # bone: (rotation mode, channel, value at frame 1, value at frame 9)
        "clavicle": ('ZXY', "rotation_euler", (0.05, -0.1, 0.08), (-0.1, 0.15, -0.05)),
        "upper_arm": ('AXIS_ANGLE', "rotation_axis_angle", (0.0, 0.0, 0.0, 1.0), (0.5, 0.3, 1.0, 0.2)),
        "forearm": ('YXZ', "rotation_euler", (0.0, 0.0, 0.0), (1.4, 0.2, -0.1)),
        "hand": ('QUATERNION', "rotation_quaternion", (2.0, 0.0, 0.0, 0.0), (1.5, 0.4, 0.1, -0.3)),
    }
    for name, (mode, channel, first, last) in keys.items():
        pb = arm.pose.bones[name]
        pb.rotation_mode = mode
        for frame, value in ((1, first), (9, last)):
            setattr(pb, channel, value)
            pb.keyframe_insert(channel, frame=frame)
    clavicle, hand = arm.pose.bones["clavicle"], arm.pose.bones["hand"]
    assert hand.bone.use_connect and not clavicle.bone.use_connect  # Blender ignores the hand's location
    for frame, (loc, size) in ((1, ((0, 0, 0), 1.0)), (9, ((0.01, 0.02, -0.01), 1.1))):
        clavicle.location = hand.location = loc
        hand.scale = (size,) * 3
        for pb in (clavicle, hand):
            pb.keyframe_insert("location", frame=frame)
        hand.keyframe_insert("scale", frame=frame)
    stats = module("live").stats
    scene.frame_set(1)
    before = dict(stats)
    for frame in range(2, 9):
        scene.frame_set(frame)
        err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
        assert err < 1e-5, f"frame {frame}: {err:.3g} m"
    assert stats["predicted"] - before["predicted"] == 7 and stats["written"] == before["written"], stats
    limit = arm.pose.bones["forearm"].constraints.new('LIMIT_ROTATION')
    limit.use_limit_x, limit.min_x, limit.max_x = True, 0.0, 0.5
    before = dict(stats)
    scene.frame_set(7)
    err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
    assert err < 1e-5 and stats["written"] - before["written"] == 1, (err, stats)


def test_hand_posing_skins_once():
    """Channels set by hand (or a script) are posed in depsgraph_update_pre, before Blender evaluates: every rotation
    mode, location and scale, connected bones; no rewrite from the evaluated pose afterwards, Blender equals the
    core. A skeleton with a constraint is not predicted there and is still corrected from the evaluated pose."""
    arm, skin, state, _ = bound_arm()
    stats, view_layer = module("live").stats, bpy.context.view_layer
    poses = [  # bone: (rotation mode, channel, value)
        {"clavicle": ('ZXY', "rotation_euler", (0.05, -0.1, 0.08)), "forearm": ('XYZ', "rotation_euler", (1.2, 0, 0))},
        {"upper_arm": ('AXIS_ANGLE', "rotation_axis_angle", (0.5, 0.3, 1.0, 0.2)),
         "hand": ('QUATERNION', "rotation_quaternion", (0.9, 0.3, 0.0, 0.1))},
        {"forearm": ('YXZ', "rotation_euler", (0.4, 0.2, -0.1))},
    ]
    before = dict(stats)
    for k, pose in enumerate(poses):
        for name, (mode, channel, value) in pose.items():
            pb = arm.pose.bones[name]
            pb.rotation_mode = mode
            setattr(pb, channel, value)
        arm.pose.bones["clavicle"].location = (0.01 * k, 0.02, -0.01)
        arm.pose.bones["hand"].scale = (1.0 + 0.05 * k,) * 3
        view_layer.update()
        err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
        assert err < 1e-5, f"pose {k}: {err:.3g} m"
    assert stats["posed"] - before["posed"] == 3 and stats["written"] == before["written"], stats
    view_layer.update()  # nothing moved: nothing written
    assert stats["posed"] - before["posed"] == 3
    limit = arm.pose.bones["forearm"].constraints.new('LIMIT_ROTATION')
    limit.use_limit_x, limit.min_x, limit.max_x = True, 0.0, 0.3
    before = dict(stats)
    arm.pose.bones["forearm"].rotation_euler = (0.9, 0.1, 0.0)  # the limit holds it at 0.3
    view_layer.update()
    err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
    assert err < 1e-5 and stats["written"] - before["written"] == 1, (err, stats)
    before = dict(stats)
    arm.pose.bones["forearm"].rotation_euler = (0.8, 0.3, 0.0)
    view_layer.update()
    err = np.abs(module("blender_io").evaluated_vertices(skin) - core_skin(arm, skin, state)).max()
    assert err < 1e-5 and stats["posed"] == before["posed"] and stats["written"] - before["written"] == 1, (err, stats)
    assert state.live and not module("runtime").last_error(arm)  # no handler failed on the way


def test_export_gltf_with_helper_bones():
    arm, skin, state, _ = bound_arm()
    path = os.path.join(TMP, "bound.glb")
    assert bpy.ops.myoskin.export_gltf(filepath=path) == {'FINISHED'}
    loaded = core().load_character(path)
    assert set(joint_names(state)) <= set(loaded.bone_names)
    assert loaded.num_bones == len(arm.data.bones)


def test_pc2_bake_equals_blender():
    arm, skin, state, _ = bound_arm()
    key_elbow(arm, ((1, 0.0), (3, 90.0)))
    path = os.path.join(TMP, "skin.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=3) == {'FINISHED'}
    cache = core().read_pc2(path)
    assert cache["frames"].shape == (3, len(skin.data.vertices), 3) and cache["start_frame"] == 1.0
    for k, frame in enumerate((1, 2, 3)):
        bpy.context.scene.frame_set(frame)
        err = np.abs(module("blender_io").evaluated_vertices(skin) - cache["frames"][k]).max()
        assert err < 1e-5, f"frame {frame}: PC2 differs from Blender by {err:.3g} m"


def test_pc2_modifier_replaces_the_armature_until_unbind():
    arm, skin, state, original = bound_arm()
    key_elbow(arm, ((1, 0.0), (3, 90.0)))
    live_skin = []
    for frame in (1, 2, 3):
        bpy.context.scene.frame_set(frame)
        live_skin.append(module("blender_io").evaluated_vertices(skin))
    path = os.path.join(TMP, "cached.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=3, add_modifier=True) == {'FINISHED'}
    armature = module("binding").armature_modifier(skin, arm)
    assert not armature.show_viewport and not armature.show_render
    assert [m.type for m in skin.modifiers].count('MESH_CACHE') == 1
    for k, frame in enumerate((1, 2, 3)):
        bpy.context.scene.frame_set(frame)
        err = np.abs(module("blender_io").evaluated_vertices(skin) - live_skin[k]).max()
        assert err < 1e-5, f"frame {frame}: the cache plays {err:.3g} m away from the live skin"
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert armature.show_viewport and armature.show_render
    assert not any(m.type == 'MESH_CACHE' for m in skin.modifiers)
    assert weights_of(skin) == original


# ------------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------------

def test_bind_bad_input():
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.view_layer.objects.active = None
    assert "No active object" in operator_error(bpy.ops.myoskin.bind)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    assert "run Extract Muscles first" in operator_error(bpy.ops.myoskin.bind)
    assert "is not bound" in operator_error(bpy.ops.myoskin.unbind)
    assert "run Extract Muscles first" in operator_error(bpy.ops.myoskin.bake_action)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert "Bind first" in operator_error(bpy.ops.myoskin.bake_pc2, filepath=os.path.join(TMP, "x.pc2"))
    for m in skin.parent.myoskin.muscles:
        m.enabled = False
    before = weights_of(skin)
    assert "disabled" in operator_error(bpy.ops.myoskin.bind)
    assert weights_of(skin) == before and not module("rig_io").muscle_bone_names(skin.parent)
    # a failure half-way (here: a weight row count that does not fit the skin) leaves the rig as it was
    for m in skin.parent.myoskin.muscles:
        m["enabled"] = True
    rig_ops = module("binding")
    real = rig_ops.hybrid_weights
    rig_ops.hybrid_weights = lambda core, character, rig, *k: tuple(a[:-1] for a in real(core, character, rig, *k))
    try:
        text = operator_error(bpy.ops.myoskin.bind)
    finally:
        rig_ops.hybrid_weights = real
    assert "weight rows" in text, text
    assert weights_of(skin) == before and not module("rig_io").muscle_bone_names(skin.parent)
    assert not skin.parent.myoskin.bound and "myoskin_original_weights" not in skin


def test_deleted_muscle_object_and_renamed_bones_after_bind():
    arm, skin, state, original = bound_arm()
    # a muscle surface deleted by hand: the rig keeps working
    bpy.data.objects.remove(state.muscles[0].surface)
    flex(arm, 80.0)
    assert np.abs(evaluated(skin) - core_skin(arm, skin, state)).max() < 1e-5
    # a skeleton bone renamed after the bind: live update stops with a message; bake and rebind say why
    arm.data.bones["hand"].name = "hand_renamed"
    flex(arm, 40.0)
    bpy.context.view_layer.update()
    assert not state.live
    # ...and the handler's message is stored where the panels show it (sidebar and modifier tab), not only
    # printed: the runtime's last error of this armature, drawn with a Dismiss button
    runtime = module("runtime")
    message = runtime.last_error(arm)
    assert "renamed or deleted" in message and "'hand'" in message, message
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from fake_layout import draw_panel
    bpy.context.view_layer.objects.active = skin
    for panel in (bpy.types.MYOSKIN_PT_main, bpy.types.MYOSKIN_PT_skin_muscles):
        layout = draw_panel(panel)
        assert " ".join(message.split()) in " ".join(layout.text().split()), (panel, layout.text())
        assert ("operator", "myoskin.clear_error") in layout.log, panel
    text = operator_error(bpy.ops.myoskin.bake_action, frame_start=1, frame_end=2)
    assert "renamed or deleted" in text, text
    # unbind still restores every original weight (the renamed bone's group was renamed with it)
    assert "hand_renamed" in skin.vertex_groups
    assert runtime.last_error(arm)  # still shown until dismissed, or Bind / Unbind succeeds
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert runtime.last_error(arm) == "" and ("operator", "myoskin.clear_error") not in \
        draw_panel(bpy.types.MYOSKIN_PT_main).log
    restored = weights_of(skin)
    assert restored.pop("hand_renamed") == original.pop("hand") and restored == original


def test_undo_after_bind_loses_no_weights():
    """Undo restores the file as it was before the bind. Background Blender has no window for ed.undo, so
    the same memfile restore is done by reverting to the state saved right before the bind; the live
    handler's cache (keyed by armature name) must not apply the stale rig."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    names = (skin.parent.name, skin.name)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    original = weights_of(skin)
    path = os.path.join(TMP, "before_bind.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    flex(skin.parent, 90.0)
    bpy.context.view_layer.update()
    try:
        bpy.ops.ed.undo()
        undone = True
    except RuntimeError:
        undone = False
    if not undone:
        bpy.ops.wm.open_mainfile(filepath=path)
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    assert not arm.myoskin.bound and not module("rig_io").muscle_bone_names(arm)
    assert weights_of(skin) == original
    flex(arm, 70.0)
    posed = evaluated(skin)  # plain skeleton skinning again, no error from a stale cache
    character = module("blender_io").character_from_blender(skin, arm)
    pose = np.array([np.array(arm.pose.bones[n].matrix) for n in character.bone_names])
    lbs = core().skin(np.asarray(character.vertices), np.asarray(character.weight_joints),
                      np.asarray(character.weight_values), core().skeleton_transforms(character, pose))
    assert np.abs(posed - lbs).max() < 1e-5
    # and binding again from there works
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.bind() == {'FINISHED'}


def belly_bulge(arm, skin, muscle_index, pose):
    """(stretch of the muscle, #belly outward displacements of the bound skin against plain LBS)."""
    live = module("live")
    rig = live.live_rig(arm)
    stretch = float(np.asarray(rig.rig.evaluate(pose)["stretch"])[muscle_index])
    character = module("blender_io").character_from_blender(skin, arm)
    backup = skin["myoskin_original_weights"]
    names = list(character.bone_names)
    rows = [[] for _ in range(len(skin.data.vertices))]
    for name, entry in backup.items():
        if name in names:
            for v, w in zip(entry["vertices"], entry["weights"]):
                rows[v].append((names.index(name), w))
    k = max(len(r) for r in rows)
    joints = np.full((len(rows), k), -1, dtype=np.int32)
    weights = np.zeros((len(rows), k))
    for v, r in enumerate(rows):
        for j, (b, w) in enumerate(r):
            joints[v, j], weights[v, j] = b, w
    lbs = core().skin(np.asarray(character.vertices), joints, weights, core().skeleton_transforms(character, pose))
    bound = module("blender_io").evaluated_vertices(skin, arm)
    muscle = rig.rig.muscles[muscle_index]
    centers, radii = np.asarray(muscle.section_centers), np.asarray(muscle.section_a)
    mid = len(centers) // 2
    belly = np.linalg.norm(np.asarray(character.vertices) - centers[mid], axis=1) < 1.5 * radii[mid]
    normals = core().vertex_normals(lbs, np.asarray(character.triangles))
    return stretch, np.einsum("ij,ij->i", bound - lbs, normals)[belly]


def test_makehuman_end_to_end():
    """Import, extract, attach a biceps to the forearm with its locator, bind, pose elbow and shoulder,
    evaluate; bulge on flexion; rest exact; save/reload identical."""
    path = runner.shared_file(MUSCULAR)
    bpy.ops.wm.read_homefile(use_empty=True)
    module("gltf_io").import_gltf(path)
    skin = [o for o in bpy.context.scene.objects if o.type == 'MESH'][0]
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm = module("blender_io").find_armature(skin)
    state = arm.myoskin
    # the left biceps (found on this body by every tier: test_extraction's anatomical names); it used to be picked
    # as "a muscle inserting on upperarm02.L", and skipped when none did, which it always did once the ends were
    # carried across the elbow (ExtractionOptions::ends.spanCarry): the test ran nothing
    arms = [i for i, m in enumerate(state.muscles) if m.name == "biceps.L"]
    assert arms, [m.name for m in state.muscles]
    # move the insertion a fifth of the way down the forearm and snap it there
    state.active_index = arms[0]
    item = state.muscles[arms[0]]
    fore = arm.data.bones["lowerarm01.L"]
    head, tail = np.array(fore.head_local), np.array(fore.tail_local)
    item.insertion_locator.location = head + 0.2 * (tail - head)
    bpy.context.view_layer.update()
    assert bpy.ops.myoskin.snap_locator(end='insertion') == {'FINISHED'}
    assert item.insertion_bone == "lowerarm01.L", item.insertion_bone
    # the reference in the mode Bind sets (state.preserve_volume): Blender's float32 dual quaternions move this
    # body's plain skeleton skin 2.3e-6 m at rest by themselves (a toe, 0.85 m from the origin; 1.3e-6 of the
    # size); the bind's own change measured against that is 6.6e-7 m on 3.4 and 2.1e-6 m on 4.5 (its pivot scale
    # path rounds the identity muscle joints differently). The core's rest pose is exact (test_hybrid_skinning);
    # here Blender's float32 blend is the limit: 2e-6 of the body's size
    for mod in skin.modifiers:
        if mod.type == 'ARMATURE':
            mod.use_deform_preserve_volume = state.preserve_volume
    bpy.context.view_layer.update()
    rest = evaluated(skin)
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    err = np.abs(evaluated(skin) - rest).max()
    size = float(np.linalg.norm(np.ptp(rest, axis=0)))
    assert err < 2e-6 * size, f"MakeHuman rest pose moved by {err:.3g} m after bind ({err / size:.2e} of the size)"
    muscle_index = [m.name for m in state.muscles if m.enabled].index(item.name)
    live = module("live")
    best = None
    for sign in (1.0, -1.0):
        pb = arm.pose.bones["lowerarm01.L"]
        pb.rotation_mode = 'XYZ'
        pb.rotation_euler = (sign * np.radians(80.0), 0.0, 0.0)
        sh = arm.pose.bones["upperarm01.L"]
        sh.rotation_mode = 'XYZ'
        sh.rotation_euler = (0.0, 0.0, np.radians(20.0))
        posed = evaluated(skin)
        assert np.abs(posed - rest).max() > 0.02
        assert np.abs(posed - core_skin(arm, skin, state)).max() < 1e-5
        pose = live.evaluated_pose(arm, live.live_rig(arm), bpy.context.evaluated_depsgraph_get())
        stretch, outward = belly_bulge(arm, skin, muscle_index, pose)
        if best is None or stretch < best[0]:
            best = (stretch, outward, sign)
    stretch, outward, sign = best
    print(f"  MakeHuman {item.name}: stretch {stretch:.3f} on flexion, belly bulge max "
          f"{outward.max() * 1000:.2f} mm, median {np.median(outward) * 1000:.2f} mm")
    # the biceps shortens and lifts its belly (measured on blender 3.4: stretch 0.841, 4.38 mm max, 3.11 mm median)
    assert stretch < 0.97 and outward.max() > 0.002 and np.median(outward) > 0.0
    # save / reload: identical coordinates
    arm.pose.bones["lowerarm01.L"].rotation_euler = (sign * np.radians(80.0), 0.0, 0.0)
    before = evaluated(skin)
    names = (arm.name, skin.name)
    out = os.path.join(TMP, "makehuman.blend")
    bpy.ops.wm.save_as_mainfile(filepath=out)
    bpy.ops.wm.open_mainfile(filepath=out)
    skin = bpy.data.objects[names[1]]
    assert np.abs(evaluated(skin) - before).max() < 1e-6


runner.run()
