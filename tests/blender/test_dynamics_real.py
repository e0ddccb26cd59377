# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: Bake PC2 with secondary motion on a real character (makehuman_muscular_male, 13,380 vertices,
extracted and bound here; skipped without ../shared). The left elbow bends 0 -> 90 degrees over frames 1-8 and
holds to frame 16.

Asserts: two chunks (1-8, 9-16) stitched by a state file give the PC2 bytes of one bake with jiggle + skin solve +
temporal filter; a jiggle map painted 0 / 1 on alternate vertices gives exactly the plain / the full jiggle skin
(1e-6 of the size); sculpt deltas captured from a shape key at frame 1 add the detail Blender shows there (1e-6 of the
size; the PC2 is within 1e-5 of Blender's sculpted skin) and carry it whole on the bent frame.
"""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, evaluated, size_of  # noqa: E402

MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TMP = tempfile.mkdtemp(prefix="myoskin_test_dynamics_real_")
END = 16
_scene = {}


def character():
    """(armature, skin, the animated elbow's pose bone): imported, extracted, bound and animated once."""
    if _scene:
        return _scene["arm"], _scene["skin"], _scene["bone"]
    path = runner.shared_file(MUSCULAR)
    bpy.ops.wm.read_homefile(use_empty=True)
    module("gltf_io").import_gltf(path)
    arm = next(o for o in bpy.context.scene.objects if o.type == 'ARMATURE')
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert len(arm.myoskin.muscles) > 0
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    skin = module("binding").bound_skins(arm)[0]
    bone = arm.pose.bones["lowerarm01.L"]
    bone.rotation_mode = 'XYZ'
    for frame, degrees in ((1, 0.0), (8, 90.0), (END, 90.0)):
        bone.rotation_euler = (np.radians(degrees), 0.0, 0.0)
        bone.keyframe_insert("rotation_euler", frame=frame)
    bpy.context.scene.render.fps = 24
    _scene.update(arm=arm, skin=skin, bone=bone)
    return arm, skin, bone


def bake(name, start, end, **options):
    path = os.path.join(TMP, f"{name}.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=start, frame_end=end, **options) == {'FINISHED'}
    return np.asarray(runner.core().read_pc2(path)["frames"])


def test_chunks_stitch_with_jiggle_skin_solve_and_filter():
    _arm, skin, _bone = character()
    options = dict(jiggle=True, skin_solve=True, temporal_filter=True)
    one = bake("one", 1, END, **options)
    state = os.path.join(TMP, "state.json")
    first = bake("first", 1, 8, state_out=state, **options)
    second = bake("second", 9, END, state_in=state, **options)
    assert one.shape == (END, len(skin.data.vertices), 3)
    assert np.concatenate([first, second]).tobytes() == one.tobytes()
    moved = float(np.linalg.norm(one[-1] - one[0], axis=1).max()) / size_of(skin)
    print(f"makehuman: chunks 1-8 + 9-{END} (state of frame 7) = one bake bit for bit; the elbow moves the skin "
          f"{moved:.3f} of the size")
    assert moved > 0.01


def test_painted_jiggle_map_per_vertex():
    _arm, skin, _bone = character()
    size = size_of(skin)
    plain, full = bake("plain", 1, END), bake("full", 1, END, jiggle=True)
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.add_jiggle_map() == {'FINISHED'}
    group = skin.vertex_groups[module("dynamics").JIGGLE_GROUP]
    zero = np.arange(len(skin.data.vertices)) % 2 == 0
    group.add([int(v) for v in np.flatnonzero(zero)], 0.0, 'REPLACE')
    try:
        painted = bake("painted", 1, END, jiggle=True)
    finally:
        skin.vertex_groups.remove(group)
    jiggle = float(np.linalg.norm(full - plain, axis=2)[:, ~zero].max()) / size
    print(f"makehuman: the jiggle moves the skin up to {jiggle:.1e} of the size; painted 0 / 1 vertices off the "
          f"plain / full skin by {np.abs(painted[:, zero] - plain[:, zero]).max() / size:.1e} / "
          f"{np.abs(painted[:, ~zero] - full[:, ~zero]).max() / size:.1e}")
    assert jiggle > 1e-4
    assert np.abs(painted[:, zero] - plain[:, zero]).max() <= 1e-6 * size
    assert np.abs(painted[:, ~zero] - full[:, ~zero]).max() <= 1e-6 * size


def test_sculpt_deltas_from_a_shape_key():
    arm, skin, bone = character()
    size = size_of(skin)
    rest = module("blender_io").mesh_vertices(skin.data)
    to_arm = module("blender_io").mesh_to_armature_matrix(skin, arm)
    wrist = np.linalg.inv(to_arm) @ np.append(np.array(bone.bone.tail_local), 1.0)
    d = np.linalg.norm(rest - wrist[:3], axis=1) / (0.06 * size)
    bump = np.where(d < 1.0, (1.0 - np.minimum(d, 1.0) ** 2) ** 3, 0.0)[:, None] * (0.005 * size) * np.array([0, 0, 1])
    assert (d < 1.0).sum() > 20
    if skin.data.shape_keys is None:
        skin.shape_key_add(name="Basis")
    key = skin.shape_key_add(name="detail")
    key.data.foreach_set("co", (rest + bump).astype(np.float32).ravel())
    bpy.context.scene.frame_set(1)
    key.value = 1.0
    sculpted = evaluated(skin)  # what the artist sees at frame 1
    key.value = 0.0
    detail = sculpted - evaluated(skin)  # the detail as the Armature modifier shows it
    key.value = 1.0
    bpy.context.view_layer.objects.active = skin
    ui = bpy.context.scene.myoskin_ui
    ui.frame_start, ui.frame_end = 1, END
    assert bpy.ops.myoskin.capture_sculpt(source_key="detail") == {'FINISHED'}
    try:
        frames = bake("sculpt", 1, END)
    finally:
        module("dynamics").remove_sculpt(skin)
    plain = bake("unsculpted", 1, END)
    err = float(np.linalg.norm((frames[0] - plain[0]) - detail, axis=1).max()) / size
    seen = float(np.linalg.norm(frames[0] - sculpted, axis=1).max()) / size
    carried = float(np.linalg.norm(frames[-1] - plain[-1], axis=1).max()) / float(np.linalg.norm(bump, axis=1).max())
    print(f"makehuman: sculpt deltas at frame 1 add the sculpted detail to {err:.1e} of the size (the PC2 is "
          f"{seen:.1e} of the size off Blender's sculpted skin); on the bent frame {carried:.3f} of the detail carried")
    assert err <= 1e-6
    assert seen <= 1e-5  # Blender (float32) against the core
    assert 0.9 < carried < 1.1


if __name__ == "__main__":
    runner.run(globals())
