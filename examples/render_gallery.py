# SPDX-License-Identifier: GPL-3.0-or-later
"""The README's gallery: bent joints of a character under plain linear blend skinning (LBS), dual quaternions
(DQS, Blender's Preserve Volume) and Myoskin (the default Bind: its muscle joints with the Volume Blend and its
volume keys), side by side, and the extracted muscles under a translucent skin. Runs inside Blender, headless:

    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup --python-exit-code 1 \\
        --addons myoskin --python examples/render_gallery.py -- CHARACTER.glb -o DIR

Writes DIR/<joint>.jpg (elbow flexion, knee flexion, shoulder abduction; left to right LBS, DQS, Myoskin;
Workbench) and DIR/muscles.jpg (Cycles). The skins are the core's (Blender's Armature modifier equals them to
1e-5, tests/blender); the poses and measures are benchmarks/skin_quality.py's, so the pictures show the rows of
the README's table. `./myoskin.sh gallery` runs it on makehuman_muscular_male into docs/gallery.
"""
import argparse
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "benchmarks"))
import skin_quality  # noqa: E402
from scene_setup import (add_sun, addon_module, empty_scene, frame_camera, muscle_material,  # noqa: E402
                         render_still, require_addon, setup_render, use_skin_material)

VIEWS = {"elbow flexion": "elbow", "knee flexion": "knee", "shoulder abduction": "shoulder"}  # label -> file


