# SPDX-License-Identifier: GPL-3.0-or-later
"""Rig operators: Bind / Unbind the muscles to the character's armature, Bake the muscle joints to an Action,
export glTF with the helper bones, bake the skin to a PC2 cache through the core.
Small: convert data (blender_io, rig_io, muscle_io), call the core, report."""
import json
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty, StringProperty

from .. import blender_io, core_loader, gltf_io, live, muscle_io, rig_io
from .muscles import _MuscleOperator, require_weights, resolve_extracted, resolve_rig
from ..state import rig_state


# ------------------------------------------------------------------------------------------------
# Bind record and weight backup (Text datablocks, so they live in the .blend)
# ------------------------------------------------------------------------------------------------


BACKUP_KEY = "myoskin_original_weights"


def backup_weights(skin):
    """Store every vertex group of the skin as an ID property on it: {name: {"index": group index,
    "vertices": [...], "weights": [...]}}. Weights are float32 in Blender and kept as float64 here, so a
    restore is exact."""
    members = [([], []) for _ in skin.vertex_groups]
    for v in skin.data.vertices:
        for g in v.groups:
            members[g.group][0].append(v.index)
            members[g.group][1].append(g.weight)
    skin[BACKUP_KEY] = {g.name: {"index": g.index, "vertices": ids, "weights": ws}
                        for g, (ids, ws) in zip(skin.vertex_groups, members)}


def restore_weights(skin):
    """Give every backed-up group exactly its backed-up members (groups keep their index; a group renamed
    since, e.g. with its bone, is found by index; missing ones are recreated; groups added since the backup
    are left alone), then drop the backup."""
    backup = skin.get(BACKUP_KEY)
    if backup is None:
        return False
    everyone = list(range(len(skin.data.vertices)))
    names = set(backup.keys())
    for name, entry in sorted(backup.items(), key=lambda kv: kv[1]["index"]):
        group = skin.vertex_groups.get(name)
        if group is None:  # renamed with its bone since the bind (a group keeps its index): restore into it
            index = int(entry["index"])
            if index < len(skin.vertex_groups) and skin.vertex_groups[index].name not in names:
                group = skin.vertex_groups[index]
            else:
                group = skin.vertex_groups.new(name=name)
        group.remove(everyone)
        ids = np.asarray(entry["vertices"], dtype=np.int64)
        ws = np.asarray(entry["weights"], dtype=np.float64)
        order = np.argsort(ws, kind="stable")
        ids, ws = ids[order], ws[order]
        breaks = np.flatnonzero(np.diff(ws) != 0) + 1
        for a, b in zip(np.concatenate(([0], breaks)), np.concatenate((breaks, [len(ws)]))):
            if b > a:
                group.add(ids[a:b].tolist(), float(ws[a]), 'REPLACE')
    del skin[BACKUP_KEY]
    return True


def hybrid_weights(core, character, rig):
    """(#V by K joints over combined joints, #V by K weights) for the skin (core, issue 5)."""
    result = core.hybrid_weights(character, rig)
    return np.asarray(result[0]), np.asarray(result[1])


def armature_modifier(skin, arm):
    for mod in skin.modifiers:
        if mod.type == 'ARMATURE' and mod.object == arm:
            return mod
    return None


def bind(context, skin, arm):
    """Create the muscle joints as deform bones, write the combined weights, keep/add the Armature modifier.
    Returns the number of joints."""
    core = core_loader.core()
    state = rig_state(arm)
    require_weights(skin, arm)
    if arm.name not in context.view_layer.objects:
        raise ValueError(f"Armature '{arm.name}' is not in the view layer: link it to bind")
    character = blender_io.character_from_blender(skin, arm)
    muscles = [core.reattach_muscle(m) for m in muscle_io.state_to_core(arm)]
    if not muscles:
        raise ValueError(f"Every muscle of '{arm.name}' is disabled: enable at least one to bind")
    rig = core.MuscleRig(character, muscles)
    joints, weights = hybrid_weights(core, character, rig)
    backup_weights(skin)
    names = list(character.bone_names)
    try:
        rig_io.create_rig_bones(arm, rig, names)
        rig_io.write_combined_weights(skin, names + list(rig.joint_names), joints, weights)
    except Exception:  # leave the rig as it was: no joint bones, the original weights
        rig_io.remove_muscle_bones(arm)
        restore_weights(skin)
        raise
    added = armature_modifier(skin, arm) is None
    if added:
        mod = skin.modifiers.new("Armature", 'ARMATURE')
        mod.object = arm
        mod.use_vertex_groups, mod.use_bone_envelopes, mod.use_deform_preserve_volume = True, False, False
    surfaces = {m.name: item.surface.name for item in rig_state(arm).muscles
                for m in muscles if m.name == item.name and item.surface is not None}
    record = {
        "skin": skin.name, "added_modifier": added, "bone_names": names,
        "bone_parents": np.asarray(character.bone_parents).tolist(),
        "bone_heads": np.asarray(character.bone_heads).tolist(),
        "bone_tails": np.asarray(character.bone_tails).tolist(),
        "bone_rest": np.asarray(character.bone_rest).tolist(),
        "joint_names": list(rig.joint_names), "muscles": core.muscles_to_json(muscles),
        "surfaces": [surfaces.get(m.name, "") for m in muscles],
    }
    live.write_bind_record(arm, record)
    state.skin = skin
    state.bound, state.dirty = True, False
    context.scene.render.use_lock_interface = True  # handlers run on the render thread during F12
    live.forget(arm.name)
    live.update_armature(arm, force=True)
    return rig.num_joints


