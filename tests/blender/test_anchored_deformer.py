# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: Bind with the anchored deformer (issue 17 item 4): the core's AnchoredSkin drives the skin
through the Core Skin modifier.

Asserts: Bind adds the Core Skin modifier and switches the Armature modifier off; the rest pose is the mesh
to 1e-6 of its size; posed (by hand, by F-curves on frame change, after save and reload) Blender's skin
equals the core's AnchoredSkin to 1e-5 of the size; Bake PC2 writes the same frames; Unbind removes the
modifier and the offsets and gives the Armature modifier and the weights back exactly.
"""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, evaluated, size_of, weights_of  # noqa: E402

TMP = tempfile.mkdtemp(prefix="myoskin_test_anchored_")





def anchored_arm():
    """The synthetic arm, extracted and bound with the anchored deformer; (arm, skin, original weights)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert len(arm.myoskin.muscles) > 0
    original = weights_of(skin)
    arm.myoskin.deformer = 'ANCHORED'
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    return arm, skin, original


def flex(arm, degrees):
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)


def core_anchored(arm, skin):
    """The core's AnchoredSkin for the evaluated skeleton pose, built independently of the add-on's cache
    (from the mesh at rest and the bound muscles), in the mesh object's space."""
    blender_io, live = module("blender_io"), module("live")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    character = blender_io.character_from_blender(skin, arm)
    muscles = list(rig.rig.muscles)
    assert len(muscles) > 0
    stuffing = module("core_skin").stuffing_of(arm)
    posed = np.asarray(core().AnchoredSkin(character, muscles, stuffing=stuffing).evaluate(pose))
    to_mesh = np.linalg.inv(blender_io.mesh_to_armature_matrix(skin, arm))
    return posed @ to_mesh[:3, :3].T + to_mesh[:3, 3]


def test_bind_switches_the_skin_to_the_core():
    arm, skin, _ = anchored_arm()
    core_skin = module("core_skin")
    mod = core_skin.modifier(skin)
    assert mod is not None and mod.node_group is not None
    armature = module("binding").armature_modifier(skin, arm)
    assert armature is not None and not armature.show_viewport and not armature.show_render
    assert skin.modifiers[-1] == mod, "the Core Skin modifier must come last"
    rest = module("blender_io").mesh_vertices(skin.data)
    assert np.abs(evaluated(skin) - rest).max() <= 1e-6 * size_of(skin)


def test_posed_skin_equals_the_core():
    arm, skin, _ = anchored_arm()
    rest = module("blender_io").mesh_vertices(skin.data)
    for degrees in (45.0, 110.0):
        flex(arm, degrees)
        got = evaluated(skin)
        want = core_anchored(arm, skin)
        err = np.abs(got - want).max()
        moved = np.abs(got - rest).max()
        print(f"anchored, elbow {degrees:.0f} deg: Blender - core {err:.2e} (size {size_of(skin):.3f}), "
              f"skin moved up to {moved:.3f}")
        assert moved > 0.05 * size_of(skin), "the pose must move the skin"
        assert err <= 1e-5 * size_of(skin)


def test_frame_change_plays_the_core_skin_and_reload_keeps_it():
    arm, skin, _ = anchored_arm()
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in ((1, 0.0), (10, 100.0)):
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    scene = bpy.context.scene
    scene.frame_set(7)
    got = evaluated(skin)
    assert np.abs(got - core_anchored(arm, skin)).max() <= 1e-5 * size_of(skin)
    path = os.path.join(TMP, "anchored.blend")
    names = skin.name, arm.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    skin, arm = (bpy.data.objects[n] for n in names)
    bpy.context.scene.frame_set(4)
    got = evaluated(skin)
    assert np.abs(got - core_anchored(arm, skin)).max() <= 1e-5 * size_of(skin)
    assert np.abs(got - module("blender_io").mesh_vertices(skin.data)).max() > 1e-3 * size_of(skin)


