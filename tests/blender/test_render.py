# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: a Cycles render of a posed, bound frame shows exactly the viewport-evaluated deformation
(the live-update handlers run for the render's own depsgraph too; render.use_lock_interface is on).

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_render.py
"""
import os
import sys
import tempfile

import bpy
import numpy as np
from mathutils import Vector

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402

TMP = tempfile.mkdtemp(prefix="myoskin_test_render_")
SIZE = 96


def flat_material():
    mat = bpy.data.materials.new("flat")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    emit = nodes.new("ShaderNodeEmission")
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(emit.outputs[0], out.inputs[0])
    return mat


def setup(scene, center, view, up, scale):
    """Cycles, 1 sample, flat emission on black; an orthographic camera at `center` looking along `view`."""
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.world = bpy.data.worlds.new("black")
    scene.world.color = (0.0, 0.0, 0.0)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    cam.location = Vector(center) - 1.0 * Vector(view)
    cam.rotation_euler = Vector(view).to_track_quat('-Z', 'Y').to_euler()
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = scale
    cam.data.clip_end = 5.0
    scene.camera = cam


def render(scene, path, animation=False):
    scene.render.filepath = path
    if animation:
        scene.render.filepath = path.replace(".png", "_####.png")
        bpy.ops.render.render(animation=True)
        path = path.replace(".png", f"_{scene.frame_start:04d}.png")
    else:
        bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path)
    pixels = np.array(image.pixels[:]).reshape(SIZE, SIZE, 4)[:, :, 0]
    bpy.data.images.remove(image)
    return pixels


def evaluated_world(skin):
    io = sys.modules["myoskin.blender_io"]
    world = np.array(skin.matrix_world)
    return io.evaluated_vertices(skin) @ world[:3, :3].T + world[:3, 3]


def test_cycles_render_equals_viewport_deformation():
    """Render the belly of the muscle that shortens most; the picture equals a static mesh at the viewport's
    coordinates, and differs from one at the plain-skeleton (LBS) coordinates: the render has the muscles."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    plain = skin.copy()  # the same skin with the skeleton's weights only
    plain.data = skin.data.copy()
    scene.collection.objects.link(plain)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    assert scene.render.use_lock_interface
    arm.myoskin.collection.hide_render = True
    mat = flat_material()
    for obj in (skin, plain):
        obj.data.materials.clear()
        obj.data.materials.append(mat)
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in ((1, 0.0), (2, 120.0)):
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(2)
    bound_points, plain_points = evaluated_world(skin), evaluated_world(plain)
    # frame the belly of the muscle that shortens most, looking across the bone at its silhouette
    live = sys.modules["myoskin.live"]
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    result = rig.rig.evaluate(pose, with_surfaces=True)
    m = int(np.argmin(result["stretch"]))
    surface = np.asarray(result["surfaces"][m])
    center = surface.mean(axis=0)
    bone = arm.data.bones[rig.rig.muscles[m].origin_bone]
    axis = np.array(bone.tail_local) - np.array(bone.head_local)
    axis /= np.linalg.norm(axis)
    out = center - np.array(bone.head_local)
    out -= axis * np.dot(out, axis)
    view = np.cross(axis, out / np.linalg.norm(out))
    setup(scene, center, view, axis, 4.0 * float(np.ptp(surface, axis=0).max()) / 2)
    plain.hide_render = True
    # the bound skin, rendered as an animation frame (frame change handlers on the render's depsgraph)
    scene.frame_set(1)  # the viewport shows another frame than the one rendered
    scene.frame_start = scene.frame_end = 2
    rendered = render(scene, os.path.join(TMP, "bound.png"), animation=True)
    skin.hide_render = True
    triangles = sys.modules["myoskin.blender_io"].mesh_triangles(skin.data)
    reference_mesh = sys.modules["myoskin.blender_io"]._new_mesh("reference", bound_points, triangles)
    reference_mesh.materials.append(mat)
    reference = bpy.data.objects.new("reference", reference_mesh)
    scene.collection.objects.link(reference)
    scene.frame_set(2)
    expected = render(scene, os.path.join(TMP, "reference.png"))
    reference_mesh.vertices.foreach_set("co", plain_points.astype(np.float32).ravel())
    reference_mesh.update()
    lbs = render(scene, os.path.join(TMP, "lbs.png"))
    same = np.abs(rendered - expected).mean()
    different = np.abs(rendered - lbs).mean()
    print(f"  mean pixel difference over the belly: render vs viewport {same:.5f}, vs plain LBS {different:.5f} "
          f"(skin moved up to {np.abs(bound_points - plain_points).max() * 1000:.1f} mm)")
    assert 0.05 < rendered.mean() < 0.95, rendered.mean()  # the silhouette is in the picture
    assert different > 4.0 / (SIZE * SIZE) and same < 0.1 * different, (same, different)  # >= 4 pixels differ


runner.run()
