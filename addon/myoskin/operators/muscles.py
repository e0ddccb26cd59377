# SPDX-License-Identifier: GPL-3.0-or-later
"""Muscle operators: extract, add from a marked region, remove, mirror, select, refresh, snap locators.
Small: convert data (blender_io, muscle_io), call the core, report."""
import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from .. import blender_io, core_loader, muscle_io
from ..blender_io import require_weights
from ..preferences import get_preferences
from ..state import LIMITS, rig_state


def resolve_rig(obj):
    """(skin mesh, armature) for the active object: the skin, its armature, or one of the muscle objects
    (surface, locator). ValueError with a message for the user otherwise."""
    if obj is not None and obj.get("myoskin_muscle") is not None and obj.parent is not None \
            and obj.parent.type == 'ARMATURE':
        arm = obj.parent
        skin = rig_state(arm).skin
        if skin is None:
            raise ValueError(f"Armature '{arm.name}' has no skin recorded: select the skinned mesh")
        return skin, arm
    if obj is not None and obj.type == 'ARMATURE' and rig_state(obj).skin is not None:
        return rig_state(obj).skin, obj
    return blender_io.resolve_skinned_mesh(obj)


def resolve_extracted(context):
    """(skin, armature, state) when muscles were extracted; ValueError otherwise."""
    skin, arm = resolve_rig(context.active_object)
    state = rig_state(arm)
    if len(state.muscles) == 0:
        raise ValueError(f"No muscles on '{arm.name}': run Extract Muscles first")
    return skin, arm, state


class _MuscleOperator:
    """Reports ValueError/RuntimeError from run() as UI errors; run() returns the INFO message."""
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        try:
            message = self.run(context)
        except (ValueError, RuntimeError, core_loader.CoreUnavailableError) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        if message:
            self.report({'INFO'}, message)
        return {'FINISHED'}


class MYOSKIN_OT_extract_muscles(_MuscleOperator, bpy.types.Operator):
    """Find the muscles that shape the active skin (replaces this character's muscles)"""
    bl_idname = "myoskin.extract_muscles"
    bl_label = "Extract Muscles"

    spacing: FloatProperty(name="Section Spacing", description="Distance between cutting planes "
                           "(0 = automatic: 1/80 of the character's extent)", default=-1.0, min=-1.0,
                           soft_max=0.2, subtype='DISTANCE', unit='LENGTH')
    min_confidence: FloatProperty(name="Min Confidence", description="Drop muscles less significant than this "
                                  "(-1 = preferences)", default=-1.0, min=-1.0, max=1.0)
    min_sections: IntProperty(name="Min Sections", description="Sections a muscle needs (-1 = preferences)",
                              default=-1, min=-1, soft_max=20)
    joint_wrap: FloatProperty(name="Joint Wrap", description="A muscle crossing a joint wraps round it on a "
                              "sphere of this times its thickness, so it bends with the skeleton (0 = straight)",
                              default=0.3, min=0.0, soft_max=1.0)
    limit: EnumProperty(name="Limit To", items=LIMITS, default='ALL')
    vertex_group: StringProperty(name="Vertex Group", description="With Limit To = Vertex Group")

    def run(self, context):
        prefs = get_preferences(context)
        skin, arm = resolve_rig(context.active_object)
        state = rig_state(arm)
        if state.bound:
            raise ValueError(f"'{arm.name}' is bound: Unbind before extracting again")
        require_weights(skin, arm)
        spacing = prefs.section_spacing if self.spacing < 0 else self.spacing
        min_sections = prefs.min_sections if self.min_sections < 0 else self.min_sections
        min_confidence = prefs.min_confidence if self.min_confidence < 0 else self.min_confidence
        wm = context.window_manager
        wm.progress_begin(0, 4)
        try:
            character, weld_map = blender_io.welded_character_from_blender(skin, arm)
            wm.progress_update(1)
            mask = None
            if self.limit == 'SELECTED':
                source = blender_io.selected_vertex_mask(skin)
                if not source.any():
                    raise ValueError(f"No vertices selected on '{skin.name}' (Limit To = Selected Vertices)")
                mask = blender_io.welded_mask(source, weld_map, character.num_vertices)
            elif self.limit == 'GROUP':
                source = blender_io.vertex_group_mask(skin, self.vertex_group)
                if not source.any():
                    raise ValueError(f"Vertex group '{self.vertex_group}' is empty")
                mask = blender_io.welded_mask(source, weld_map, character.num_vertices)
            muscles, report = core_loader.core().extract_muscles(
                character, spacing=spacing, vertex_mask=mask, min_confidence=min_confidence,
                min_sections=min_sections, joint_wrap=self.joint_wrap)
            wm.progress_update(2)
            for m in muscles:
                m.joints = prefs.joints_per_muscle
                m.bulge = prefs.bulge_factor
            muscle_io.set_muscles(arm, skin, muscles)
            wm.progress_update(3)
        finally:
            wm.progress_end()
        seconds = sum(report["timings"].values())
        message = (f"Extracted {len(muscles)} muscles from {skin.name} ({report['sections']} sections, "
                   f"{report['bumps']} bumps, {seconds:.2f} s)")
        if not muscles:
            message += ": no significant bumps (smooth skin?); lower Min Confidence or mark a region"
        return message


