# SPDX-License-Identifier: GPL-3.0-or-later
"""Properties editor > Modifiers: the skin's muscle settings (armature, muscles, bind state, live update)."""
import bpy

from .. import core_loader
from ..blender_io import find_armature
from ..state import rig_skins
from .common import draw_core_status, draw_last_error


class MYOSKIN_PT_skin_muscles(bpy.types.Panel):
    bl_label = "Myoskin Muscles"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "modifier"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == 'MESH'

    def draw(self, context):
        layout = self.layout
        draw_core_status(layout, context)
        arm = find_armature(context.object)
        if arm is None:
            layout.label(text="No armature: add an Armature modifier", icon='ERROR')
            return
        layout.label(text=f"Skinned by {arm.name} ({len(arm.data.bones)} bones)", icon='ARMATURE_DATA')
        draw_last_error(layout, arm, context)
        state = arm.myoskin
        skins = rig_skins(arm)
        if skins and context.object not in skins:
            layout.label(text=f"Muscles belong to {', '.join(o.name for o in skins)}", icon='INFO')
            return
        if len(skins) > 1:
            layout.label(text=f"Character of {len(skins)} meshes: {', '.join(o.name for o in skins)}", icon='INFO')
        enabled = sum(1 for m in state.muscles if m.enabled)
        layout.label(text=f"{len(state.muscles)} muscles ({enabled} enabled)", icon='MOD_SKIN')
        row = layout.row(align=True)
        row.enabled = core_loader.available()
        if not state.muscles:
            row.operator("myoskin.extract_muscles", icon='MOD_SKIN')
            return
        row.operator("myoskin.bind", icon='LINKED')
        row.operator("myoskin.unbind", icon='UNLINKED')
        if state.bound:
            layout.prop(state, "live")
            if state.dirty:
                layout.label(text="Edited since the bind: Bind again", icon='ERROR')


classes = (MYOSKIN_PT_skin_muscles,)
