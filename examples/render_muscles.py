# SPDX-License-Identifier: GPL-3.0-or-later
"""Extract the muscles of characters and render them (red) under a translucent skin, so a person can
judge the result (issue 3). Runs inside Blender, headless:

    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup --python-exit-code 1 \\
        --addons myoskin --python examples/render_muscles.py -- CHARACTER.glb [CHARACTER.glb ...] -o DIR

For each character writes to DIR: <name>.muscles.json, <name>_front.png and <name>_back.png (Cycles
CPU), and prints the muscle count per region. `./myoskin.sh render-muscles` runs it on both MakeHuman
characters of ../shared.
"""
import argparse
import collections
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene_setup import (add_sun, addon_module, empty_scene, frame_camera, muscle_material,  # noqa: E402
                         render_still, require_addon, setup_render, use_skin_material)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="render_muscles.py", description="Extract and render muscles (inside Blender)")
    p.add_argument("characters", nargs="+", help=".glb/.gltf files (or .obj with a .skeleton.json beside)")
    p.add_argument("--output", "-o", required=True, help="output folder (created if missing)")
    p.add_argument("--samples", type=int, default=24)
    p.add_argument("--resolution", type=int, nargs=2, default=(540, 720), metavar=("X", "Y"))
    return p.parse_args(argv)


def log(message, start=[time.perf_counter()]):  # noqa: B006 (process start time)
    print(f"[render_muscles {time.perf_counter() - start[0]:5.1f} s] {message}", flush=True)


def mesh_object(name, vertices, triangles, material, parent):
    """`material`: a material, or None for the translucent skin."""
    obj = bpy.data.objects.new(name, addon_module("blender_io")._new_mesh(name, vertices, triangles))
    if material is None:
        use_skin_material(obj)
    else:
        obj.data.materials.append(material)
    obj.parent = parent
    bpy.context.scene.collection.objects.link(obj)
    return obj


def render_character(core, path, out, args):
    character = core.load_character(path)
    muscles, report = core.extract_muscles(character)
    name = character.name or os.path.splitext(os.path.basename(path))[0]
    core.write_muscles(os.path.join(out, f"{name}.muscles.json"), muscles)
    regions = collections.Counter(m.region for m in muscles)
    log(f"{name}: {len(muscles)} muscles from {report['sections']} sections "
        f"({len(report['skipped'])} skipped) in {sum(report['timings'].values()):.2f} s")
    for region, count in sorted(regions.items()):
        log(f"    {region}: {count}")

    empty_scene()
    scene = bpy.context.scene
    root = bpy.data.objects.new(f"{name} (Y-up to Z-up)", None)
    scene.collection.objects.link(root)
    if path.lower().endswith((".glb", ".gltf")):  # glTF is Y-up, Blender Z-up
        root.rotation_euler = (np.pi / 2, 0.0, 0.0)
    mesh_object(f"{name}_skin", np.asarray(character.vertices), np.asarray(character.triangles),
                None, root)
    red = muscle_material()
    for m in muscles:
        mesh_object(m.name, np.asarray(m.surface_vertices), np.asarray(m.surface_triangles), red, root)
    bpy.context.view_layer.update()

    world = np.array(root.matrix_world)
    points = np.asarray(character.vertices) @ world[:3, :3].T + world[:3, 3]
    setup_render(scene, args.samples, tuple(args.resolution))
    add_sun()
    for view, direction in (("front", (0.0, -1.0, 0.08)), ("back", (0.0, 1.0, 0.08))):
        frame_camera(points, args.resolution, direction=direction, margin=1.05)
        render_still(scene, os.path.join(out, f"{name}_{view}.png"))
        log(f"rendered {name}_{view}.png")
    return len(muscles)


def main():
    args = parse_args()
    core = require_addon("render_muscles.py").core()
    out = os.path.abspath(args.output)
    os.makedirs(out, exist_ok=True)
    counts = {}
    for path in args.characters:
        if not os.path.isfile(path):
            sys.exit(f"render_muscles.py: {path} not found")
        counts[os.path.basename(path)] = render_character(core, path, out, args)
    for name, count in counts.items():
        log(f"{name}: {count} muscles")
    log(f"done: outputs in {out}")


if __name__ == "__main__":
    main()
