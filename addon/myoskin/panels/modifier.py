# SPDX-License-Identifier: GPL-3.0-or-later
"""Properties editor > Modifiers: the skin's muscle settings (for now: core status and armature)."""
import bpy

from ..blender_io import find_armature
from .common import draw_core_status


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
        else:
            layout.label(text=f"Skinned by {arm.name} ({len(arm.data.bones)} bones)", icon='ARMATURE_DATA')


classes = (MYOSKIN_PT_skin_muscles,)
