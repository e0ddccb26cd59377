# SPDX-License-Identifier: GPL-3.0-or-later
"""View3D > Sidebar > Myoskin > Dynamics (issue 16): jiggle settings of the rig and of the active muscle, the
painted jiggle map, skin solve and temporal filter, the skin's sculpt deltas, and the bakes with dynamics
(Bake Muscle Action with jiggle, Bake PC2 with everything); farms: batch.py. Drawing only: no core calls."""
import bpy

from .. import core_loader, dynamics
from ..blender_io import find_skin_meshes
from .sidebar import MyoskinSidebar, active_rig


def dynamics_skin(context, arm, skin):
    """The mesh the per-skin rows act on: the active skin, else the armature's one skin (None when several)."""
    if skin is not None and skin.type == 'MESH' and skin.get("myoskin_muscle") is None:
        return skin
    meshes = find_skin_meshes(arm)
    return meshes[0] if len(meshes) == 1 else None


def draw_jiggle(layout, state, skin):
    """The rig's jiggle settings, the active muscle's overrides and the painted map."""
    col = layout.column(align=True)
    col.prop(state, "jiggle")
    if not state.jiggle:
        return
    row = col.row(align=True)
    row.prop(state, "jiggle_frequency")
    row.prop(state, "jiggle_damping")
    col.prop(state, "jiggle_amount")
    if 0 <= state.active_index < len(state.muscles):
        item = state.muscles[state.active_index]
        row = col.row(align=True)
        row.label(text=item.name)
        row.prop(item, "jiggle_frequency", text="Hz")
        row.prop(item, "jiggle_damping", text="Damping")
    if skin is None:
        col.label(text="Select a skin for its jiggle map", icon='INFO')
    elif dynamics.JIGGLE_GROUP in skin.vertex_groups:
        col.label(text=f"Jiggle map: vertex group {dynamics.JIGGLE_GROUP} (Weight Paint)", icon='GROUP_VERTEX')
    else:
        col.operator("myoskin.add_jiggle_map", icon='GROUP_VERTEX').skin = skin.name


def draw_sculpt(layout, skin):
    """The skin's sculpt deltas (frame, source, Remove) and Capture from the active shape key."""
    box = layout.box()
    if skin is None:
        box.label(text="Select a skin for its sculpt deltas", icon='INFO')
        return
    try:
        info = dynamics.sculpt_info(skin)
    except ValueError as e:
        box.label(text=str(e), icon='ERROR')
        info = None
    if info is not None:
        row = box.row(align=True)
        row.label(text=f"Sculpt deltas: frame {info['frame']}, {info.get('source', '')}", icon='SCULPTMODE_HLT')
        row.operator("myoskin.remove_sculpt", text="", icon='X').skin = skin.name
    else:
        box.label(text="No sculpt deltas", icon='SCULPTMODE_HLT')
    key = skin.active_shape_key
    source = key.name if key is not None and key != getattr(skin.data.shape_keys, "reference_key", None) else ""
    box.label(text=f"Sculpt: {source or '(make the sculpted shape key active)'}")
    row = box.row()
    row.enabled = core_loader.available() and bool(source)
    op = row.operator("myoskin.capture_sculpt", icon='ADD')
    op.skin, op.source_key = skin.name, source


class MYOSKIN_PT_dynamics(MyoskinSidebar, bpy.types.Panel):
    bl_label = "Dynamics"
    bl_parent_id = "MYOSKIN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        skin, arm = active_rig(context)
        if arm is None:
            layout.label(text="Select a skinned mesh or its armature", icon='INFO')
            return
        if not core_loader.available():
            layout.label(text="Needs the compiled core", icon='ERROR')
            return
        state, ui = arm.myoskin, context.scene.myoskin_ui
        skin = dynamics_skin(context, arm, skin)
        draw_jiggle(layout, state, skin)
        col = layout.column(align=True)
        col.prop(state, "skin_solve")
        row = col.row()
        row.enabled = state.skin_solve
        row.prop(state, "temporal_filter")
        draw_sculpt(layout, skin)
        if not state.bound:
            layout.label(text="Bind first to bake", icon='INFO')
            return
        row = layout.row(align=True)
        row.prop(ui, "frame_start")
        row.prop(ui, "frame_end")
        op = layout.operator("myoskin.bake_action", text="Bake Muscle Action (Jiggle)", icon='ACTION')
        op.frame_start, op.frame_end, op.jiggle = ui.frame_start, ui.frame_end, state.jiggle
        layout.prop(ui, "pc2_path")
        op = layout.operator("myoskin.bake_pc2", text="Bake PC2 (Dynamics)", icon='FILE_CACHE')
        op.filepath, op.frame_start, op.frame_end = ui.pc2_path, ui.frame_start, ui.frame_end
        op.skin_solve, op.jiggle = state.skin_solve, state.jiggle
        op.temporal_filter = state.skin_solve and state.temporal_filter
        layout.label(text="Farms: batch.py --bake A-B --pc2 F --state-in S --state-out S", icon='INFO')


classes = (MYOSKIN_PT_dynamics,)
