# SPDX-License-Identifier: GPL-3.0-or-later
"""Run by tests/blender/test_undo.py inside a windowed Blender (under xvfb-run): Bind as a user does (an
undo step), then Edit > Undo and Redo; writes what it saw as JSON to the path after "--"."""
import json
import sys

import bpy

OUT = sys.argv[sys.argv.index("--") + 1]
seen = {}


def weights(skin):
    names = {g.index: g.name for g in skin.vertex_groups}
    return sorted((names[g.group], v.index, g.weight) for v in skin.data.vertices for g in v.groups)


def view3d():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D')
    region = next(r for r in area.regions if r.type == 'WINDOW')
    return bpy.context.temp_override(window=win, area=area, region=region, screen=win.screen)


def finish(error=None):
    if error:
        seen["error"] = error
    with open(OUT, "w", encoding="utf-8") as f:
        json.dump(seen, f)
    bpy.ops.wm.quit_blender()


def bind_step():
    try:
        with view3d():
            for obj in list(bpy.data.objects):
                bpy.data.objects.remove(obj)
            bpy.ops.myoskin.add_synthetic_arm(seed=1)
            bpy.ops.myoskin.extract_muscles()
            skin = bpy.context.view_layer.objects.active
            seen["names"] = [skin.name, skin.parent.name]
            seen["before"] = weights(skin)
            seen["bones_before"] = len(skin.parent.data.bones)
            bpy.ops.ed.undo_push(message="before bind")
            bpy.ops.myoskin.bind('EXEC_DEFAULT', True)  # True: push an undo step, as the UI does
            seen["bound"] = skin.parent.myoskin.bound
            seen["bones_bound"] = len(skin.parent.data.bones)
    except Exception as e:  # noqa: BLE001
        return finish(f"bind: {e}")
    bpy.app.timers.register(undo_step, first_interval=0.3)


def undo_step():
    try:
        with view3d():
            seen["undo"] = list(bpy.ops.ed.undo())
        skin, arm = (bpy.data.objects[n] for n in seen["names"])
        seen["after_undo"] = weights(skin) == seen["before"]
        seen["bound_after_undo"] = arm.myoskin.bound
        seen["bones_after_undo"] = len(arm.data.bones)
        pb = arm.pose.bones["forearm"]
        pb.rotation_mode = 'XYZ'
        pb.rotation_euler = (1.0, 0.0, 0.0)
        bpy.context.view_layer.update()  # the live handlers must not touch the un-bound rig
        with view3d():
            seen["redo"] = list(bpy.ops.ed.redo())
        arm = bpy.data.objects[seen["names"][1]]
        seen["bound_after_redo"] = arm.myoskin.bound
        seen["bones_after_redo"] = len(arm.data.bones)
        del seen["before"]
    except Exception as e:  # noqa: BLE001
        return finish(f"undo: {e}")
    finish()


bpy.app.timers.register(bind_step, first_interval=1.0)
