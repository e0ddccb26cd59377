# SPDX-License-Identifier: GPL-3.0-or-later
"""Run by tests/blender/test_undo.py inside a windowed Blender (under xvfb-run): Undo and Redo in the middle
of live update (a bound rig playing its animation, posed by hand between two undo steps), Undo of a Bake,
then an F12 render (Cycles, 16 x 16) while playback runs; writes what it saw as JSON to the path after "--"."""
import json
import sys

import bpy
import numpy as np

OUT = sys.argv[sys.argv.index("--") + 1]
seen = {}
reference = {}


def view3d():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D')
    region = next(r for r in area.regions if r.type == 'WINDOW')
    return bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen)


def skin_positions(name):
    obj = bpy.data.objects[name]
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    return co.reshape(-1, 3).astype(np.float64)


def error_of(arm_name):
    runtime = next(m for n, m in sys.modules.items() if n == "myoskin.runtime" or n.endswith(".myoskin.runtime"))
    return runtime.last_error(arm_name)


def finish(error=None):
    if error:
        seen["error"] = error
    with open(OUT, "w", encoding="utf-8") as f:
        json.dump(seen, f)
    bpy.ops.wm.quit_blender()


def setup():
    try:
        with view3d():
            for obj in list(bpy.data.objects):
                bpy.data.objects.remove(obj)
            bpy.ops.myoskin.add_synthetic_arm(seed=1)
            bpy.ops.myoskin.extract_muscles()
            bpy.ops.myoskin.bind()
        skin = bpy.context.view_layer.objects.active
        arm = skin.parent
        seen["names"] = [skin.name, arm.name]
        pb = arm.pose.bones["forearm"]
        pb.rotation_mode = 'XYZ'
        for frame, degrees in ((1, 0.0), (10, 100.0)):
            pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)
            pb.keyframe_insert("rotation_euler", frame=frame)
        scene = bpy.context.scene
        for frame in range(1, 5):  # playing
            scene.frame_set(frame)
        reference["frame4"] = skin_positions(skin.name)
        with view3d():
            bpy.ops.ed.undo_push(message="playing")
        pb.rotation_euler = (1.4, 0.2, 0.0)  # posed by hand in the middle of playback
        bpy.context.view_layer.update()
        reference["hand"] = skin_positions(skin.name)
        seen["hand_moved"] = float(np.abs(reference["hand"] - reference["frame4"]).max())
        with view3d():
            bpy.ops.ed.undo_push(message="posed by hand")
    except Exception as e:  # noqa: BLE001
        return finish(f"setup: {e}")
    bpy.app.timers.register(undo_redo, first_interval=0.3)


def undo_redo():
    try:
        skin_name, arm_name = seen["names"]
        with view3d():
            seen["undo"] = list(bpy.ops.ed.undo())
        scene = bpy.context.scene  # (undo replaced every datablock: look them up again)
        bpy.context.view_layer.update()
        seen["after_undo"] = float(np.abs(skin_positions(skin_name) - reference["frame4"]).max())
        for frame in (5, 6, 4):  # playback goes on after the undo
            scene.frame_set(frame)
        seen["after_undo_playing"] = float(np.abs(skin_positions(skin_name) - reference["frame4"]).max())
        with view3d():
            seen["redo"] = list(bpy.ops.ed.redo())
        bpy.context.view_layer.update()
        seen["after_redo"] = float(np.abs(skin_positions(skin_name) - reference["hand"]).max())
        seen["errors"] = error_of(arm_name)
        arm = bpy.data.objects[arm_name]
        bpy.context.view_layer.objects.active = arm
        with view3d():
            seen["bake"] = list(bpy.ops.myoskin.bake_action('EXEC_DEFAULT', True, frame_start=1, frame_end=5))
        seen["live_after_bake"] = bpy.data.objects[arm_name].myoskin.live
    except Exception as e:  # noqa: BLE001
        return finish(f"undo/redo: {e}")
    bpy.app.timers.register(undo_bake, first_interval=0.3)


def undo_bake():
    try:
        skin_name, arm_name = seen["names"]
        with view3d():
            seen["undo_bake"] = list(bpy.ops.ed.undo())
        arm = bpy.data.objects[arm_name]
        seen["live_after_undo_bake"] = arm.myoskin.live
        action = arm.animation_data.action if arm.animation_data else None
        seen["baked_curves_after_undo"] = sum(1 for fc in getattr(action, "fcurves", ()) if ".j" in fc.data_path) \
            if action is not None and hasattr(action, "fcurves") else -1
        scene = bpy.context.scene
        for frame in (2, 4):
            scene.frame_set(frame)
        seen["after_undo_bake_frame4"] = float(np.abs(skin_positions(skin_name) - reference["frame4"]).max())
        seen["errors"] += error_of(arm_name)
        # F12 while playback runs: start playing, render a frame from the next timer
        scene.render.engine = 'CYCLES'
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False
        scene.render.resolution_x = scene.render.resolution_y = 16
        scene.render.resolution_percentage = 100
        camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        scene.collection.objects.link(camera)
        camera.location, camera.rotation_euler = (0.0, -3.0, 0.3), (1.5708, 0.0, 0.0)
        scene.camera = camera
        scene.frame_start, scene.frame_end = 1, 10
        with view3d():
            seen["play"] = list(bpy.ops.screen.animation_play())
        seen["frames_seen"] = [scene.frame_current]
    except Exception as e:  # noqa: BLE001
        return finish(f"undo bake: {e}")
    bpy.app.timers.register(render_while_playing, first_interval=0.5)


def render_while_playing():
    try:
        skin_name, arm_name = seen["names"]
        scene = bpy.context.scene
        screen = bpy.context.window_manager.windows[0].screen
        seen["playing"] = bool(screen.is_animation_playing)
        seen["frames_seen"].append(scene.frame_current)
        with view3d():
            seen["render"] = list(bpy.ops.render.render(write_still=False))
        seen["frames_seen"].append(scene.frame_current)
        with view3d():
            bpy.ops.screen.animation_cancel(restore_frame=False)
        scene.frame_set(4)
        seen["after_render_frame4"] = float(np.abs(skin_positions(skin_name) - reference["frame4"]).max())
        seen["live_after_render"] = bpy.data.objects[arm_name].myoskin.live
        seen["errors"] += error_of(arm_name)
    except Exception as e:  # noqa: BLE001
        return finish(f"render while playing: {e}")
    finish()


bpy.app.timers.register(setup, first_interval=1.0)
