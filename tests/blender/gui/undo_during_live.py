# SPDX-License-Identifier: GPL-3.0-or-later
"""Run by tests/blender/test_undo.py inside a windowed Blender (under xvfb-run): Undo and Redo in the middle
of live update (a bound rig playing its animation, posed by hand between two undo steps), and Undo of a
Bake; writes what it saw as JSON to the path after "--"."""
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
    except Exception as e:  # noqa: BLE001
        return finish(f"undo bake: {e}")
    finish()


bpy.app.timers.register(setup, first_interval=1.0)
