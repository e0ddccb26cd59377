# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier for Preserve Volume: the rig setting makes Bind switch the Armature modifier's
use_deform_preserve_volume on, and Blender's dual quaternion skin then equals the core's preserve-volume
skinner (1e-5 of the character's size) with the muscle joints bulging (scaled joint bones), a scaled skeleton
bone, elbow flexion and shoulder abduction; the rest pose stays exact (1e-6 of the size); the setting follows
on a bound rig, Unbind gives the modifier its own setting back, and Bake PC2 computes the same mode. The volume
blend (Volume Blend: the share group and a second Armature modifier with Multi Modifier) equals the core's too, Bake
PC2 computes it and Unbind restores the character exactly.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_preserve_volume.py
"""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, evaluated, size_of  # noqa: E402

TOLERANCE = 1e-5  # Blender (float32) against the core, relative to the character's bounding-box diagonal
TMP = tempfile.mkdtemp(prefix="myoskin_test_preserve_volume_")




def armature_modifier(skin, arm):
    return next(m for m in skin.modifiers if m.type == 'ARMATURE' and m.object == arm)


def bound_arm(preserve_volume=True, seed=1, volume_blend=False):
    """The synthetic arm, extracted, Preserve Volume (and the volume blend) set, bound; returns (arm, skin, state)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=seed, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm.myoskin.preserve_volume = preserve_volume
    arm.myoskin.volume_blend = volume_blend
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    return arm, skin, arm.myoskin


def core_skin(arm, skin, preserve_volume, share=None):
    """The core's skin for the current evaluated pose (mesh object space), in the given mode (`share`: the volume
    blend with these #V dual-quaternion shares); also the largest |scale - 1| of a muscle joint in this pose."""
    live, rig_io, io = module("live"), module("rig_io"), module("blender_io")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    joints, weights = rig_io.read_combined_weights(skin, rig.bone_names + rig.joint_names)
    joint_matrices = rig.rig.evaluate(pose)["joint_matrices"]
    transforms = np.concatenate([pose @ np.linalg.inv(np.asarray(rig.character.bone_rest)),
                                 joint_matrices @ np.linalg.inv(np.asarray(rig.rig.bind_matrices))])
    rest = io.mesh_vertices(skin.data)
    bulge = float(np.abs(np.linalg.norm(joint_matrices[:, :3, :3], axis=1) - 1.0).max())
    if share is not None:  # the volume keys (shape keys before the modifiers) at the core's weights for this pose
        rest = rest + volume_key_offsets(arm, skin, rig, pose)
        return core().skin(rest, joints, weights, transforms, dqs_share=share,
                           rest_matrices=core().combined_rest_matrices(rig.character, rig.rig),
                           dq_scale=module("binding").dq_scale()), bulge
    if not preserve_volume:
        return core().skin(rest, joints, weights, transforms), bulge
    return core().skin(rest, joints, weights, transforms, preserve_volume=True,
                       rest_matrices=core().combined_rest_matrices(rig.character, rig.rig),
                       dq_scale=module("binding").dq_scale()), bulge


def volume_key_offsets(arm, skin, rig, pose):
    """#V by 3 (mesh space): the volume keys' offsets at the core's weights for `pose`."""
    to_mesh = np.linalg.inv(module("blender_io").mesh_to_armature_matrix(skin, arm))[:3, :3]
    return module("volume_keys").pose_offsets(skin, arm, rig.character, pose) @ to_mesh.T


def set_pose(arm, rotations, scales=None):
    """rotations {bone: (x, y, z) Euler degrees}, scales {bone: (sx, sy, sz)}; every other bone at rest."""
    for pb in arm.pose.bones:
        if pb.name not in ("clavicle", "upper_arm", "forearm", "hand"):
            continue
        pb.rotation_mode = 'XYZ'
        pb.rotation_euler = tuple(np.radians(rotations.get(pb.name, (0.0, 0.0, 0.0))))
        pb.scale = (scales or {}).get(pb.name, (1.0, 1.0, 1.0))


POSES = [  # (name, rotations, scales)
    ("elbow 120", {"forearm": (120.0, 0.0, 0.0)}, None),
    ("elbow 70", {"forearm": (70.0, 0.0, 0.0)}, None),
    ("shoulder abduction 90 + elbow 60", {"upper_arm": (0.0, 0.0, 90.0), "forearm": (60.0, 0.0, 0.0)}, None),
    ("shoulder 120 forward, wrist", {"upper_arm": (-120.0, 20.0, 0.0), "hand": (30.0, 0.0, 20.0)}, None),
    # Scaled skeleton bones: uniform on the upper arm (its children inherit it without shear: a non-uniform
    # one shears the muscle joints below it, which a Blender bone cannot take, in either mode), non-uniform on
    # the hand (a leaf).
    ("elbow 110, scaled upper arm and hand", {"forearm": (110.0, 0.0, 0.0), "hand": (20.0, 0.0, 30.0)},
     {"upper_arm": (1.1, 1.1, 1.1), "hand": (1.2, 0.85, 1.1)}),
]


def test_bind_sets_preserve_volume_and_blender_equals_the_core():
    arm, skin, state = bound_arm(preserve_volume=True)
    mod = armature_modifier(skin, arm)
    assert mod.use_deform_preserve_volume, "Bind should switch the modifier's Preserve Volume on"
    size = size_of(skin)
    rest = module("blender_io").mesh_vertices(skin.data)
    at_rest = evaluated(skin)
    rest_err = float(np.abs(at_rest - rest).max()) / size
    expected_rest, _ = core_skin(arm, skin, True)
    assert rest_err < 1e-6 and np.abs(expected_rest - rest).max() / size < 1e-6, rest_err
    errors, bulges = [], []
    for name, rotations, scales in POSES:
        set_pose(arm, rotations, scales)
        blender = evaluated(skin)
        expected, bulge = core_skin(arm, skin, True)
        linear, _ = core_skin(arm, skin, False)
        err = float(np.abs(blender - expected).max()) / size
        differs = float(np.abs(blender - linear).max()) / size
        print(f"  {name}: Blender preserve volume vs core {err:.2e} of the size (vs linear {differs:.2e}), "
              f"largest muscle joint |scale - 1| {bulge:.3f}")
        assert differs > 1e-3, f"{name}: Blender's skin looks linear; is Preserve Volume on?"
        errors.append(err)
        bulges.append(bulge)
    print(f"  rest pose error {rest_err:.2e}; max Blender vs core in preserve volume {max(errors):.2e} "
          f"(Blender {bpy.app.version_string})")
    assert max(errors) < TOLERANCE, errors
    assert max(bulges) > 0.02, "some pose should bulge (scale) the muscle joints"


def test_the_setting_follows_on_a_bound_rig_and_unbind_restores_the_modifier():
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    mod = armature_modifier(skin, arm)  # the character's own modifier, kept by Bind
    mod.use_deform_preserve_volume = False
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    state = arm.myoskin
    state.preserve_volume = True
    state.volume_blend = False  # Preserve Volume alone
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    assert armature_modifier(skin, arm).use_deform_preserve_volume
    set_pose(arm, {"forearm": (100.0, 0.0, 0.0)})
    size = size_of(skin)
    state.preserve_volume = False  # bound: the modifier follows at once
    assert not armature_modifier(skin, arm).use_deform_preserve_volume
    assert np.abs(evaluated(skin) - core_skin(arm, skin, False)[0]).max() / size < TOLERANCE
    state.preserve_volume = True
    assert armature_modifier(skin, arm).use_deform_preserve_volume
    assert np.abs(evaluated(skin) - core_skin(arm, skin, True)[0]).max() / size < TOLERANCE
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert not armature_modifier(skin, arm).use_deform_preserve_volume, "Unbind restores the modifier's own setting"
    state.preserve_volume = False  # unbound: nothing to follow, no error
    assert not state.bound


def test_pc2_bake_uses_the_same_mode_and_equals_blender():
    arm, skin, state = bound_arm(preserve_volume=True)
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, degrees in ((1, 0.0), (3, 120.0)):
        pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    path = os.path.join(TMP, "skin.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=3) == {'FINISHED'}
    frames = core().read_pc2(path)["frames"]
    size = size_of(skin)
    errors = []
    for k, frame in enumerate((1, 2, 3)):
        bpy.context.scene.frame_set(frame)
        blender = module("blender_io").evaluated_vertices(skin)
        errors.append(float(np.abs(blender - frames[k]).max()) / size)
    linear, _ = core_skin(arm, skin, False)
    print(f"  PC2 (preserve volume) vs Blender: {max(errors):.2e} of the size")
    assert max(errors) < TOLERANCE, errors
    assert np.abs(frames[2] - linear).max() / size > 1e-3  # the bake really is in the preserve-volume mode


def character_snapshot(skin):
    """What Unbind must give back: the modifier stack (type, object, Preserve Volume, Multi Modifier, group) and
    every vertex group with its members' weights."""
    mods = [(m.type, getattr(m, "object", None) and m.object.name, getattr(m, "use_deform_preserve_volume", None),
             getattr(m, "use_multi_modifier", None), getattr(m, "vertex_group", None),
             getattr(m, "invert_vertex_group", None)) for m in skin.modifiers]
    groups = {g.name: {} for g in skin.vertex_groups}
    names = [g.name for g in skin.vertex_groups]
    for v in skin.data.vertices:
        for g in v.groups:
            groups[names[g.group]][v.index] = g.weight
    return mods, names, groups, sorted(skin.keys())


def test_volume_blend_bind_writes_the_group_and_a_second_modifier_and_blender_equals_the_core():
    """Volume Blend: Bind writes the share group and a second Armature modifier (Preserve Volume, Multi Modifier)
    right after the first, which turns linear; Blender's skin then equals the core's volume blend (1e-5 of the size)
    with Bind's shares and with random shares written into the group (every mix in [0, 1]); rest pose exact."""
    binding = module("binding")
    arm, skin, state = bound_arm(preserve_volume=True, volume_blend=True)
    mods = [m for m in skin.modifiers if m.type == 'ARMATURE' and m.object == arm]
    assert len(mods) == 2, [m.name for m in skin.modifiers]
    first, second = mods
    assert list(skin.modifiers).index(second) == list(skin.modifiers).index(first) + 1
    assert not first.use_deform_preserve_volume and second.use_deform_preserve_volume
    assert second.use_multi_modifier and second.vertex_group == binding.VOLUME_BLEND_GROUP
    share = binding.read_share_group(skin)
    assert share is not None and len(share) == len(skin.data.vertices)
    assert share.min() >= 0.0 and share.max() <= 1.0 and share.max() > 0.0
    keys = module("volume_keys").stored(skin)  # the arm's joints keep their volume well: maybe none (the soldier's test)
    assert skin.data.shape_keys is not None or not keys
    size = size_of(skin)
    rest = module("blender_io").mesh_vertices(skin.data)
    rest_err = float(np.abs(evaluated(skin) - rest).max()) / size
    assert rest_err < 1e-6, rest_err
    rng = np.random.default_rng(7)
    errors = []
    for label in ("Bind's shares", "random shares"):
        if label == "random shares":
            binding.write_share_group(skin, rng.uniform(0.0, 1.0, len(share)))
            share = binding.read_share_group(skin)
            assert 0.2 < share.mean() < 0.8
        for name, rotations, scales in POSES:
            set_pose(arm, rotations, scales)
            blender = evaluated(skin)
            expected, _ = core_skin(arm, skin, True, share=share)
            linear, _ = core_skin(arm, skin, False)
            dq, _ = core_skin(arm, skin, True)
            err = float(np.abs(blender - expected).max()) / size
            print(f"  {label}, {name}: Blender volume blend vs core {err:.2e} of the size (vs linear "
                  f"{np.abs(blender - linear).max() / size:.2e}, vs DQS {np.abs(blender - dq).max() / size:.2e})")
            errors.append(err)
            if label == "random shares":  # a real mix: neither mode alone
                assert np.abs(blender - linear).max() / size > 1e-4 and np.abs(blender - dq).max() / size > 1e-4
    print(f"  rest pose error {rest_err:.2e}; max Blender vs core, volume blend {max(errors):.2e} "
          f"(Blender {bpy.app.version_string})")
    assert max(errors) < TOLERANCE, errors


def test_volume_blend_switches_on_a_bound_rig_at_once_and_blender_still_equals_the_core():
    """Volume Blend toggled on a bound rig: off removes the second modifier and the linear group at once (the first
    modifier takes the rig's Preserve Volume over the whole skin), on adds them back from the share group, Blender
    equals the core in each mode; a rig bound with it off has no shares, so switching it on binds again."""
    binding, handlers, runtime = module("binding"), module("handlers"), module("runtime")
    for preserve_volume in (False, True):
        arm, skin, state = bound_arm(preserve_volume=preserve_volume, volume_blend=True)
        first = binding.armature_modifier(skin, arm)
        share = binding.read_share_group(skin)
        assert share is not None and first.vertex_group == binding.LINEAR_GROUP
        set_pose(arm, {"forearm": (110.0, 0.0, 0.0), "upper_arm": (0.0, 0.0, 40.0)})
        size = size_of(skin)
        for on in (False, True, False, True):
            state.volume_blend = on
            assert (binding.volume_blend_modifier(skin, arm) is not None) == on
            assert (first.vertex_group == binding.LINEAR_GROUP) == on
            assert (binding.LINEAR_GROUP in skin.vertex_groups) == on and not state.dirty
            # the blend's first modifier is linear; without the blend it takes the rig's Preserve Volume
            assert first.use_deform_preserve_volume == (preserve_volume and not on)
            expected, _ = core_skin(arm, skin, preserve_volume and not on, share=share if on else None)
            err = float(np.abs(evaluated(skin) - expected).max()) / size
            print(f"  Volume Blend switched {'on' if on else 'off'} while bound (Preserve Volume {preserve_volume}): "
                  f"Blender vs core {err:.2e} of the size")
            assert err < TOLERANCE, (on, err)
        assert json_record(arm)["volume_blend"] is True
    # Bound with it off: no shares yet; on, the rig binds again (Auto Rebind's timer, run here at once).
    arm, skin, state = bound_arm(preserve_volume=True, volume_blend=False)
    assert binding.read_share_group(skin) is None
    state.volume_blend = True
    assert state.dirty and binding.volume_blend_modifier(skin, arm) is None
    handlers.rebind_pending(force=True)
    assert not state.dirty and binding.volume_blend_modifier(skin, arm) is not None
    assert binding.read_share_group(skin) is not None
    state.auto_rebind = False
    state.volume_blend = False
    runtime.clear_error(arm)
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    state.volume_blend = True  # bound off, no Auto Rebind: marked edited, the panels say why
    assert state.dirty and "needs a Bind" in runtime.last_error(arm), runtime.last_error(arm)


def test_joints_slide_switched_on_a_bound_rig_binds_again_and_blender_still_equals_the_core():
    """Joints Slide off (MuscleRig joints_slide=False): the bound rig binds again (Auto Rebind), the bind record and
    the live rig carry the setting, the muscle joints no longer slide along the limb (they move in the bent pose),
    and Blender's volume-blended skin equals the core's with that rig; no Auto Rebind: marked edited, and said."""
    handlers, runtime, live, binding = module("handlers"), module("runtime"), module("live"), module("binding")
    arm, skin, state = bound_arm(preserve_volume=True, volume_blend=True)
    assert state.joints_slide and json_record(arm)["joints_slide"] is True and live.live_rig(arm).rig.joints_slide
    set_pose(arm, {"forearm": (100.0, 0.0, 0.0)})
    size = size_of(skin)
    evaluated(skin)
    names = live.live_rig(arm).joint_names
    before = np.array([arm.pose.bones[n].head for n in names])
    state.joints_slide = False
    assert state.dirty
    handlers.rebind_pending(force=True)
    rig = live.live_rig(arm)
    assert not state.dirty and json_record(arm)["joints_slide"] is False and not rig.rig.joints_slide
    expected, _ = core_skin(arm, skin, True, share=binding.read_share_group(skin))
    err = float(np.abs(evaluated(skin) - expected).max()) / size
    after = np.array([arm.pose.bones[n].head for n in rig.joint_names])
    moved = float(np.abs(after - before).max()) / size
    print(f"  Joints Slide off: Blender vs core {err:.2e} of the size; muscle joints moved {moved:.2e} of the size")
    assert err < TOLERANCE and moved > 1e-3, (err, moved)
    state.auto_rebind = False
    runtime.clear_error(arm)
    state.joints_slide = True
    assert state.dirty and "next Bind" in runtime.last_error(arm), runtime.last_error(arm)
    state.dirty = False
    state.joints_slide = False  # back to what the rig was bound with: nothing to do
    assert not state.dirty
    # A bind record written before the setting existed (no "joints_slide") was bound with sliding joints
    record = json_record(arm)
    del record["joints_slide"]
    binding.write_bind_record(arm, record)
    assert live.live_rig(arm).rig.joints_slide


def test_a_share_group_written_by_the_other_blender_generation_is_rewritten_on_load():
    """3.x's Multi Modifier reads the share group as the linear result's share, 4.x and 5.x as the second modifier's:
    a .blend bound in one and opened in the other gets its group rewritten on load (the same shares mix)."""
    binding, live = module("binding"), module("live")
    arm, skin, state = bound_arm(preserve_volume=False, volume_blend=True)
    share = binding.read_share_group(skin)
    assert share is not None and 0.0 < share.mean() < 1.0
    here = skin[binding.SHARE_CONVENTION_KEY]
    other = "own" if here == "previous" else "previous"
    group = skin.vertex_groups[binding.VOLUME_BLEND_GROUP]  # as the other generation wrote it
    group.remove(list(range(len(skin.data.vertices))))
    ids = np.flatnonzero(share < 1.0) if other == "previous" else np.flatnonzero(share > 0.0)
    module("blender_io").add_group_weights(group, ids, (1.0 - share[ids]) if other == "previous" else share[ids])
    skin[binding.SHARE_CONVENTION_KEY] = other
    assert np.abs(binding.read_share_group(skin) - share).max() < 1e-6  # read the way it was written
    live.on_load()
    assert skin[binding.SHARE_CONVENTION_KEY] == here
    assert np.abs(binding.read_share_group(skin) - share).max() < 1e-6
    set_pose(arm, {"forearm": (110.0, 0.0, 0.0)})
    expected, _ = core_skin(arm, skin, False, share=binding.read_share_group(skin))
    err = float(np.abs(evaluated(skin) - expected).max()) / size_of(skin)
    print(f"  share group rewritten from '{other}' to '{here}': Blender vs core {err:.2e} of the size")
    assert err < TOLERANCE, err


def json_record(arm):
    import json
    return json.loads(arm.myoskin.bind_text.as_string())


def test_volume_blend_unbind_restores_the_character_exactly_and_pc2_equals_blender():
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=2, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    before = character_snapshot(skin)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm.myoskin.volume_blend = True
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    binding = module("binding")
    assert binding.volume_blend_modifier(skin, arm) is not None
    binding.write_share_group(skin, np.linspace(0.0, 1.0, len(skin.data.vertices)))  # every mix, as Bake reads it
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, degrees in ((1, 0.0), (3, 120.0)):
        pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    path = os.path.join(TMP, "blend.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=3) == {'FINISHED'}
    frames = core().read_pc2(path)["frames"]
    size = size_of(skin)
    errors = []
    for k, frame in enumerate((1, 2, 3)):
        bpy.context.scene.frame_set(frame)
        errors.append(float(np.abs(module("blender_io").evaluated_vertices(skin) - frames[k]).max()) / size)
    print(f"  PC2 (volume blend) vs Blender: {max(errors):.2e} of the size")
    assert max(errors) < TOLERANCE, errors
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert binding.volume_blend_modifier(skin, arm) is None
    assert character_snapshot(skin) == before
    assert skin.data.shape_keys is None, "Unbind leaves the volume keys (and the Basis it added)"


def test_a_rig_bound_before_the_default_changed_keeps_its_linear_mode_on_load():
    """Preserve Volume is on by default; a .blend whose rig was bound linear with the setting never stored (as
    the old default left it) opens with the setting off, so the next Bind keeps the mode it was bound with."""
    arm, skin, state = bound_arm(preserve_volume=False)
    assert not state.preserve_volume
    state.property_unset("preserve_volume")  # as a file saved before the default changed
    assert state.preserve_volume and not armature_modifier(skin, arm).use_deform_preserve_volume
    path = os.path.join(TMP, "old_default.blend")
    names = arm.name, skin.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    assert not arm.myoskin.preserve_volume and not armature_modifier(skin, arm).use_deform_preserve_volume
    # a new rig takes the new default
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    assert bpy.context.view_layer.objects.active.parent.myoskin.preserve_volume




def test_volume_keys_of_a_character_nobody_here_made_play_as_the_core_and_export():
    """Quaternius' soldier (four meshes, x100) imported, extracted and bound at the defaults: its shoulders get
    directional volume keys (a limb's root), every key's driver is a simple expression equal to the core's weight, and
    with the upper arm raised and the elbow bent Blender's skin of every mesh equals the core's (rest + the keys at the
    core's weights, then the volume blend) to 1e-5 of the size; a glTF export carries the keys as morph targets with
    their weights animation, and the drivers are back afterwards."""
    import json
    path = runner.shared_file("characters/quaternius_woman_soldier/woman_soldier.glb")
    io, live, rig_io, vk, binding = (module(n) for n in ("blender_io", "live", "rig_io", "volume_keys", "binding"))
    bpy.ops.wm.read_homefile(use_empty=True)
    assert module("gltf_io").import_gltf(path) == {'FINISHED'}
    arm = max((o for o in bpy.context.scene.objects if o.type == 'ARMATURE' and io.character_meshes(o)[0]),
              key=lambda a: len(io.character_meshes(a)[0]))
    arm.animation_data_clear()
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    bpy.context.view_layer.objects.active = arm
    arm.select_set(True)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    meshes = io.character_meshes(arm)[0]
    assert len(meshes) == 4, [m.name for m in meshes]
    entries = {m.name: vk.stored(m) for m in meshes}
    directional = [e["name"] for es in entries.values() for e in es if any(e["swing"])]
    assert directional, entries
    native = []  # every key's driver valid and a simple expression (no Python)
    for m in meshes:
        if entries[m.name]:
            drivers = {fc.data_path: fc.driver for fc in m.data.shape_keys.animation_data.drivers}
            native += [(e["name"], drivers[f'key_blocks["{e["name"]}"].value']) for e in entries[m.name]]
    assert len(native) == sum(len(es) for es in entries.values()) > 0
    bad = [(name, d.expression) for name, d in native if not (d.is_valid and d.is_simple_expression)]
    assert not bad, bad
    frames = ((1, 0.0), (5, 70.0))
    # the upper arm swung toward the side of one of its directional keys (its tail leaning along (sx, 0, sz) in the
    # bone's rest frame: about Y x lean), the elbow bent, and a joint whose key's weight s (k1 + k2 s) turns negative
    # (its band gains volume at small bends before it collapses) bent to that weight's lowest
    upper = next(e for es in entries.values() for e in es if e["bone"] == "UpperArm.L" and any(e["swing"]))
    sx, sz = upper["swing"]

    def lowest(e):  # (the lowest weight over s in [0, 1], its s)
        k1, k2 = e["k1"], e["k2"]
        s = min(max(-k1 / (2.0 * k2), 0.0), 1.0) if k2 > 0.0 else 1.0
        return s * (k1 + k2 * s), s

    turning = sorted((lowest(e), e["bone"]) for es in entries.values() for e in es
                     if not any(e["swing"]) and e["bone"] not in ("UpperArm.L", "LowerArm.L"))
    assert turning and turning[0][0][0] < -0.05, turning  # a key whose weight turns negative (measured: the feet)
    (_, s_low), low_bone = turning[0]
    for bone, axis, factor in (("UpperArm.L", (sz, 0.0, -sx), 1.0), ("LowerArm.L", (1.0, 0.0, 0.0), 1.5),
                               (low_bone, (1.0, 0.0, 0.0), np.degrees(2.0 * np.arcsin(np.sqrt(s_low))) / 70.0)):
        pb = arm.pose.bones[bone]
        pb.rotation_mode = 'QUATERNION'
        for frame, degrees in frames:
            half = np.radians(degrees * factor) / 2
            pb.rotation_quaternion = (np.cos(half), *(np.sin(half) * np.asarray(axis)))
            pb.keyframe_insert("rotation_quaternion", frame=frame)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 5
    scene.frame_set(5)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, depsgraph)
    transforms = np.concatenate([pose @ np.linalg.inv(np.asarray(rig.character.bone_rest)),
                                 rig.rig.evaluate(pose)["joint_matrices"] @ np.linalg.inv(rig.rig.bind_matrices)])
    rests = {m.name: io.mesh_vertices(m.data) @ io.mesh_to_armature_matrix(m, arm)[:3, :3].T
             + io.mesh_to_armature_matrix(m, arm)[:3, 3] for m in meshes}
    every = np.concatenate(list(rests.values()))
    size = float(np.linalg.norm(every.max(axis=0) - every.min(axis=0)))
    errors, driver_errors, acting = [], [], {}
    for m in meshes:
        weights = vk.pose_weights(m, rig.character, pose)
        if weights:
            blocks = m.data.shape_keys.evaluated_get(depsgraph).key_blocks
            driver_errors.append(max(abs(blocks[n].value - w) for n, w in weights.items()))
            acting.update(weights)
        to_arm = io.mesh_to_armature_matrix(m, arm)
        joints, weights_ = rig_io.read_combined_weights(m, rig.bone_names + rig.joint_names)
        rest = rests[m.name] + vk.pose_offsets(m, arm, rig.character, pose)
        skinned = binding.skinner_for(m, arm, rig, rest, joints, weights_).deform(transforms)
        blender = io.evaluated_vertices(m) @ to_arm[:3, :3].T + to_arm[:3, 3]
        errors.append(float(np.abs(blender - skinned).max()) / size)
    moved = {n: w for n, w in acting.items() if abs(w) > 0.05}
    print(f"  soldier: {sum(len(e) for e in entries.values())} volume keys ({len(directional)} directional); acting "
          f"{sorted(moved)}; drivers vs core {max(driver_errors):.1e}; Blender vs core {max(errors):.2e} of the size")
    assert driver_errors and max(driver_errors) < 1e-6, driver_errors
    assert upper["name"] in moved, acting  # the shoulder's directional key acts on the swung arm
    assert min(acting.values()) < -0.05, acting  # Blender's shape key takes the negative weight (slider_min -1)
    assert max(errors) < TOLERANCE, errors
    # glTF export: the keys' values baked into the morph weights animation, the drivers written again afterwards
    gltf = os.path.join(TMP, "soldier.gltf")
    for o in bpy.context.view_layer.objects:
        o.select_set(o == arm or o in meshes)
    with module("correctives").weights_baked_for_export(bpy.context, meshes, arm):
        module("gltf_io").export_gltf(gltf, use_selection=True)
    with open(gltf) as f:
        doc = json.load(f)
    names = [n for mesh in doc["meshes"] for n in mesh.get("extras", {}).get("targetNames", [])]
    assert set(moved) <= set(names), (sorted(moved), names)
    assert any(c["target"]["path"] == "weights" for a in doc.get("animations", []) for c in a["channels"])
    # the negative weight is exported as it is (glTF allows it; Blender's own glTF importer clamps it to 0)
    low_name = next(e["name"] for es in entries.values() for e in es if e["bone"] == low_bone and not any(e["swing"]))
    exported = []
    for a in doc.get("animations", []):
        for c in a["channels"]:
            if c["target"]["path"] != "weights":
                continue
            targets = doc["meshes"][doc["nodes"][c["target"]["node"]]["mesh"]].get("extras", {}).get("targetNames", [])
            if low_name not in targets:
                continue
            accessor = doc["accessors"][a["samplers"][c["sampler"]]["output"]]
            view = doc["bufferViews"][accessor["bufferView"]]
            with open(os.path.join(TMP, doc["buffers"][view["buffer"]]["uri"]), "rb") as f:
                f.seek(view.get("byteOffset", 0) + accessor.get("byteOffset", 0))
                values = np.frombuffer(f.read(4 * accessor["count"]), dtype="<f4")
            exported.append(float(values.reshape(-1, len(targets))[:, targets.index(low_name)].min()))
    assert exported and min(exported) < -0.05, (low_name, exported)
    restored = 0
    for m in meshes:
        if entries[m.name]:
            paths = {fc.data_path for fc in m.data.shape_keys.animation_data.drivers}
            restored += sum(f'key_blocks["{e["name"]}"].value' in paths for e in entries[m.name])
    assert restored == sum(len(es) for es in entries.values()) > 0, restored


runner.run()