def unbind(skin, arm):
    """Remove the muscle-joint bones and their groups, restore the original weights exactly."""
    state = rig_state(arm)
    record = json.loads(state.bind_text.as_string()) if state.bind_text else {}
    rig_io.remove_muscle_bones(arm)
    restore_weights(skin)
    if record.get("added_modifier"):
        mod = armature_modifier(skin, arm)
        if mod is not None:
            skin.modifiers.remove(mod)
    if state.bind_text is not None:
        bpy.data.texts.remove(state.bind_text)
    state.bound, state.dirty = False, False
    live.forget(arm.name)


class MYOSKIN_OT_bind(_MuscleOperator, bpy.types.Operator):
    """Bind the enabled muscles: muscle joints become deform bones of the armature (own bone layer),
    their weights vertex groups blended with the skeleton's (binds again when already bound)"""
    bl_idname = "myoskin.bind"
    bl_label = "Bind"

    def run(self, context):
        skin, arm, state = resolve_extracted(context)
        wm = context.window_manager
        wm.progress_begin(0, 2)
        try:
            if state.bound:
                unbind(skin, arm)
            wm.progress_update(1)
            joints = bind(context, skin, arm)
        finally:
            wm.progress_end()
        return f"Bound {sum(1 for m in state.muscles if m.enabled)} muscles ({joints} joints) to {arm.name}"


class MYOSKIN_OT_unbind(_MuscleOperator, bpy.types.Operator):
    """Remove the muscle joints and restore the skin's original weights exactly"""
    bl_idname = "myoskin.unbind"
    bl_label = "Unbind"

    def run(self, context):
        skin, arm = resolve_rig(context.active_object)
        if not rig_state(arm).bound:
            raise ValueError(f"'{arm.name}' is not bound")
        unbind(skin, arm)
        return f"Unbound {arm.name}: original weights restored"


def require_bound(context):
    skin, arm, state = resolve_extracted(context)
    if not state.bound:
        raise ValueError(f"'{arm.name}' is not bound: Bind first")
    return skin, arm, state


class MYOSKIN_OT_bake_action(_MuscleOperator, bpy.types.Operator):
    """Key the muscle joints' pose on every frame of a range into the armature's Action (plays without the
    add-on, exports to glTF)"""
    bl_idname = "myoskin.bake_action"
    bl_label = "Bake Muscle Action"

    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=120)

    def run(self, context):
        skin, arm, state = require_bound(context)
        if self.frame_end < self.frame_start:
            raise ValueError(f"Frame range {self.frame_start}-{self.frame_end} is empty")
        scene = context.scene
        names = json.loads(state.bind_text.as_string())["joint_names"]
        missing = [n for n in names if n not in arm.pose.bones]
        if missing:
            raise ValueError(f"Muscle bone '{missing[0]}' is missing (deleted or renamed?): bind again")
        live.live_rig(arm).skeleton_indices(arm.pose.bones)  # ValueError naming a renamed skeleton bone
        if arm.animation_data is None:
            arm.animation_data_create()
        if arm.animation_data.action is None:
            arm.animation_data.action = bpy.data.actions.new(f"{arm.name}Action")
        state.live = True  # mutes the joints' earlier baked keys, so they cannot override the live values
        wm = context.window_manager
        wm.progress_begin(self.frame_start, self.frame_end)
        current = scene.frame_current
        try:
            for frame in range(self.frame_start, self.frame_end + 1):
                scene.frame_set(frame)
                live.update_armature(arm, context.evaluated_depsgraph_get(), force=True)
                for n in names:
                    pb = arm.pose.bones[n]
                    pb.rotation_mode = 'QUATERNION'
                    for path in ("location", "rotation_quaternion", "scale"):
                        pb.keyframe_insert(path, frame=frame, group=n)
                wm.progress_update(frame)
        finally:
            wm.progress_end()
        state.live = False  # the baked Action plays now (also without the add-on); Live Update mutes it again
        scene.frame_set(current)
        return (f"Baked {len(names)} muscle joints over frames {self.frame_start}-{self.frame_end} "
                f"(live update off: the Action plays; turn it on after editing the animation)")