def test_pc2_bake_equals_blender():
    arm, skin, _ = anchored_arm()
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in ((1, 0.0), (5, 90.0)):
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    path = os.path.join(TMP, "anchored.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=5) == {'FINISHED'}
    frames = core().read_pc2(path)["frames"]
    assert frames.shape == (5, len(skin.data.vertices), 3)
    bpy.context.scene.frame_set(4)
    assert np.abs(frames[3] - evaluated(skin)).max() <= 1e-5 * size_of(skin)


def test_stuffing_empty_is_anchored_to_and_blender_equals_the_core():
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert bpy.ops.myoskin.add_stuffing(bone="upper_arm") == {'FINISHED'}
    empty = bpy.data.objects["Stuffing.upper_arm"]
    bone = arm.data.bones["upper_arm"]
    head, tail = np.array(bone.head_local), np.array(bone.tail_local)
    rest = module("blender_io").mesh_vertices(skin.data)
    t = np.clip((rest - head) @ (tail - head) / np.dot(tail - head, tail - head), 0.0, 1.0)
    near = (t > 0.3) & (t < 0.7)
    radius = float(np.median(np.linalg.norm(rest[near] - (head + t[near, None] * (tail - head)), axis=1)))
    empty.scale = (0.9 * radius, 0.35 * bone.length, 0.9 * radius)  # reaches nearer the skin than the capsule
    bpy.context.view_layer.update()
    centre = module("core_skin").stuffing_of(arm)[0]["center"]
    placed = np.array(arm.matrix_world.inverted() @ empty.matrix_world.translation)
    assert np.abs(np.array(centre) - placed).max() <= 1e-6 * size_of(skin), "the rest place is where the Empty is"
    bpy.context.view_layer.objects.active = skin
    arm.myoskin.deformer = 'ANCHORED'
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    assert len(module("binding").read_bind_record(arm)["stuffing"]) == 1
    anchored = module("live").live_rig(arm).anchored[0][2]
    kinds = [c["kind"] for c in anchored.components]
    index = kinds.index("stuffing")
    anchored_to_it = int(np.sum(np.asarray(anchored.vertex_component) == index))
    print(f"stuffing on the upper arm: {anchored_to_it} of {len(rest)} skin vertices anchor to it")
    assert anchored_to_it > 100
    pb = arm.pose.bones["upper_arm"]
    pb.rotation_mode = 'XYZ'
    pb.rotation_euler = (0.0, 0.0, np.radians(40.0))
    flex(arm, 70.0)
    got = evaluated(skin)
    err = np.abs(got - core_anchored(arm, skin)).max()
    assert err <= 1e-5 * size_of(skin), (err, size_of(skin), dict(module("live").stats))
    empty.scale = (-1.0, 1.0, 1.0)
    msg = runner.operator_error(bpy.ops.myoskin.bind)
    assert "mirrored" in msg, msg
    assert arm.myoskin.bound, "a refused Bind keeps the current bind"


def test_pinned_group_keeps_vertices_out_of_the_relaxation():
    arm, skin, _ = anchored_arm()
    flex(arm, 110.0)
    free = evaluated(skin)
    anchored = module("live").live_rig(arm).anchored[0][2]
    assert anchored.report["seam_vertices"] > 0
    group = skin.vertex_groups.new(name=module("core_skin").PINNED_GROUP)
    group.add(list(range(len(skin.data.vertices))), 1.0, 'REPLACE')
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    flex(arm, 110.0)
    pinned = evaluated(skin)
    rig = module("live").live_rig(arm)
    pose = module("live").evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    character = module("blender_io").character_from_blender(skin, arm)
    unrelaxed = np.asarray(core().AnchoredSkin(character, list(rig.rig.muscles), relax_iterations=0).evaluate(pose))
    assert np.abs(pinned - unrelaxed).max() <= 1e-5 * size_of(skin), "every vertex pinned: no relaxation"
    assert np.abs(free - pinned).max() > 1e-5 * size_of(skin), "the relaxation moved some vertices before"


def test_unbind_gives_everything_back():
    arm, skin, original = anchored_arm()
    flex(arm, 80.0)
    evaluated(skin)
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    core_skin = module("core_skin")
    assert core_skin.modifier(skin) is None
    assert skin.data.attributes.get(core_skin.OFFSET_ATTRIBUTE) is None
    armature = module("binding").armature_modifier(skin, arm)
    assert armature is not None and armature.show_viewport and armature.show_render
    assert weights_of(skin) == original


if __name__ == "__main__":
    runner.run(globals())