class MYOSKIN_OT_add_muscle_from_region(_MuscleOperator, bpy.types.Operator):
    """Force a muscle in a marked skin region: the selected faces, or a vertex group"""
    bl_idname = "myoskin.add_muscle_from_region"
    bl_label = "Add Muscle from Region"

    source: EnumProperty(name="Region", items=(
        ('FACES', "Selected Faces", "The faces selected on the skin"),
        ('GROUP', "Vertex Group", "The vertices of a vertex group")), default='FACES')
    vertex_group: StringProperty(name="Vertex Group")

    def run(self, context):
        skin, arm = resolve_rig(context.active_object)
        require_weights(skin, arm)
        state = rig_state(arm)
        if self.source == 'FACES':
            source = blender_io.selected_vertex_mask(skin, faces=True)
            if not source.any():
                raise ValueError(f"No faces selected on '{skin.name}': select the region in Edit Mode")
        else:
            source = blender_io.vertex_group_mask(skin, self.vertex_group)
            if not source.any():
                raise ValueError(f"Vertex group '{self.vertex_group}' is empty")
        character, weld_map = blender_io.welded_character_from_blender(skin, arm)
        region = blender_io.welded_mask(source, weld_map, character.num_vertices)
        prefs = get_preferences(context)
        # min_confidence 1: only the forced muscle survives (forced muscles are always kept).
        muscles, report = core_loader.core().extract_muscles(
            character, spacing=prefs.section_spacing, forced_regions=[region], min_confidence=1.0,
            min_sections=max(2, prefs.min_sections // 2))
        if not muscles:
            raise ValueError("No bump found in the marked region: mark a larger region across the muscle "
                             "(it needs several cutting planes)")
        vertices = np.asarray(character.vertices)[region]
        best = max(muscles, key=lambda m: int((np.linalg.norm(
            vertices[:, None, :] - np.asarray(m.section_centers)[None, :, :], axis=2).min(axis=1) < 0.05).sum()))
        best.joints, best.bulge = prefs.joints_per_muscle, prefs.bulge_factor
        if state.skin is None:
            state.skin = skin
        item = muscle_io.add_muscle(arm, best)
        state.active_index = len(state.muscles) - 1
        state.dirty = state.bound
        muscle_io.sync_text(arm)
        return f"Added muscle {item.name} ({best.num_sections} sections)"


class MYOSKIN_OT_remove_muscle(_MuscleOperator, bpy.types.Operator):
    """Delete the active muscle (its surface and locators too)"""
    bl_idname = "myoskin.remove_muscle"
    bl_label = "Remove Muscle"

    index: IntProperty(name="Index", description="Muscle to remove (-1 = the active one)", default=-1)

    def run(self, context):
        _skin, arm, state = resolve_extracted(context)
        index = state.active_index if self.index < 0 else self.index
        if not 0 <= index < len(state.muscles):
            raise ValueError(f"No muscle at index {index}")
        name = state.muscles[index].name
        muscle_io.remove_muscle(arm, index)
        state.dirty = state.bound
        muscle_io.sync_text(arm)
        return f"Removed {name}"


class MYOSKIN_OT_mirror_muscle(_MuscleOperator, bpy.types.Operator):
    """Copy the active muscle to the other side (X mirrored, .L/.R bone names flipped); replaces an
    existing muscle of the mirrored name"""
    bl_idname = "myoskin.mirror_muscle"
    bl_label = "Mirror Muscle"

    def run(self, context):
        _skin, arm, state = resolve_extracted(context)
        if not 0 <= state.active_index < len(state.muscles):
            raise ValueError("No active muscle")
        item = state.muscles[state.active_index]
        mirrored = muscle_io.mirrored_muscle(arm, item)
        mirrored.joints, mirrored.bulge = item.joints, item.bulge
        source, enabled = item.name, item.enabled  # read now: removing a mirror twin shifts the list under `item`
        existing, _ = muscle_io.find_item(arm, mirrored.name)
        if existing >= 0:
            muscle_io.remove_muscle(arm, existing)
        new = muscle_io.add_muscle(arm, mirrored)
        new.enabled = enabled
        state.active_index = len(state.muscles) - 1
        state.dirty = state.bound
        muscle_io.sync_text(arm)
        return f"Mirrored {source} to {new.name}"


class MYOSKIN_OT_select_muscle(_MuscleOperator, bpy.types.Operator):
    """Select the active muscle's surface (and make it the list's active item)"""
    bl_idname = "myoskin.select_muscle"
    bl_label = "Select Muscle"
    bl_options = {'REGISTER'}

    index: IntProperty(name="Index", default=-1)

    def run(self, context):
        _skin, _arm, state = resolve_extracted(context)
        index = state.active_index if self.index < 0 else self.index
        if not 0 <= index < len(state.muscles):
            raise ValueError(f"No muscle at index {index}")
        state.active_index = index
        surface = state.muscles[index].surface
        if surface is None or surface.name not in context.view_layer.objects:
            raise ValueError(f"Muscle '{state.muscles[index].name}' has no surface object (deleted?): "
                             f"use Refresh Muscles to rebuild it")
        surface.select_set(True)
        return ""


class MYOSKIN_OT_refresh_muscles(_MuscleOperator, bpy.types.Operator):
    """Rebuild every muscle from its locators and settings (recreates deleted surfaces and locators)"""
    bl_idname = "myoskin.refresh_muscles"
    bl_label = "Refresh Muscles"

    def run(self, context):
        _skin, arm, state = resolve_extracted(context)
        for item in state.muscles:
            for end in muscle_io.LOCATOR_ENDS:
                locator = getattr(item, end + "_locator")
                if locator is None or locator.name not in bpy.data.objects:
                    stored = muscle_io.data_to_muscle(item.data, item.name)
                    muscle_io.make_locator(arm, item, end, getattr(stored, end))
            muscle_io.refresh_muscle(arm, item)
            muscle_io.update_wrap_display(arm, item)
        muscle_io.sync_text(arm)
        return f"Refreshed {len(state.muscles)} muscles"


class MYOSKIN_OT_snap_locator(_MuscleOperator, bpy.types.Operator):
    """Move the active muscle's origin or insertion onto the nearest bone and attach it there"""
    bl_idname = "myoskin.snap_locator"
    bl_label = "Snap to Nearest Bone"

    end: EnumProperty(name="End", items=(('origin', "Origin", ""), ('insertion', "Insertion", "")))

    def run(self, context):
        _skin, arm, state = resolve_extracted(context)
        item = state.muscles[state.active_index]
        locator = getattr(item, self.end + "_locator")
        if locator is None:
            raise ValueError(f"Muscle '{item.name}' has no {self.end} locator: use Refresh Muscles")
        bone, point = muscle_io.nearest_bone(arm, muscle_io.locator_rest_position(locator))
        item[self.end + "_bone"] = bone
        muscle_io.attach_locator(arm, locator, bone, point)
        muscle_io.refresh_muscle(arm, item)
        state.dirty = state.bound
        muscle_io.sync_text(arm)
        return f"{item.name}: {self.end} on {bone}"


classes = (MYOSKIN_OT_extract_muscles, MYOSKIN_OT_add_muscle_from_region, MYOSKIN_OT_remove_muscle,
           MYOSKIN_OT_mirror_muscle, MYOSKIN_OT_select_muscle, MYOSKIN_OT_refresh_muscles,
           MYOSKIN_OT_snap_locator)