def view_direction(character, bone, hinge, direction):
    """Camera direction (glTF frame: +Z front, +Y up, +X left) along the bend's axis, from the outer side, a
    little from the front: the joint's profile."""
    names = list(character.bone_names)
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    h = names.index(hinge)
    if direction == "outward":
        return np.array([0.0, 0.1, 1.0])
    axis = np.cross(tails[h] - heads[h], [0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)
    if axis[0] * heads[names.index(bone)][0] < 0:  # the limb's outer side
        axis = -axis
    return axis + np.array([0.0, 0.0, 0.25])


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_gallery.py", description="Render the README's gallery (inside Blender)")
    p.add_argument("character", help="a MakeHuman .glb (the joints are named as MakeHuman's rig)")
    p.add_argument("--output", "-o", required=True, help="output folder (created if missing)")
    p.add_argument("--resolution", type=int, nargs=2, default=(420, 420), metavar=("X", "Y"),
                   help="size of each panel")
    return p.parse_args(argv)


def log(message, start=[time.perf_counter()]):  # noqa: B006 (process start time)
    print(f"[render_gallery {time.perf_counter() - start[0]:5.1f} s] {message}", flush=True)


def mesh_object(name, vertices, triangles, parent, material=None):
    obj = bpy.data.objects.new(name, addon_module("blender_io")._new_mesh(name, vertices, triangles))
    if material == "skin":
        use_skin_material(obj)
    elif material is not None:
        obj.data.materials.append(material)
    obj.parent = parent
    bpy.context.scene.collection.objects.link(obj)
    return obj


def workbench(scene, resolution):
    scene.render.engine = 'BLENDER_WORKBENCH'
    scene.display.shading.light = 'STUDIO'
    scene.display.shading.color_type = 'SINGLE'
    scene.display.shading.single_color = (0.8, 0.6, 0.5)
    scene.display.shading.show_cavity = True
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.view_settings.view_transform = 'Standard'


def side_by_side(paths, out):
    """One JPEG of the panels left to right (Blender's image API: works headless in every version)."""
    images = [bpy.data.images.load(p) for p in paths]
    w, h = images[0].size
    pixels = np.concatenate([np.asarray(im.pixels[:], np.float32).reshape(h, w, 4) for im in images], axis=1)
    result = bpy.data.images.new("gallery", width=w * len(images), height=h, alpha=True)
    result.pixels.foreach_set(pixels.ravel())
    result.filepath_raw = out
    result.file_format = 'JPEG'
    result.save()
    for im in images + [result]:
        bpy.data.images.remove(im)
    for p in paths:
        os.remove(p)


def render_joints(core, character, muscles, out, args):
    """Per joint: the three skins as objects in turn, the same camera, then the panels joined."""
    rig, hj, hw, share, keys = skin_quality.bind_skin(core, character, muscles)
    rest = np.asarray(character.vertices)
    tris = np.asarray(character.triangles)
    sj, sw = np.asarray(character.weight_joints), np.asarray(character.weight_values)
    names, heads = list(character.bone_names), np.asarray(character.bone_heads)
    bone_rest, combined_rest = np.asarray(character.bone_rest), core.combined_rest_matrices(character, rig)
    limb_radius = core.extract_muscles(character, build_surfaces=False)[1]["limb_radius"]
    rows = {r["label"]: r for r in skin_quality.measure(core, character, muscles, skin_quality.MAKEHUMAN_JOINTS)}
    scene = bpy.context.scene
    for label, bone, hinge, _upper, direction, degrees in skin_quality.MAKEHUMAN_JOINTS:
        if label not in VIEWS or bone not in names:
            continue
        file_name, view = VIEWS[label], view_direction(character, bone, hinge, direction)
        pose = skin_quality.bent_pose(character, bone, hinge, direction, degrees)
        skel = core.skeleton_transforms(character, pose)
        full = core.skinning_transforms(character, pose, rig, rig.evaluate(pose)["joint_matrices"])
        skins = [
            ("LBS", core.skin(rest, sj, sw, skel)),
            ("DQS", core.skin(rest, sj, sw, skel, preserve_volume=True, rest_matrices=bone_rest)),
            ("Myoskin", core.skin(skin_quality.with_volume_keys(core, character, rest, keys, pose), hj, hw, full,
                                  dqs_share=share, rest_matrices=combined_rest)),
        ]
        joint = pose[names.index(bone)][:3, 3]
        empty_scene()
        root = bpy.data.objects.new("Y-up to Z-up", None)  # glTF is Y-up, Blender Z-up
        root.rotation_euler = (np.pi / 2, 0.0, 0.0)
        scene.collection.objects.link(root)
        objects = [mesh_object(f"{label} {kind}", np.asarray(v), tris, root) for kind, v in skins]
        bpy.context.view_layer.update()
        world = np.array(root.matrix_world)
        near = np.linalg.norm(np.asarray(skins[0][1]) - joint, axis=1) < 4.0 * limb_radius
        points = np.concatenate([np.asarray(v)[near] for _, v in skins]) @ world[:3, :3].T + world[:3, 3]
        workbench(scene, tuple(args.resolution))
        frame_camera(points, args.resolution, direction=tuple(world[:3, :3] @ np.asarray(view)), margin=1.05)
        panels = []
        for i, obj in enumerate(objects):
            for j, other in enumerate(objects):
                other.hide_render = i != j
            panels.append(os.path.join(out, f"{file_name}_{i}.png"))
            render_still(scene, panels[-1])
        side_by_side(panels, os.path.join(out, f"{file_name}.jpg"))
        r = rows.get(label)
        if r is not None:
            log(f"{file_name}.jpg: {label} {degrees:g} deg, band volume LBS {100 * r['lbs']:+.1f} %, DQS "
                f"{100 * r['dqs']:+.1f} %, Myoskin {100 * r['myoskin_vk']:+.1f} %")


def render_muscles(character, muscles, out):
    """The extracted muscles (red) under the translucent skin, from the front (Cycles)."""
    scene = bpy.context.scene
    empty_scene()
    root = bpy.data.objects.new("Y-up to Z-up", None)
    root.rotation_euler = (np.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(root)
    mesh_object("skin", np.asarray(character.vertices), np.asarray(character.triangles), root, "skin")
    red = muscle_material()
    for m in muscles:
        mesh_object(m.name, np.asarray(m.surface_vertices), np.asarray(m.surface_triangles), root, red)
    bpy.context.view_layer.update()
    world = np.array(root.matrix_world)
    points = np.asarray(character.vertices) @ world[:3, :3].T + world[:3, 3]
    setup_render(scene, 24, (540, 720))
    add_sun()
    frame_camera(points, (540, 720), direction=(0.0, -1.0, 0.08), margin=1.05)
    png = os.path.join(out, "muscles.png")
    render_still(scene, png)
    side_by_side([png], os.path.join(out, "muscles.jpg"))
    log(f"muscles.jpg: {len(muscles)} muscles")


def main():
    args = parse_args()
    core = require_addon("render_gallery.py").core()
    if not os.path.isfile(args.character):
        sys.exit(f"render_gallery.py: {args.character} not found")
    out = os.path.abspath(args.output)
    os.makedirs(out, exist_ok=True)
    character = core.load_character(args.character, require_weights=True)
    muscles, _ = core.extract_muscles(character)
    render_joints(core, character, muscles, out, args)
    render_muscles(character, muscles, out)
    log(f"done: {out}")


if __name__ == "__main__":
    main()
