# SPDX-License-Identifier: GPL-3.0-or-later
"""View3D > Sidebar > Myoskin: core status, the active character, then the workflow in order
Extract -> Edit -> Bind -> Bake. Drawing only: no core calls (panels redraw often)."""
import bpy

from .. import core_loader
from ..blender_io import find_armature
from ..state import BONE_ROLES, missing_role_bones, role_chains, role_overrides, rig_skins
from .common import draw_character_info, draw_core_status, draw_last_error, draw_wrapped


class MyoskinSidebar:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Myoskin"


def active_rig(context):
    """(skin or None, armature or None) for the active object: the skin, its armature or a muscle object."""
    obj = context.active_object
    if obj is None:
        return None, None
    if obj.get("myoskin_muscle") is not None and obj.parent is not None and obj.parent.type == 'ARMATURE':
        return obj.parent.myoskin.skin, obj.parent
    arm = find_armature(obj)
    if arm is None:
        return None, None
    skin = obj if obj.type == 'MESH' else arm.myoskin.skin
    return skin, arm


class MYOSKIN_PT_main(MyoskinSidebar, bpy.types.Panel):
    bl_label = "Myoskin"

    def draw(self, context):
        layout = self.layout
        draw_core_status(layout, context)
        draw_last_error(layout, active_rig(context)[1], context)
        draw_character_info(layout, context.active_object)
        row = layout.row(align=True)
        row.enabled = core_loader.available()
        row.operator("myoskin.character_info", icon='INFO')
        row = layout.row()
        row.enabled = core_loader.available()
        row.operator("myoskin.add_synthetic_arm", icon='ADD')


class _WorkflowStep(MyoskinSidebar):
    bl_parent_id = "MYOSKIN_PT_main"
    hint = ""

    def draw(self, context):
        layout = self.layout
        if not core_loader.available():
            layout.label(text=self.hint)
            layout.label(text="Needs the compiled core (see above)", icon='ERROR')
            return
        skin, arm = active_rig(context)
        if arm is None:
            layout.label(text=self.hint)
            layout.label(text="Select a skinned mesh or its armature", icon='INFO')
            return
        self.draw_step(context, layout, skin, arm, arm.myoskin, context.scene.myoskin_ui)


class MYOSKIN_PT_extract(_WorkflowStep, bpy.types.Panel):
    bl_label = "1. Extract"
    hint = "Find the muscles that shape the skin"

    def draw_step(self, context, layout, skin, arm, state, ui):
        col = layout.column()
        col.prop(ui, "spacing_radii")
        col.prop(ui, "min_confidence")
        col.prop(ui, "joint_wrap")
        col.prop(ui, "max_per_region")
        col.prop(ui, "limit")
        if ui.limit == 'GROUP' and skin is not None:
            col.prop_search(ui, "vertex_group", skin, "vertex_groups")
        row = layout.row()
        row.enabled = not state.bound
        op = row.operator("myoskin.extract_muscles", icon='MOD_SKIN')
        op.spacing, op.min_confidence, op.limit, op.vertex_group = (ui.spacing_radii, ui.min_confidence, ui.limit,
                                                                    ui.vertex_group)
        op.joint_wrap, op.max_per_region, op.expert = ui.joint_wrap, ui.max_per_region, ui.expert
        layout.prop(ui, "expert")  # tuning, not everyday use
        if state.bound:
            layout.label(text="Bound: unbind to extract again", icon='LOCKED')
        layout.label(text=f"{len(state.muscles)} muscles on {arm.name}", icon='OUTLINER_OB_MESH')


ROLE_LABELS = {key: label for key, label, _description in BONE_ROLES}


def draw_role_row(layout, item):
    """One bone: its name, an override mark, its role (editable)."""
    row = layout.row(align=True)
    split = row.split(factor=0.55, align=True)
    split.label(text=item.name, icon='BONE_DATA')
    split.prop(item, "role", text="")
    if item.overridden:
        row.label(text="", icon='MODIFIER_ON')  # an override (differs from the detected role)