class MYOSKIN_OT_export_gltf(_MuscleOperator, bpy.types.Operator):
    """Export the skin and its armature, muscle-joint helper bones included, to glTF (with the Actions)"""
    bl_idname = "myoskin.export_gltf"
    bl_label = "Export glTF"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="File", subtype='FILE_PATH', default="//character.glb")

    def run(self, context):
        skin, arm = resolve_rig(context.active_object)
        path = bpy.path.abspath(self.filepath)
        if not path or path.endswith(os.sep):
            raise ValueError("Give a file name for the glTF export")
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        for obj in context.view_layer.objects:
            obj.select_set(obj in (skin, arm))
        gltf_io.export_gltf(path)
        return f"Exported {skin.name} + {arm.name} ({len(arm.data.bones)} bones) to {path}"


class MYOSKIN_OT_bake_pc2(_MuscleOperator, bpy.types.Operator):
    """Bake the skin over a frame range to a PC2 point cache computed by the core (Equation 3 with the
    muscle joints), for a Mesh Cache modifier or other tools"""
    bl_idname = "myoskin.bake_pc2"
    bl_label = "Bake PC2"
    bl_options = {'REGISTER'}

    filepath: StringProperty(name="File", subtype='FILE_PATH', default="//skin.pc2")
    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=120)
    add_modifier: BoolProperty(name="Add Mesh Cache Modifier", default=False)

    def run(self, context):
        skin, arm, state = require_bound(context)
        if self.frame_end < self.frame_start:
            raise ValueError(f"Frame range {self.frame_start}-{self.frame_end} is empty")
        path = bpy.path.abspath(self.filepath)
        frames = bake_skin_frames(context, skin, arm, self.frame_start, self.frame_end)
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        core_loader.core().write_pc2(path, frames, float(self.frame_start), 1.0)
        if self.add_modifier:
            mod = skin.modifiers.new("Myoskin PC2", 'MESH_CACHE')
            mod.cache_format, mod.filepath = 'PC2', path
        return f"Baked {len(frames)} frames of {skin.name} to {path}"


def bake_skin_frames(context, skin, arm, start, end):
    """#frames by #V by 3 float32 skin positions (mesh object space) from the core's skinner."""
    core = core_loader.core()
    rig = live.live_rig(arm)
    names = rig.bone_names + rig.joint_names
    joints, weights = rig_io.read_combined_weights(skin, names)
    to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
    rest = blender_io.mesh_vertices(skin.data) @ to_arm[:3, :3].T + to_arm[:3, 3]
    skinner = core.Skinner(rest, joints, weights, len(names))
    to_mesh = np.linalg.inv(to_arm)
    rest_bones = np.asarray(rig.character.bone_rest)
    bind_inv = np.linalg.inv(np.asarray(rig.rig.bind_matrices))
    scene = context.scene
    current = scene.frame_current
    out = np.empty((end - start + 1, len(rest), 3), dtype=np.float32)
    try:
        for k, frame in enumerate(range(start, end + 1)):
            scene.frame_set(frame)
            pose = live.evaluated_pose(arm, rig, context.evaluated_depsgraph_get())
            joint_matrices = rig.rig.evaluate(pose)["joint_matrices"]
            transforms = np.concatenate([pose @ np.linalg.inv(rest_bones), joint_matrices @ bind_inv])
            posed = skinner.deform(transforms).astype(np.float64)
            out[k] = posed @ to_mesh[:3, :3].T + to_mesh[:3, 3]
    finally:
        scene.frame_set(current)
    return out


classes = (MYOSKIN_OT_bind, MYOSKIN_OT_unbind, MYOSKIN_OT_bake_action, MYOSKIN_OT_export_gltf,
           MYOSKIN_OT_bake_pc2)
