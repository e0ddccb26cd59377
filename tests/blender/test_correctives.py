# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier for pose-space correctives (issue 16): Add Corrective turns a sculpt at a pose (a sculpted copy of
the posed skin, or a shape key sculpted on it) into a shape key in rest space with native drivers, and Blender's
posed skin then reproduces the sculpt to 1e-6 of the character's size (plain skeleton weights, linear; a bound rig
with the muscle joints and Preserve Volume) and equals the core's skinner on the corrected mesh to 1e-5; at rest
and beyond the falloff the key is off and the skin is the rest skin; several poses of one bone are each
reproduced; the drivers are simple expressions that play in a Blender without the add-on and with Auto Run off;
the glTF export carries the morph target and its weights animation; bad input is an error report.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_correctives.py
"""
import json
import math
import os
import subprocess
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, evaluated, size_of  # noqa: E402

REPRODUCE = 1e-6  # the sculpt at its pose, relative to the character's bounding-box diagonal
CORE = 1e-5       # Blender (float32) against the core
TMP = tempfile.mkdtemp(prefix="myoskin_test_correctives_")




def new_arm(bound=False, volume_blend=False):
    """The synthetic arm (plain skeleton weights, linear) or bound with Preserve Volume (and the volume blend);
    (arm, skin)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    if bound:
        assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
        arm.myoskin.preserve_volume = True
        arm.myoskin.volume_blend = volume_blend
        assert bpy.ops.myoskin.bind() == {'FINISHED'}
    bpy.context.view_layer.objects.active = skin
    return arm, skin


def set_pose(arm, rotations):
    """rotations {bone: (degrees, axis)} as quaternions; every other bone at rest; the muscle joints follow."""
    for pb in arm.pose.bones:
        if pb.get("myoskin_joint") or pb.bone.get("myoskin_joint"):
            continue
        pb.rotation_mode = 'QUATERNION'
        degrees, axis = rotations.get(pb.name, (0.0, (1.0, 0.0, 0.0)))
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        half = math.radians(degrees) / 2
        pb.rotation_quaternion = (math.cos(half), *(math.sin(half) * axis))
    bpy.context.view_layer.update()
    if arm.myoskin.bound:
        module("live").update_armature(arm, force=True)
    bpy.context.view_layer.update()


def bone_head_in_mesh(arm, skin, bone):
    head = arm.matrix_world @ arm.pose.bones[bone].head
    return np.array(skin.matrix_world.inverted() @ head)


def sculpt_points(skin, arm, bone, amplitude=0.02, radius=0.15):
    """The posed skin with a smooth bulge round the bone's head (mesh space)."""
    posed = evaluated(skin)
    size = size_of(skin)
    d = np.linalg.norm(posed - bone_head_in_mesh(arm, skin, bone), axis=1) / (radius * size)
    f = np.where(d < 1.0, (1.0 - np.minimum(d, 1.0) ** 2) ** 3, 0.0)
    direction = np.array([0.0, 0.3, 1.0]) / np.linalg.norm([0.0, 0.3, 1.0])
    assert (f > 0).sum() > 10
    return posed + amplitude * size * f[:, None] * direction, posed