class MYOSKIN_UL_bone_roles(bpy.types.UIList):
    """The ignored bones (to give one a role); filter by name."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        draw_role_row(layout, item)

    def filter_items(self, context, data, propname):
        items = getattr(data, propname)
        flags = [self.bitflag_filter_item if item.role == 'ignore' else 0 for item in items]
        if self.filter_name:
            by_name = bpy.types.UI_UL_list.filter_items_by_name(self.filter_name, self.bitflag_filter_item, items,
                                                                "name")
            flags = [f & n for f, n in zip(flags, by_name)]
        return flags, []


class MYOSKIN_PT_bone_roles(_WorkflowStep, bpy.types.Panel):
    bl_label = "Bone Roles"
    bl_parent_id = "MYOSKIN_PT_extract"
    bl_options = {'DEFAULT_CLOSED'}
    hint = "Which bones get cutting planes"

    def draw_step(self, context, layout, skin, arm, state, ui):
        row = layout.row(align=True)
        row.operator("myoskin.detect_bone_roles", icon='VIEWZOOM')
        row.operator("myoskin.reset_bone_roles", icon='LOOP_BACK')
        if len(state.bone_roles) == 0:
            layout.label(text="Not detected yet: Detect (or Extract) lists them", icon='INFO')
            return
        missing = missing_role_bones(arm)
        if missing:
            box = layout.box()
            box.alert = True
            draw_wrapped(box, f"Overrides name bones '{arm.name}' no longer has: {', '.join(missing)} (renamed or "
                              f"deleted?). Detect drops them, Reset clears every override.", context, icon='ERROR')
        overrides = role_overrides(arm)
        chains = role_chains(arm)
        layout.label(text=f"{len(chains)} chain(s), {len(overrides)} override(s)", icon='ARMATURE_DATA')
        for role, chain in chains:
            box = layout.box()
            col = box.column(align=True)
            col.label(text=f"{ROLE_LABELS.get(role, role)}: {chain[0].name}"
                           f"{f' .. {chain[-1].name}' if len(chain) > 1 else ''}")
            for item in chain:
                draw_role_row(col, item)
        ignored = sum(1 for item in state.bone_roles if item.role == 'ignore')
        layout.prop(ui, "show_ignored", text=f"Ignored Bones ({ignored})",
                    icon='TRIA_DOWN' if ui.show_ignored else 'TRIA_RIGHT', emboss=False)
        if ui.show_ignored and ignored:
            layout.template_list("MYOSKIN_UL_bone_roles", "", state, "bone_roles", state, "bone_role_index", rows=4)


class MYOSKIN_UL_muscles(bpy.types.UIList):
    """One row per muscle: enabled toggle, editable name, confidence."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.prop(item, "enabled", text="")
        split = row.split(factor=0.8, align=True)
        split.prop(item, "name", text="", emboss=False)
        missing = item.surface is None or item.surface.name not in bpy.data.objects
        split.label(text="!" if missing else f"{item.confidence:.2f}", icon='ERROR' if missing else 'NONE')


