# SPDX-License-Identifier: GPL-3.0-or-later
"""View3D > Sidebar > Myoskin: core status, the active character, then the workflow in order."""
import bpy

from .. import core_loader
from .common import draw_character_info, draw_core_status


class MyoskinSidebar:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Myoskin"


class MYOSKIN_PT_main(MyoskinSidebar, bpy.types.Panel):
    bl_label = "Myoskin"

    def draw(self, context):
        layout = self.layout
        draw_core_status(layout, context)
        draw_character_info(layout, context.active_object)
        row = layout.row(align=True)
        row.enabled = core_loader.available()
        row.operator("myoskin.character_info", icon='INFO')
        row = layout.row()
        row.enabled = core_loader.available()
        row.operator("myoskin.add_synthetic_arm", icon='ADD')


class _WorkflowStep(MyoskinSidebar):
    bl_parent_id = "MYOSKIN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}
    hint = ""

    def draw(self, context):
        col = self.layout.column()
        col.enabled = core_loader.available()
        col.label(text=self.hint)
        col.label(text="Coming soon", icon='TIME')


class MYOSKIN_PT_extract(_WorkflowStep, bpy.types.Panel):
    bl_label = "1. Extract"
    hint = "Find the muscles that shape the skin"


class MYOSKIN_PT_edit(_WorkflowStep, bpy.types.Panel):
    bl_label = "2. Edit"
    hint = "Add, remove and reshape muscles"


class MYOSKIN_PT_bind(_WorkflowStep, bpy.types.Panel):
    bl_label = "3. Bind"
    hint = "Muscle joints and weights on the rig"


class MYOSKIN_PT_bake(_WorkflowStep, bpy.types.Panel):
    bl_label = "4. Bake"
    hint = "Muscle motion to keyframes or a cache"


classes = (MYOSKIN_PT_main, MYOSKIN_PT_extract, MYOSKIN_PT_edit, MYOSKIN_PT_bind, MYOSKIN_PT_bake)
