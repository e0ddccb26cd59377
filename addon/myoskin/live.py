# SPDX-License-Identifier: GPL-3.0-or-later
"""Live update of bound muscles: when the skeleton moves, the muscle-joint bones (and the muscle surfaces)
follow, exactly as the core computes them.

Route (measured, README "Live update"): `frame_change_post` + `depsgraph_update_post` handlers. They read
the skeleton's pose from the EVALUATED armature of the depsgraph they are given (so IK, constraints and
drivers are already applied: no one-frame lag), evaluate the core's MuscleRig, write the joints' pose with
one foreach_set and tag the armature; Blender's second evaluation pass in the same frame_set / update then
re-skins with the new joints. Cost: the skin is evaluated twice per frame. The handlers write ORIGINAL data,
so every depsgraph (viewport, F12 / Cycles render with render.use_lock_interface on) sees the same joints.

State: nothing is held between calls but a cache keyed by armature name and the bind record's text (rebuilt
after reload or undo); objects are looked up in bpy.data on every call. Without the add-on the file opens
and shows the joints as last written (or as baked to the Action).
"""
import json

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import core_loader

_cache = {}     # armature name -> LiveRig
_busy = False


class LiveRig:
    """A MuscleRig built from an armature's bind record, plus index arrays into its pose bones."""

    def __init__(self, arm_obj, record_text):
        core = core_loader.core()
        record = json.loads(record_text)
        self.key = record_text
        self.bone_names = record["bone_names"]
        self.joint_names = record["joint_names"]
        self.character = skeleton_character(record)
        muscles = [core.reattach_muscle(m) for m in core.muscles_from_json(record["muscles"])]
        self.rig = core.MuscleRig(self.character, muscles)
        if list(self.rig.joint_names) != self.joint_names:
            raise ValueError(f"'{arm_obj.name}': the bind record's joints do not match its muscles: bind again")
        self.surface_names = record.get("surfaces", [])
        self.last_pose = None

    def skeleton_indices(self, pose_bones):
        idx = [pose_bones.find(n) for n in self.bone_names]
        missing = [n for n, i in zip(self.bone_names, idx) if i < 0]
        if missing:
            raise ValueError(f"bone '{missing[0]}' was renamed or deleted since the bind: bind again")
        return np.asarray(idx)


def skeleton_character(record):
    """A core Character carrying only the bind record's skeleton (MuscleRig needs no skin); its mesh is a
    unit tetrahedron placeholder."""
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)
    return core_loader.core().character_from_arrays(
        "skeleton", tetra, faces, record["bone_names"], np.asarray(record["bone_parents"], dtype=np.int32),
        np.asarray(record["bone_heads"], dtype=np.float64), np.asarray(record["bone_tails"], dtype=np.float64),
        np.ascontiguousarray(record["bone_rest"], dtype=np.float64), np.zeros((0, 0), dtype=np.int32),
        np.zeros((0, 0)))


def bind_record_text(arm_obj):
    text = arm_obj.myoskin.joint_names_text
    return text.as_string() if text is not None else ""


def live_rig(arm_obj):
    """The cached LiveRig of a bound armature (rebuilt when its bind record changed)."""
    record = bind_record_text(arm_obj)
    if not record:
        raise ValueError(f"'{arm_obj.name}' has no bind record: bind again")
    cached = _cache.get(arm_obj.name)
    if cached is None or cached.key != record:
        cached = LiveRig(arm_obj, record)
        _cache[arm_obj.name] = cached
    return cached


def evaluated_pose(arm_obj, live, depsgraph=None):
    """#B by 4 by 4 skeleton pose (armature space) from the evaluated armature (constraints and IK applied)."""
    source = arm_obj.evaluated_get(depsgraph) if depsgraph is not None else arm_obj
    pose_bones = source.pose.bones
    flat = np.empty(len(pose_bones) * 16, dtype=np.float32)
    pose_bones.foreach_get("matrix", flat)
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1)[live.skeleton_indices(pose_bones)].astype(np.float64)


def muscles_visible(arm_obj, view_layer=None):
    coll = arm_obj.myoskin.collection
    if coll is None or coll.hide_viewport:
        return False
    return any(o.visible_get() for o in coll.objects if o.type == 'MESH')


def update_armature(arm_obj, depsgraph=None, force=False, surfaces=None):
    """Pose one bound armature's muscle joints (and surfaces) from its evaluated skeleton. Returns True
    when it wrote something."""
    from . import rig_io
    live = live_rig(arm_obj)
    pose = evaluated_pose(arm_obj, live, depsgraph)
    if not force and live.last_pose is not None and np.array_equal(pose, live.last_pose):
        return False
    with_surfaces = muscles_visible(arm_obj) if surfaces is None else surfaces
    result = live.rig.evaluate(pose, with_surfaces=with_surfaces)
    parents = {n: pose[i] for i, n in enumerate(live.bone_names)}
    rig_io.write_joint_matrices(arm_obj, live.joint_names, result["joint_matrices"], parent_matrices=parents)
    if with_surfaces:
        write_surfaces(arm_obj, live, result["surfaces"])
    live.last_pose = pose
    return True


def write_surfaces(arm_obj, live, surfaces):
    for name, vertices in zip(live.surface_names, surfaces):
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != 'MESH' or len(obj.data.vertices) != len(vertices):
            continue
        obj.data.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
        obj.data.update()


def bound_armatures(scene):
    return [o for o in scene.objects if o.type == 'ARMATURE' and o.myoskin.bound and o.myoskin.live]


@persistent
def on_update(scene, depsgraph=None):
    """frame_change_post / depsgraph_update_post: re-pose every bound armature whose skeleton moved."""
    global _busy
    if _busy or not core_loader.available():
        return
    armatures = bound_armatures(scene)
    if not armatures:
        return
    _busy = True
    try:
        for arm in armatures:
            try:
                update_armature(arm, depsgraph)
            except (ValueError, RuntimeError) as e:
                print(f"Myoskin: live update of '{arm.name}' stopped: {e}")
                arm.myoskin["live"] = False
    finally:
        _busy = False


def forget(arm_name=None):
    """Drop cached rigs (all, or one armature's)."""
    if arm_name is None:
        _cache.clear()
    else:
        _cache.pop(arm_name, None)


def register():
    for handlers in (bpy.app.handlers.frame_change_post, bpy.app.handlers.depsgraph_update_post):
        if on_update not in handlers:
            handlers.append(on_update)


def unregister():
    for handlers in (bpy.app.handlers.frame_change_post, bpy.app.handlers.depsgraph_update_post):
        if on_update in handlers:
            handlers.remove(on_update)
    forget()