class MYOSKIN_PT_edit(_WorkflowStep, bpy.types.Panel):
    bl_label = "2. Edit"
    hint = "Add, remove and reshape muscles"

    def draw_step(self, context, layout, skin, arm, state, ui):
        row = layout.row()
        row.template_list("MYOSKIN_UL_muscles", "", state, "muscles", state, "active_index", rows=5)
        col = row.column(align=True)
        op = col.operator("myoskin.add_muscle_from_region", icon='ADD', text="")
        op.source, op.vertex_group = ui.region_source, ui.vertex_group
        col.operator("myoskin.remove_muscle", icon='REMOVE', text="").index = -1
        col.separator()
        col.operator("myoskin.mirror_muscle", icon='MOD_MIRROR', text="")
        col.operator("myoskin.select_muscle", icon='RESTRICT_SELECT_OFF', text="").index = -1
        col.operator("myoskin.refresh_muscles", icon='FILE_REFRESH', text="")
        box = layout.box()
        box.label(text="Add Muscle from Region")
        box.prop(ui, "region_source", text="")
        if ui.region_source == 'GROUP' and skin is not None:
            box.prop_search(ui, "vertex_group", skin, "vertex_groups")
        if not 0 <= state.active_index < len(state.muscles):
            return
        item = state.muscles[state.active_index]
        col = layout.column()
        col.label(text=f"{item.region}  (confidence {item.confidence:.2f})", icon='INFO')
        col.prop(item, "bulge")
        col.prop(item, "joints")
        col.prop(item, "wrap_type")
        if item.wrap_type != 'none':
            col.prop_search(item, "wrap_bone", arm.data, "bones")
            col.prop(item, "wrap_radius")
            if item.wrap_type == 'bone':
                col.prop(item, "wrap_side", expand=True)
        for end in ("origin", "insertion"):
            col.label(text=f"{end.title()} on {getattr(item, end + '_bone')}", icon='EMPTY_AXIS')
            row = col.row(align=True)
            locator = getattr(item, end + "_locator")
            if locator is not None:
                row.prop(locator, "location", text="")
            row.operator("myoskin.snap_locator", text="", icon='SNAP_ON').end = end


class MYOSKIN_PT_bind(_WorkflowStep, bpy.types.Panel):
    bl_label = "3. Bind"
    hint = "Muscle joints and weights on the rig"

    def draw_step(self, context, layout, skin, arm, state, ui):
        row = layout.row(align=True)
        row.operator("myoskin.bind", icon='LINKED')
        row.operator("myoskin.unbind", icon='UNLINKED')
        layout.prop(state, "deformer")
        if state.deformer == 'ANCHORED':
            layout.operator("myoskin.add_stuffing", icon='SPHERE')
        layout.prop(state, "max_influences")
        layout.prop(state, "volume_blend")
        row = layout.row()
        row.active = not state.volume_blend
        row.prop(state, "preserve_volume")
        row = layout.row()
        row.active = state.deformer != 'ANCHORED'  # the anchored skin does not use the muscle joints
        row.prop(state, "joints_slide")
        if state.bound:
            skins = rig_skins(arm)
            layout.label(text=f"Bound to {', '.join(o.name for o in skins) if skins else '?'}", icon='CHECKMARK')
            layout.prop(state, "live")
            layout.prop(state, "auto_rebind")
            if state.dirty:
                layout.label(text="Edited since the bind: Bind again", icon='ERROR')
        else:
            layout.label(text="Not bound", icon='INFO')


class MYOSKIN_PT_bake(_WorkflowStep, bpy.types.Panel):
    bl_label = "4. Bake"
    hint = "Muscle motion to keyframes or a cache"

    def draw_step(self, context, layout, skin, arm, state, ui):
        row = layout.row(align=True)
        row.prop(ui, "frame_start")
        row.prop(ui, "frame_end")
        op = layout.operator("myoskin.bake_action", icon='ACTION')
        op.frame_start, op.frame_end, op.jiggle = ui.frame_start, ui.frame_end, False
        layout.prop(ui, "export_path")
        layout.operator("myoskin.export_gltf", icon='EXPORT').filepath = ui.export_path
        layout.prop(ui, "pc2_path")
        op = layout.operator("myoskin.bake_pc2", icon='FILE_CACHE')
        op.filepath, op.frame_start, op.frame_end = ui.pc2_path, ui.frame_start, ui.frame_end
        op.skin_solve = op.jiggle = op.temporal_filter = False
        layout.label(text="Jiggle, skin solve, sculpt deltas: the Dynamics panel", icon='INFO')


classes = (MYOSKIN_UL_muscles, MYOSKIN_UL_bone_roles, MYOSKIN_PT_main, MYOSKIN_PT_extract, MYOSKIN_PT_bone_roles,
           MYOSKIN_PT_edit, MYOSKIN_PT_bind,
           MYOSKIN_PT_bake)
