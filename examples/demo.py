# SPDX-License-Identifier: GPL-3.0-or-later
"""Myoskin's main job: the default character in Blender, its muscles, and renders at rest and posed.

    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup --python-exit-code 1 \
        --addons myoskin --python examples/demo.py -- --output DIR

Writes to DIR:
    myoskin_demo.blend   the rig with its muscle joints bound (Extract + Bind through the add-on), the skin
                         (hybrid vertex groups + linear Armature modifier) and the muscles; frame 1 = rest,
                         frame 2 = elbow bent ~90 degrees; muscle joints baked to the Action
    muscles.json         the muscles extracted from the skin (format myoskin.muscles, version 1)
    truth.json           the generator's ground-truth muscles (centre lines and radii)
    render_rest.png      Cycles render, muscles (red) under a translucent skin, rest pose
    render_posed.png     the same with the elbow bent
"""
import argparse
import json
import os
import sys
import time

import bpy
import numpy as np


FRAME_REST, FRAME_POSED = 1, 2


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="demo.py", description="Myoskin demo (run inside Blender)")
    p.add_argument("--output", "-o", required=True, help="output folder (created if missing)")
    p.add_argument("--seed", type=int, default=1, help="synthetic arm seed")
    p.add_argument("--muscle-scale", type=float, default=1.0)
    p.add_argument("--elbow", type=float, default=90.0, help="elbow flexion in degrees for the posed frame")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--resolution", type=int, nargs=2, default=(480, 270), metavar=("X", "Y"))
    p.add_argument("--no-render", action="store_true", help="skip the PNG renders")
    return p.parse_args(argv)


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene_setup import (add_sun, addon_module, empty_scene, frame_camera, muscle_material,  # noqa: E402
                         render_still, require_addon, setup_render, use_skin_material)


def addon():
    """The add-on's modules, or a clear exit when Blender was started without it."""
    core_loader = require_addon("demo.py")
    blender_io, muscle_io, preferences, truth = (addon_module(n) for n in ("blender_io", "muscle_io",
                                                                          "preferences", "truth"))
    return blender_io, core_loader, preferences, truth, muscle_io


def log(message, start=[time.perf_counter()]):  # noqa: B006 (process start time)
    print(f"[demo {time.perf_counter() - start[0]:5.1f} s] {message}", flush=True)


def pose_elbow(arm_obj, degrees):
    """Flex the elbow: rotate the forearm about its local X (the bone's hinge axis in this rig),
    keyed at FRAME_POSED, with the rest pose keyed at FRAME_REST."""
    pb = arm_obj.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    pb.rotation_euler = (0.0, 0.0, 0.0)
    pb.keyframe_insert("rotation_euler", frame=FRAME_REST)
    pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)
    pb.keyframe_insert("rotation_euler", frame=FRAME_POSED)


def render(scene, frame, path):
    scene.frame_set(frame)
    render_still(scene, path)


def main():
    args = parse_args()
    blender_io, core_loader, preferences, truth_mod, muscle_io = addon()
    core = core_loader.core()
    out = os.path.abspath(args.output)
    os.makedirs(out, exist_ok=True)
    prefs = preferences.get_preferences()

    log("generating the default character (procedural muscular arm)")
    character, truth = core.make_synthetic_arm(seed=args.seed, muscle_scale=args.muscle_scale)
    log(f"{character!r}, {len(truth)} true muscles")

    empty_scene()
    scene = bpy.context.scene
    arm_obj, mesh_obj = blender_io.character_to_blender(character, "SyntheticArm")
    use_skin_material(mesh_obj)
    arm_obj.hide_render = True
    # The ground truth as tubes, kept in the .blend for comparison (hidden in the renders).
    tubes = blender_io.truth_to_curves(truth, armature_obj=arm_obj)
    for tube in tubes:
        tube.hide_render = True

    # The muscles extracted from the skin (Yang & Zhang's pipeline in the core), through the add-on's
    # operators as an artist would run them: Extract, then Bind (muscle joints + weights on the rig).
    for obj in bpy.context.selected_objects:
        obj.select_set(False)
    bpy.context.view_layer.objects.active = mesh_obj
    assert bpy.ops.myoskin.extract_muscles(spacing=prefs.section_spacing_radii,
                                           min_sections=prefs.min_sections) == {'FINISHED'}
    state = arm_obj.myoskin
    muscles = muscle_io.state_to_core(arm_obj)
    material = muscle_material()
    shapes = [item.surface for item in state.muscles]
    for shape in shapes:
        shape.data.materials.append(material)
    for item in state.muscles:
        for locator in (item.origin_locator, item.insertion_locator):
            locator.hide_render = True
    accuracy = core.measure_extraction(muscles, truth)
    log(f"extracted {len(muscles)} muscles: recall {accuracy['recall']:.2f}, precision "
        f"{accuracy['precision']:.2f} against the {len(truth)} true ones")
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    log(f"built {arm_obj.name} ({len(arm_obj.data.bones)} bones incl. muscle joints), {mesh_obj.name} "
        f"({len(mesh_obj.data.vertices)} vertices), {len(shapes)} muscle meshes, {len(tubes)} truth tubes")
    core.write_muscles(os.path.join(out, "muscles.json"), muscles)
    with open(os.path.join(out, "truth.json"), "w", encoding="utf-8") as f:
        json.dump(truth_mod.truth_to_json_dict(truth), f, indent=1)
    log(f"wrote muscles.json ({len(muscles)} muscles) and truth.json")

    pose_elbow(arm_obj, args.elbow)
    scene.frame_start, scene.frame_end = FRAME_REST, FRAME_POSED
    points = []
    for frame in (FRAME_REST, FRAME_POSED):
        scene.frame_set(frame)
        world = np.array(mesh_obj.matrix_world)
        points.append(blender_io.evaluated_vertices(mesh_obj) @ world[:3, :3].T + world[:3, 3])
    posed_err = np.abs(points[1] - points[0]).max()
    log(f"posed the elbow {args.elbow:.0f} degrees (skin moved up to {posed_err:.3f} m, muscles follow live)")
    assert bpy.ops.myoskin.bake_action(frame_start=FRAME_REST, frame_end=FRAME_POSED) == {'FINISHED'}
    log("baked the muscle joints to the Action (the .blend plays without the add-on)")

    setup_render(scene, args.samples, tuple(args.resolution))
    frame_camera(np.vstack(points), args.resolution)
    add_sun()
    scene.frame_set(FRAME_REST)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "myoskin_demo.blend"))
    log("saved myoskin_demo.blend")

    if not args.no_render:
        for frame, name in ((FRAME_REST, "render_rest.png"), (FRAME_POSED, "render_posed.png")):
            render(scene, frame, os.path.join(out, name))
            log(f"rendered {name}")
    log(f"done: outputs in {out}")


if __name__ == "__main__":
    main()