def sculpted_copy(skin, points, name="sculpt"):
    """A mesh object with the skin's faces at `points` (mesh space of the skin), placed as the skin."""
    faces = [list(p.vertices) for p in skin.data.polygons]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in points], [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.matrix_world = skin.matrix_world
    mesh.vertices.foreach_set("co", points.astype(np.float32).ravel())
    bpy.context.view_layer.objects.active = skin
    return obj


def core_posed(skin, arm):
    """The core's skinner on what Blender's Armature modifier receives (the shape keys applied), mesh space."""
    c = module("correctives")
    skinner, transforms, to_arm = c.deform_setup(skin, arm, bpy.context.evaluated_depsgraph_get())
    inputs = c.evaluated(skin, bpy.context)
    inputs = inputs @ to_arm[:3, :3].T + to_arm[:3, 3]
    core = runner.core()
    mode = skinner.preserve_volume
    names = [b.name for b in arm.data.bones if b.use_deform]
    joints, weights = module("rig_io").read_combined_weights(skin, names)
    binding = module("binding")
    if binding.volume_blend_modifier(skin, arm) is not None:  # the volume blend's shares as Blender mixes them
        rest = np.array([np.array(arm.data.bones[n].matrix_local) for n in names])
        again = core.Skinner(inputs, joints, weights, len(names), dqs_share=binding.read_share_group(skin),
                             rest_matrices=rest, dq_scale=binding.dq_scale())
    elif mode:
        rest = np.array([np.array(arm.data.bones[n].matrix_local) for n in names])
        again = core.Skinner(inputs, joints, weights, len(names), preserve_volume=True, rest_matrices=rest,
                             dq_scale=module("binding").dq_scale())
    else:
        again = core.Skinner(inputs, joints, weights, len(names))
    out = again.deform(transforms).astype(np.float64)
    to_mesh = np.linalg.inv(to_arm)
    return out @ to_mesh[:3, :3].T + to_mesh[:3, 3]


def key_value(skin, name):
    bpy.context.view_layer.update()
    return skin.data.shape_keys.key_blocks[name].value


def check_sculpt_reproduced(bound, volume_blend=False):
    arm, skin = new_arm(bound, volume_blend)
    size = size_of(skin)
    rest = module("blender_io").mesh_vertices(skin.data)
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0))})
    sculpt, posed = sculpt_points(skin, arm, "forearm")
    source = sculpted_copy(skin, sculpt)
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=source.name, name="elbow") == {'FINISHED'}
    blender = evaluated(skin)
    err = float(np.linalg.norm(blender - sculpt, axis=1).max()) / size
    core = float(np.linalg.norm(blender - core_posed(skin, arm), axis=1).max()) / size
    moved = float(np.linalg.norm(sculpt - posed, axis=1).max()) / size
    mode = ('bound, volume blend' if volume_blend else 'bound, preserve volume') if bound else 'skeleton weights, linear'
    print(f"  {mode}: sculpt (moves the skin "
          f"{moved:.3f} of the size) reproduced to {err:.2e}, Blender vs core {core:.2e} of the size; "
          f"key value {key_value(skin, 'elbow'):.7f}")
    assert moved > 0.015
    assert err < REPRODUCE, err
    assert core < CORE, core
    # at rest: the key is off and the skin is the rest skin
    set_pose(arm, {})
    assert key_value(skin, "elbow") == 0.0
    assert np.linalg.norm(evaluated(skin) - rest, axis=1).max() / size < REPRODUCE
    # beyond the falloff (bent the other way; sideways): off
    for pose in ({"forearm": (-100.0, (1.0, 0.0, 0.0))}, {"forearm": (90.0, (0.0, 0.0, 1.0))}):
        set_pose(arm, pose)
        assert key_value(skin, "elbow") == 0.0, pose
    # half way: partly on, between 0 and 1
    set_pose(arm, {"forearm": (70.0, (1.0, 0.0, 0.0))})
    assert 0.0 < key_value(skin, "elbow") < 1.0
    return arm, skin


def test_a_sculpted_copy_is_reproduced_at_its_pose_with_skeleton_weights():
    check_sculpt_reproduced(bound=False)


def test_a_sculpted_copy_is_reproduced_on_a_bound_rig_with_preserve_volume():
    arm, skin = check_sculpt_reproduced(bound=True)
    assert module("binding").armature_modifier(skin, arm).use_deform_preserve_volume
    assert any(b.get("myoskin_joint") for b in arm.data.bones)


def test_a_sculpted_copy_is_reproduced_on_a_rig_bound_with_the_volume_blend():
    """The default bind: the first Armature modifier over the linear group, the second one's dual quaternions."""
    arm, skin = check_sculpt_reproduced(bound=True, volume_blend=True)
    binding = module("binding")
    assert binding.volume_blend_modifier(skin, arm) is not None
    assert binding.armature_modifier(skin, arm).vertex_group == binding.LINEAR_GROUP


