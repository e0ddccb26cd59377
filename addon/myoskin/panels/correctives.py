# SPDX-License-Identifier: GPL-3.0-or-later
"""View3D > Sidebar > Myoskin > Correctives: the skin's pose-space correctives (each with its driving bone and a
Remove button) and Add Corrective from the skin's active shape key, driven by the active pose bone. Drawing only."""
import math

import bpy

from .. import core_loader
from ..blender_io import find_skin_meshes
from ..correctives import stored
from .sidebar import MyoskinSidebar, active_rig


class MYOSKIN_PT_correctives(MyoskinSidebar, bpy.types.Panel):
    bl_label = "Correctives"
    bl_parent_id = "MYOSKIN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        skin, arm = active_rig(context)
        if skin is None and arm is not None:  # the armature active (Pose Mode) with one skinned mesh
            meshes = find_skin_meshes(arm)
            skin = meshes[0] if len(meshes) == 1 else None
        if skin is None or arm is None:
            layout.label(text="Select a skinned mesh")
            return
        try:
            _armature, entries = stored(skin)
        except ValueError as e:
            layout.label(text=str(e), icon='ERROR')
            entries = []
        col = layout.column(align=True)
        for e in entries:
            row = col.row(align=True)
            row.label(text=f"{e['name']}  ({e['bone']}, {math.degrees(float(e['falloff'])):.0f} deg)",
                      icon='SHAPEKEY_DATA')
            op = row.operator("myoskin.remove_corrective", text="", icon='X')
            op.name, op.skin = e["name"], skin.name
        if not entries:
            col.label(text="No correctives")
        key = skin.active_shape_key
        pose_bone = context.active_pose_bone if arm.mode == 'POSE' else None
        bone = pose_bone.name if pose_bone is not None else ""
        source = key.name if key is not None and key != getattr(skin.data.shape_keys, "reference_key", None) else ""
        layout.label(text=f"Sculpt: {source or '(make the sculpted shape key active)'}")
        layout.label(text=f"Bone: {bone or '(pose the driving bone and make it active)'}")
        row = layout.row()
        row.enabled = core_loader.available() and bool(source) and bool(bone)
        op = row.operator("myoskin.add_corrective", icon='ADD')
        op.skin, op.bone, op.source_key = skin.name, bone, source


classes = (MYOSKIN_PT_correctives,)
