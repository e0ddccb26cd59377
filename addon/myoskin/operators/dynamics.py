# SPDX-License-Identifier: GPL-3.0-or-later
"""Dynamics operators (issue 16): Capture / Remove Sculpt Deltas (detail sculpted at one frame, re-applied by
Bake PC2 on every frame in the surface's local frame) and Add Jiggle Map (the painted per-vertex jiggle
influence). Small: resolve the skin, call the services (dynamics, correctives) and the bake, report."""
import bpy
import numpy as np
from bpy.props import StringProperty

from .. import binding, blender_io, core_loader, correctives, dynamics
from ..state import rig_state
from .correctives import pose_muscle_joints, resolve_skin
from .muscles import _MuscleOperator
from .rig import bake_skin_frames


def simulation_start(scene, frame):
    """The frame Bake PC2 from the Dynamics panel simulates from: the panel's Start (never after `frame`)."""
    return min(scene.myoskin_ui.frame_start, frame)


def simulated_frame(context, skin, arm, frame):
    """#V by 3 float64 (mesh space): what Bake PC2 from the Dynamics panel (the rig's settings, simulated from the
    panel's Start) gives at `frame` without the sculpt."""
    state = rig_state(arm)
    frames = bake_skin_frames(context, [skin], arm, frame, frame, skin_solve=state.skin_solve, jiggle=state.jiggle,
                              temporal_filter=state.skin_solve and state.temporal_filter,
                              sim_start=simulation_start(context.scene, frame), sculpt=False)
    return np.asarray(frames[0][0], dtype=np.float64)


class MYOSKIN_OT_capture_sculpt(_MuscleOperator, bpy.types.Operator):
    """Store detail sculpted at the current frame (a shape key sculpted on the posed skin, or a sculpted copy of
    it) as normal-space deltas against the simulated skin there; Bake PC2 re-applies them on every frame in the
    surface's local frame, so the detail turns with the surface"""
    bl_idname = "myoskin.capture_sculpt"
    bl_label = "Capture Sculpt Deltas"

    source_key: StringProperty(name="Sculpt Shape Key", description="The skin's shape key holding the detail "
                               "(sculpted on the posed skin at this frame); set to 0 once captured")
    source_object: StringProperty(name="Sculpt Object", description="Or a sculpted copy of the skin as simulated "
                                  "at this frame (same vertices), in place of the shape key")
    skin: StringProperty(name="Skin", description="The skinned mesh (empty: the active object)")

    def run(self, context):
        skin, arm = resolve_skin(context, self.skin)
        if not rig_state(arm).bound:
            raise ValueError(f"'{arm.name}' is not bound: Bind first")
        if skin not in [s.object for s in rig_state(arm).skins]:
            raise ValueError(f"'{skin.name}' is not a mesh of the muscles of '{arm.name}'")
        if bool(self.source_key) == bool(self.source_object):
            raise ValueError("Give the sculpt as a shape key of the skin or as a sculpted object (one of them)")
        if skin.mode != 'OBJECT':
            raise ValueError(f"'{skin.name}' is in {skin.mode.title()} Mode: go back to Object Mode to capture")
        frame = context.scene.frame_current
        pose_muscle_joints(arm)
        if self.source_key:  # the key's offset on the posed skin, added to the simulated skin
            sculpted = correctives.sculpt_target(context, skin, arm, source_key=self.source_key)
            kb = skin.data.shape_keys.key_blocks[self.source_key]
            kb.value = 0.0  # captured: from now on the deltas carry it (the bake's shape key mix leaves it out)
            offset = sculpted - correctives.evaluated(skin, context, keep=binding.armature_modifiers(skin, arm))
            reference = simulated_frame(context, skin, arm, frame)
            sculpted = reference + offset
            source = f"shape key {self.source_key}"
        else:
            obj = bpy.data.objects.get(self.source_object)
            if obj is None:
                raise ValueError(f"There is no object '{self.source_object}'")
            sculpted = correctives.sculpt_target(context, skin, arm, source_object=obj)
            reference = simulated_frame(context, skin, arm, frame)
            source = f"object {obj.name}"
        to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
        deltas = core_loader.core().SculptDeltas(reference @ to_arm[:3, :3].T + to_arm[:3, 3],
                                                 blender_io.mesh_triangles(skin.data),
                                                 sculpted @ to_arm[:3, :3].T + to_arm[:3, 3])
        dynamics.store_sculpt(skin, arm, frame, source, deltas)
        moved = float(np.linalg.norm(sculpted - reference, axis=1).max())
        return (f"Captured sculpt deltas on '{skin.name}' at frame {frame} from the {source} (detail up to "
                f"{moved:.4g}): Bake PC2 applies them on every frame")


class MYOSKIN_OT_remove_sculpt(_MuscleOperator, bpy.types.Operator):
    """Remove the skin's sculpt deltas (Bake PC2 no longer adds the detail)"""
    bl_idname = "myoskin.remove_sculpt"
    bl_label = "Remove Sculpt Deltas"

    skin: StringProperty(name="Skin", description="The skinned mesh (empty: the active object)")

    def run(self, context):
        skin, _arm = resolve_skin(context, self.skin)
        if not dynamics.remove_sculpt(skin):
            raise ValueError(f"'{skin.name}' has no sculpt deltas")
        return f"Removed the sculpt deltas of '{skin.name}'"


class MYOSKIN_OT_add_jiggle_map(_MuscleOperator, bpy.types.Operator):
    """Add the painted jiggle map to the skin: the vertex group myoskin_jiggle at full weight (the default
    jiggle); paint it toward 0 where the skin should not jiggle. Bake PC2 scales each vertex's jiggle by it;
    Bake Muscle Action scales each muscle joint's by its mean over the skin the joint moves"""
    bl_idname = "myoskin.add_jiggle_map"
    bl_label = "Add Jiggle Map"

    skin: StringProperty(name="Skin", description="The skinned mesh (empty: the active object)")

    def run(self, context):
        skin, _arm = resolve_skin(context, self.skin)
        if dynamics.JIGGLE_GROUP in skin.vertex_groups:
            raise ValueError(f"'{skin.name}' has a jiggle map already (vertex group {dynamics.JIGGLE_GROUP}): "
                             f"paint it in Weight Paint mode")
        group = skin.vertex_groups.new(name=dynamics.JIGGLE_GROUP)
        group.add(list(range(len(skin.data.vertices))), 1.0, 'REPLACE')
        skin.vertex_groups.active_index = group.index
        return f"Added the jiggle map {dynamics.JIGGLE_GROUP} to '{skin.name}' (1 everywhere: paint it down)"


classes = (MYOSKIN_OT_capture_sculpt, MYOSKIN_OT_remove_sculpt, MYOSKIN_OT_add_jiggle_map)