def test_object_transforms_of_the_skin_and_the_armature_are_taken_into_account():
    """The armature object moved, turned and scaled, the skin with a transform of its own under it."""
    arm, skin = new_arm()
    arm.location, arm.rotation_euler, arm.scale = (0.3, -0.2, 0.5), (0.2, 0.4, 1.1), (1.7, 1.7, 1.7)
    skin.location, skin.rotation_euler, skin.scale = (0.05, 0.0, -0.02), (0.0, 0.0, 0.3), (1.2, 1.2, 1.2)
    bpy.context.view_layer.update()
    size = size_of(skin)
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0)), "upper_arm": (30.0, (0.0, 0.0, 1.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    source = sculpted_copy(skin, sculpt)
    source.matrix_world = arm.matrix_world  # the copy placed elsewhere: its world positions are the sculpt
    m = np.linalg.inv(np.array(source.matrix_world)) @ np.array(skin.matrix_world)
    source.data.vertices.foreach_set("co", (sculpt @ m[:3, :3].T + m[:3, 3]).astype(np.float32).ravel())
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=source.name) == {'FINISHED'}
    err = float(np.linalg.norm(evaluated(skin) - sculpt, axis=1).max()) / size
    core = float(np.linalg.norm(evaluated(skin) - core_posed(skin, arm), axis=1).max()) / size
    print(f"  moved, turned and scaled objects: sculpt reproduced to {err:.2e}, Blender vs core {core:.2e} of the size")
    assert err < REPRODUCE, err
    assert core < CORE, core


def test_a_sculpted_shape_key_becomes_the_corrective():
    """The artist's shape key sculpted on the posed skin (its offsets in rest space, as Sculpt Mode stores
    them): the corrective gives the same posed skin, and the sculpt key is set to 0."""
    arm, skin = new_arm()
    size = size_of(skin)
    set_pose(arm, {"forearm": (95.0, (1.0, 0.0, 0.0))})
    skin.shape_key_add(name="Basis", from_mix=False)
    fix = skin.shape_key_add(name="fix", from_mix=False)
    basis = module("blender_io").mesh_vertices(skin.data)
    elbow = np.array(arm.data.bones["forearm"].head_local)  # armature and mesh spaces agree on the arm
    d = np.linalg.norm(basis - elbow, axis=1) / (0.15 * size)
    bump = np.where(d < 1.0, (1.0 - np.minimum(d, 1.0) ** 2) ** 3, 0.0)[:, None] * np.array([0.0, 0.0, 0.02 * size])
    fix.data.foreach_set("co", (basis + bump).astype(np.float32).ravel())
    fix.value = 1.0
    target = evaluated(skin)
    fix.value = 0.0
    assert np.linalg.norm(evaluated(skin) - target, axis=1).max() > 0.01 * size
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_key="fix") == {'FINISHED'}
    keys = skin.data.shape_keys.key_blocks
    assert "fix" in keys and "fix.sculpt" in keys and keys["fix.sculpt"].value == 0.0
    err = float(np.linalg.norm(evaluated(skin) - target, axis=1).max()) / size
    print(f"  shape key sculpt reproduced to {err:.2e} of the size")
    assert err < REPRODUCE, err


def test_several_poses_of_one_bone_are_each_reproduced_and_rest_stays_rest():
    arm, skin = new_arm()
    size = size_of(skin)
    rest = module("blender_io").mesh_vertices(skin.data)
    sculpts = {}
    for name, degrees in (("elbow_60", 60.0), ("elbow_110", 110.0)):
        set_pose(arm, {"forearm": (degrees, (1.0, 0.0, 0.0))})
        sculpt, _posed = sculpt_points(skin, arm, "forearm", amplitude=0.015)
        source = sculpted_copy(skin, sculpt, name + "_sculpt")
        assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=source.name, name=name,
                                              falloff=math.radians(80.0)) == {'FINISHED'}
        sculpts[name] = (degrees, sculpt)
    stored = json.loads(skin["myoskin_correctives"])["correctives"]
    assert [e["name"] for e in stored] == ["elbow_60", "elbow_110"]
    assert len(sculpts) == 2
    for name, (degrees, sculpt) in sculpts.items():
        set_pose(arm, {"forearm": (degrees, (1.0, 0.0, 0.0))})
        err = float(np.linalg.norm(evaluated(skin) - sculpt, axis=1).max()) / size
        values = [round(key_value(skin, n), 6) for n in sculpts]
        print(f"  {name}: reproduced to {err:.2e} of the size, key values {values}")
        assert err < REPRODUCE, (name, err)
    set_pose(arm, {"forearm": (85.0, (1.0, 0.0, 0.0))})
    assert key_value(skin, "elbow_60") > 0.05 and key_value(skin, "elbow_110") > 0.05  # blended in between
    set_pose(arm, {})
    assert np.linalg.norm(evaluated(skin) - rest, axis=1).max() / size < REPRODUCE
    # removing one rebuilds the other's drivers: it is still reproduced at its pose
    assert bpy.ops.myoskin.remove_corrective(name="elbow_60") == {'FINISHED'}
    assert "elbow_60" not in skin.data.shape_keys.key_blocks
    set_pose(arm, {"forearm": (110.0, (1.0, 0.0, 0.0))})
    err = float(np.linalg.norm(evaluated(skin) - sculpts["elbow_110"][1], axis=1).max()) / size
    assert err < REPRODUCE, err
    set_pose(arm, {"forearm": (60.0, (1.0, 0.0, 0.0))})
    assert 0.0 <= key_value(skin, "elbow_110") < 1.0


PLAYBACK = """
import sys, bpy, numpy as np
bpy.context.preferences.filepaths.use_scripts_auto_execute = False
path, skin_name, out = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.open_mainfile(filepath=path)
bpy.context.view_layer.update()
skin = bpy.data.objects[skin_name]
ev = skin.evaluated_get(bpy.context.evaluated_depsgraph_get())
mesh = ev.to_mesh()
co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
mesh.vertices.foreach_get("co", co)
np.save(out, co.reshape(-1, 3))
print("ADDONS", sorted(a.module for a in bpy.context.preferences.addons))
print("AUTOEXEC_FAIL", bpy.app.autoexec_fail)
"""


def test_drivers_are_simple_expressions_and_play_without_the_addon_and_auto_run_off():
    arm, skin = new_arm()
    size = size_of(skin)
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    source = sculpted_copy(skin, sculpt)
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=source.name) == {'FINISHED'}
    drivers = list(skin.data.shape_keys.animation_data.drivers)
    assert len(drivers) == 3  # the rest kernel, the pose kernel, the key's value
    for fc in drivers:
        assert fc.driver.is_simple_expression, fc.driver.expression
        assert fc.driver.is_valid
    path = os.path.join(TMP, "corrective.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    script = os.path.join(TMP, "playback.py")
    with open(script, "w") as f:
        f.write(PLAYBACK)
    out = os.path.join(TMP, "played.npy")
    env = {k: v for k, v in os.environ.items() if k != "BLENDER_USER_SCRIPTS"}  # the add-on is not found
    result = subprocess.run(runner.blender_command("--python-exit-code", "1", "-P", script, "--", path, skin.name, out),
                            capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "myoskin" not in result.stdout.split("ADDONS", 1)[1].splitlines()[0], result.stdout
    assert "AUTOEXEC_FAIL False" in result.stdout, result.stdout
    err = float(np.linalg.norm(np.load(out) - sculpt, axis=1).max()) / size
    print(f"  played in a Blender without the add-on, Auto Run off: sculpt to {err:.2e} of the size")
    assert err < REPRODUCE, err


def test_gltf_export_carries_the_morph_target_and_its_weights_animation():
    arm, skin = new_arm()
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    source = sculpted_copy(skin, sculpt)
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=source.name, name="elbow") == {'FINISHED'}
    bpy.data.objects.remove(source)
    pb = arm.pose.bones["forearm"]
    for frame, degrees in ((1, 0.0), (10, 100.0), (20, 0.0)):
        half = math.radians(degrees) / 2
        pb.rotation_quaternion = (math.cos(half), math.sin(half), 0.0, 0.0)
        pb.keyframe_insert("rotation_quaternion", frame=frame)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 20
    scene.frame_set(1)
    for o in bpy.context.view_layer.objects:
        o.select_set(o in (arm, skin))
    path = os.path.join(TMP, "corrective.gltf")
    with module("correctives").weights_baked_for_export(bpy.context, [skin], arm):
        module("gltf_io").export_gltf(path, use_selection=True)
    assert skin.data.shape_keys.animation_data.drivers, "the drivers are back after the export"
    with open(path) as f:
        doc = json.load(f)
    meshes = [m for m in doc["meshes"] if any(p.get("targets") for p in m["primitives"])]
    assert len(meshes) == 1, [m.get("name") for m in doc["meshes"]]
    assert "elbow" in meshes[0].get("extras", {}).get("targetNames", []), meshes[0].get("extras")
    channels = [(a, c) for a in doc.get("animations", []) for c in a["channels"] if c["target"]["path"] == "weights"]
    assert channels, [c["target"] for a in doc.get("animations", []) for c in a["channels"]]
    anim, channel = channels[0]
    accessor = doc["accessors"][anim["samplers"][channel["sampler"]]["output"]]
    view = doc["bufferViews"][accessor["bufferView"]]
    with open(os.path.join(TMP, doc["buffers"][view["buffer"]]["uri"]), "rb") as f:
        f.seek(view.get("byteOffset", 0) + accessor.get("byteOffset", 0))
        weights = np.frombuffer(f.read(4 * accessor["count"]), dtype=np.float32)
    targets = len(meshes[0]["primitives"][0]["targets"])
    elbow = weights.reshape(-1, targets)[:, meshes[0]["extras"]["targetNames"].index("elbow")]
    print(f"  glTF: {targets} morph target(s), weights animation of {len(elbow)} keys, from {elbow.min():.3f} to "
          f"{elbow.max():.3f}")
    assert elbow.min() == 0.0 and abs(elbow.max() - 1.0) < 1e-5


def test_bake_pc2_includes_the_correctives_and_shape_keys():
    """Bake PC2 skins the shape key mix Blender evaluates on each frame (the corrective driven on at the pose, an
    animated artist's key): the cache equals Blender's posed skin to 1e-5 of the size."""
    arm, skin = new_arm(bound=True)
    size = size_of(skin)
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=sculpted_copy(skin, sculpt).name,
                                          name="elbow") == {'FINISHED'}
    # an artist's key animated 0 -> 0.7 over the same frames (a bump on the upper arm)
    extra = skin.shape_key_add(name="artist", from_mix=False)
    basis = module("blender_io").mesh_vertices(skin.data)
    shoulder = np.array(arm.data.bones["forearm"].head_local) * 0.5
    d = np.linalg.norm(basis - shoulder, axis=1) / (0.2 * size)
    bump = np.where(d < 1.0, (1.0 - np.minimum(d, 1.0) ** 2) ** 3, 0.0)[:, None] * np.array([0.03 * size, 0.0, 0.0])
    extra.data.foreach_set("co", (basis + bump).astype(np.float32).ravel())
    pb = arm.pose.bones["forearm"]
    for frame, degrees, value in ((1, 0.0, 0.0), (5, 100.0, 0.7)):
        set_pose(arm, {"forearm": (degrees, (1.0, 0.0, 0.0))})
        pb.keyframe_insert("rotation_quaternion", frame=frame)
        extra.value = value
        extra.keyframe_insert("value", frame=frame)
    path = os.path.join(TMP, "keys.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=5) == {'FINISHED'}
    frames = runner.core().read_pc2(path)["frames"]
    bpy.context.scene.frame_set(5)
    module("live").update_armature(arm, force=True)
    assert key_value(skin, "elbow") > 0.99 and abs(key_value(skin, "artist") - 0.7) < 1e-6
    blender = evaluated(skin)
    err = float(np.linalg.norm(frames[4] - blender, axis=1).max()) / size
    keys = module("dynamics").ShapeKeyMix(skin)
    without = skin.data.shape_keys.key_blocks
    for kb in without:
        kb.mute = kb.name in ("elbow", "artist")
    plain = evaluated(skin)
    for kb in without:
        kb.mute = False
    moved = float(np.linalg.norm(blender - plain, axis=1).max()) / size
    print(f"  Bake PC2 with the corrective on and an animated key at 0.7: {err:.1e} of the size off Blender's skin "
          f"(the keys move it {moved:.3f} of the size; {len(keys.names)} keys mixed)")
    assert moved > 0.01
    assert err < CORE, err
    assert float(np.linalg.norm(frames[0] - module("blender_io").mesh_vertices(skin.data), axis=1).max()) / size \
        < REPRODUCE, "at rest the correctives and the animated key are off"


def test_the_panel_lists_the_correctives_and_offers_add_from_the_active_shape_key():
    from fake_layout import draw_panel
    arm, skin = new_arm()
    log = draw_panel(bpy.types.MYOSKIN_PT_correctives).log
    assert ("label", "No correctives") in log and ("operator", "myoskin.add_corrective") in log
    set_pose(arm, {"forearm": (100.0, (1.0, 0.0, 0.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    assert bpy.ops.myoskin.add_corrective(bone="forearm", source_object=sculpted_copy(skin, sculpt).name,
                                          name="elbow") == {'FINISHED'}
    skin.shape_key_add(name="next_fix", from_mix=False)
    skin.active_shape_key_index = len(skin.data.shape_keys.key_blocks) - 1
    text = " ".join(t for kind, t in draw_panel(bpy.types.MYOSKIN_PT_correctives).log if kind == "label")
    assert "elbow  (forearm, 60 deg)" in text and "Sculpt: next_fix" in text, text
    assert ("operator", "myoskin.remove_corrective") in draw_panel(bpy.types.MYOSKIN_PT_correctives).log
    bpy.context.view_layer.objects.active = arm  # the armature active: its one skin
    assert "elbow  (forearm, 60 deg)" in draw_panel(bpy.types.MYOSKIN_PT_correctives).text()


def test_bad_input_is_reported_not_raised():
    arm, skin = new_arm()
    set_pose(arm, {"forearm": (90.0, (1.0, 0.0, 0.0))})
    sculpt, _posed = sculpt_points(skin, arm, "forearm")
    good = sculpted_copy(skin, sculpt, "good")
    err = runner.operator_error
    add = bpy.ops.myoskin.add_corrective
    # a different vertex count
    short = bpy.data.meshes.new("short")
    short.from_pydata([tuple(p) for p in sculpt[:-3]], [], [])
    short_obj = bpy.data.objects.new("short", short)
    bpy.context.scene.collection.objects.link(short_obj)
    assert "vertices" in err(add, bone="forearm", source_object="short")
    # NaN in the sculpt
    nan = sculpt.copy()
    nan[5, 1] = np.nan
    sculpted_copy(skin, nan, "nan")
    assert "NaN" in err(add, bone="forearm", source_object="nan")
    # a bone that does not exist; no sculpt given; a missing shape key
    assert "no bone 'nope'" in err(add, bone="nope", source_object="good")
    assert "one of them" in err(add, bone="forearm")
    assert "no shape key" in err(add, bone="forearm", source_key="missing")
    # the bone at rest
    set_pose(arm, {})
    assert "rest direction" in err(add, bone="forearm", source_object="good")
    # two identical driving poses
    set_pose(arm, {"forearm": (90.0, (1.0, 0.0, 0.0))})
    assert add(bone="forearm", source_object="good", name="first") == {'FINISHED'}
    keys_before = len(skin.data.shape_keys.key_blocks)
    text = err(add, bone="forearm", source_object="good", name="second")
    assert "same pose" in text, text
    assert len(skin.data.shape_keys.key_blocks) == keys_before  # nothing changed
    assert "no corrective 'other'" in err(bpy.ops.myoskin.remove_corrective, name="other")
    # a deforming modifier before the Armature modifier
    smooth = skin.modifiers.new("Smooth", 'SMOOTH')
    if hasattr(skin.modifiers, "move"):  # Blender 4.x, 5.x
        skin.modifiers.move(len(skin.modifiers) - 1, 0)
    else:
        bpy.ops.object.modifier_move_to_index(modifier=smooth.name, index=0)
    assert skin.modifiers[0] == smooth
    set_pose(arm, {"forearm": (60.0, (1.0, 0.0, 0.0))})
    assert "comes before its Armature modifier" in err(add, bone="forearm", source_object="good", name="third")
    skin.modifiers.remove(smooth)
    # a skin the core moves (the Anchored Skin deformer's Geometry Nodes modifier)
    skin.modifiers.new(module("core_skin").MODIFIER, 'NODES')
    assert "Anchored Skin" in err(add, bone="forearm", source_object="good", name="third")
    assert good.name in bpy.data.objects


runner.run()
