# SPDX-License-Identifier: GPL-3.0-or-later
"""Muscle operators: extract, add from a marked region, remove, mirror, select, refresh, snap locators.
Small: convert data (blender_io, muscle_io), call the core, report."""
import json
import traceback

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from .. import blender_io, core_loader, muscle_io
from ..preferences import get_preferences
from ..state import (LIMITS, clear_role_overrides, missing_role_bones, rig_skins, rig_state, role_overrides,
                     set_detected_roles, set_rig_skins)

# The last Extract per armature name: {"muscles", "diagnosis", "analysed", "left_out" (lines naming the skin
# components left out of the analysis), "scale_note" (the body is far from the reference size), "message"} (batch
# prints it; the operator's report says the same).
last_extraction = {}


def _muscle_object_armature(obj):
    """The armature of a muscle object (surface, locator), else None."""
    if obj is not None and obj.get("myoskin_muscle") is not None and obj.parent is not None \
            and obj.parent.type == 'ARMATURE':
        return obj.parent
    return None


def resolve_rig(obj):
    """(skin meshes, armature) for the active object (the skin, its armature, or one of the muscle objects):
    the meshes the armature's muscles were extracted from when it has muscles, else the character of the
    active object (blender_io.resolve_character). ValueError with a message for the user otherwise."""
    arm = _muscle_object_armature(obj)
    if arm is not None:
        skins = rig_skins(arm)
        if not skins:
            raise ValueError(f"Armature '{arm.name}' has no skin recorded: select the skinned mesh")
        return skins, arm
    arm = obj if obj is not None and obj.type == 'ARMATURE' else blender_io.find_armature(obj)
    if arm is not None and arm.type == 'ARMATURE' and rig_skins(arm):
        return rig_skins(arm), arm
    meshes, arm, _skipped = blender_io.resolve_character(obj)
    return meshes, arm


def resolve_extracted(context):
    """(skin meshes, armature, state) when muscles were extracted; ValueError otherwise."""
    skins, arm = resolve_rig(context.active_object)
    state = rig_state(arm)
    if len(state.muscles) == 0:
        raise ValueError(f"No muscles on '{arm.name}': run Extract Muscles first")
    return skins, arm, state


def character_label(skins, arm):
    """How a report names the character: the mesh, or the armature and its meshes."""
    if len(skins) == 1:
        return skins[0].name
    return f"{arm.name} ({len(skins)} meshes: {', '.join(o.name for o in skins)})"


def selection_masks(skins, faces=False):
    """Per mesh, its selected vertices (or vertices of selected faces): the meshes in Edit Mode when any
    is, else every mesh's stored selection."""
    editing = [o for o in skins if o.mode == 'EDIT']
    return [blender_io.selected_vertex_mask(o, faces=faces) if not editing or o in editing else None
            for o in skins]


def group_masks(skins, group_name):
    """Per mesh, the vertices of its vertex group `group_name` (None where it has none); ValueError when no
    mesh has the group."""
    masks = [blender_io.vertex_group_mask(o, group_name) if group_name in o.vertex_groups else None
             for o in skins]
    if all(m is None for m in masks):
        raise ValueError(f"{'Mesh' if len(skins) == 1 else 'Meshes'} {', '.join(repr(o.name) for o in skins)}: "
                         f"no vertex group '{group_name}'")
    return masks


def extraction_input(obj):
    """(skin meshes, armature, skipped meshes) Extract uses for the active object: a muscle object's rig, a
    mesh alone, or the armature with every mesh it deforms."""
    if _muscle_object_armature(obj) is not None:
        skins, arm = resolve_rig(obj)
        return skins, arm, []
    return blender_io.resolve_character(obj)


def extraction_character(skins, arm):
    """(CombinedCharacter, scale, core Character in the extraction space: armature space times its scale)."""
    combined = blender_io.combined_character(skins, arm)
    scale = blender_io.armature_scale(arm)
    return combined, scale, blender_io.scaled_character(combined.character, scale)


def checked_role_overrides(arm):
    """The armature's bone role overrides ({bone: role}); ValueError naming bones that are gone."""
    missing = missing_role_bones(arm)
    if missing:
        raise ValueError(f"Bone role overrides name {'a bone' if len(missing) == 1 else 'bones'} '{arm.name}' no "
                         f"longer has: {', '.join(repr(b) for b in missing)} (renamed or deleted?): Detect in "
                         f"Bone Roles drops {'it' if len(missing) == 1 else 'them'}, Reset clears every override")
    return role_overrides(arm)


def left_out_lines(combined, excluded):
    """Lines naming the skin components the core left out of the analysis, per mesh and reason, e.g.
    "18 rigid parts of 'Soldier_Head' (bound to 'Head')" (first_vertex mapped back through the weld map)."""
    if not excluded:
        return []
    meshes = combined.source_meshes([e["first_vertex"] for e in excluded])
    groups = {}
    for e, mesh in zip(excluded, meshes):
        g = groups.setdefault((mesh.name, e["reason"]), {"parts": 0, "vertices": 0, "bones": []})
        g["parts"] += 1
        g["vertices"] += int(e["vertices"])
        if e["bone"] and e["bone"] not in g["bones"]:
            g["bones"].append(e["bone"])
    lines = []
    for (mesh, reason), g in groups.items():
        line = f"{g['parts']} {reason} part{'s' if g['parts'] != 1 else ''} of '{mesh}'"
        if g["bones"]:
            line += f" (bound to {', '.join(repr(b) for b in g['bones'][:4])}{' ...' if len(g['bones']) > 4 else ''})"
        else:
            line += f" ({g['vertices']} vertices)"
        lines.append(line)
    return lines


class _MuscleOperator:
    """Reports ValueError/RuntimeError from run() as UI errors; run() returns the INFO message, or
    (level, message) for another level ('WARNING'). Any other exception is a bug: it is reported too (with
    its type, and its traceback printed to the console), never raised into Blender. Operators that change the
    character (`edits_character`) refuse a character linked from a library (read-only) first."""
    bl_options = {'REGISTER', 'UNDO'}
    edits_character = True

    def execute(self, context):
        try:
            if self.edits_character:
                blender_io.require_editable(context.active_object)
            message = self.run(context)
        except (ValueError, RuntimeError, core_loader.CoreUnavailableError) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001  (a bug: say so in the UI instead of a traceback)
            traceback.print_exc()
            self.report({'ERROR'}, f"{self.bl_label} failed unexpectedly ({type(e).__name__}: {e}); nothing more "
                                   f"was done. Please report this with the console output")
            return {'CANCELLED'}
        level = 'INFO'
        if isinstance(message, tuple):
            level, message = message
        if message:
            self.report({level}, message)
        return {'FINISHED'}


def expert_options(text):
    """The Extract operator's expert options: a JSON object {key: value} (empty = none)."""
    if not text.strip():
        return None
    try:
        options = json.loads(text)
    except ValueError as e:
        raise ValueError(f"Expert Options are not valid JSON ({e})") from None
    if not isinstance(options, dict):
        raise ValueError("Expert Options must be a JSON object {\"key\": value}")
    return options


class MYOSKIN_OT_extract_muscles(_MuscleOperator, bpy.types.Operator):
    """Find the muscles that shape the active skin (replaces this character's muscles)"""
    bl_idname = "myoskin.extract_muscles"
    bl_label = "Extract Muscles"

    spacing: FloatProperty(name="Section Spacing", description="Distance between cutting planes in limb radii "
                           "(the body's median limb radius; 0 = automatic: 1/80 of the character's extent; "
                           "-1 = preferences)", default=-1.0, min=-1.0, soft_max=4.0)
    min_confidence: FloatProperty(name="Min Confidence", description="Drop muscles less significant than this "
                                  "(-1 = preferences)", default=-1.0, min=-1.0, max=1.0)
    min_sections: IntProperty(name="Min Sections", description="Sections a muscle needs (-1 = preferences)",
                              default=-1, min=-1, soft_max=20)
    joint_wrap: FloatProperty(name="Joint Wrap", description="A muscle crossing a joint wraps round it on a "
                              "sphere of this times its thickness, so it bends with the skeleton (0 = straight)",
                              default=0.3, min=0.0, soft_max=1.0)
    max_per_region: IntProperty(name="Max per Region", description="Keep at most this many muscles (the most "
                                "confident) per region (0 = all)", default=0, min=0, soft_max=10)
    limit: EnumProperty(name="Limit To", items=LIMITS, default='ALL')
    vertex_group: StringProperty(name="Vertex Group", description="With Limit To = Vertex Group")
    expert: StringProperty(name="Expert Options", description="Expert tuning, not for everyday use: a JSON object "
                           "{key: value} of the core's extraction options (e.g. {\"filters.minEvidence\": 7}; "
                           "the keys: Python _core.extraction_options())", default="",
                           options={'SKIP_SAVE'})  # never reused from the last call: tuning is asked for each time

    def run(self, context):
        prefs = get_preferences(context)
        skins, arm, skipped = extraction_input(context.active_object)
        state = rig_state(arm)
        if state.bound:
            raise ValueError(f"'{arm.name}' is bound: Unbind before extracting again")
        for skin in skins:
            blender_io.require_weights(skin, arm)
        overrides = checked_role_overrides(arm)
        spacing = prefs.section_spacing_radii if self.spacing < 0 else self.spacing
        min_sections = prefs.min_sections if self.min_sections < 0 else self.min_sections
        min_confidence = prefs.min_confidence if self.min_confidence < 0 else self.min_confidence
        label = character_label(skins, arm)
        wm = context.window_manager
        wm.progress_begin(0, 4)
        try:
            combined, scale, character = extraction_character(skins, arm)
            wm.progress_update(1)
            mask = None
            if self.limit == 'SELECTED':
                mask = combined.mask(selection_masks(skins))
                if not mask.any():
                    raise ValueError(f"No vertices selected on {label} (Limit To = Selected Vertices)")
            elif self.limit == 'GROUP':
                mask = combined.mask(group_masks(skins, self.vertex_group))
                if not mask.any():
                    raise ValueError(f"Vertex group '{self.vertex_group}' is empty")
            core = core_loader.core()
            muscles, report = core.extract_muscles(
                character, spacing=spacing, min_confidence=min_confidence, min_sections=min_sections,
                max_per_region=self.max_per_region, joint_wrap=self.joint_wrap, vertex_mask=mask,
                bone_roles=overrides, options=expert_options(self.expert))
            left_out = left_out_lines(combined, report.get("excluded", []))
            last_extraction[arm.name] = {"muscles": len(muscles), "analysed": report["analysed"],
                                         "diagnosis": report["diagnosis"], "left_out": left_out,
                                         "scale_note": report.get("scale_note", "")}
            if not report["analysed"]:  # nothing changed in the file: say why
                hint = ""
                if report["diagnosis"].startswith("no limb chain"):
                    hint = ("; Reset in Extract > Bone Roles clears your overrides" if overrides else
                            "; give bones a role in Extract > Bone Roles (Detect lists them)")
                message = f"Nothing could be analysed: {report['diagnosis']} ({label}{hint})"
                last_extraction[arm.name]["message"] = message
                raise ValueError(message)
            wm.progress_update(2)
            muscles = muscle_io.scale_muscles(muscles, 1.0 / scale)  # back to the armature's space
            for m in muscles:
                m.joints = prefs.joints_per_muscle
                m.bulge = prefs.bulge_factor
            muscle_io.set_muscles(arm, skins, muscles)
            set_detected_roles(arm, core.bone_roles(character))  # the panel's list (overrides kept)
            wm.progress_update(3)
        finally:
            wm.progress_end()
        seconds = sum(report["timings"].values())
        counts = f"({report['sections']} sections, {report['bumps']} bumps, {seconds:.2f} s)"
        if muscles:
            message = f"Extracted {len(muscles)} muscles from {label} {counts}"
        else:
            message = (f"Found no muscles on {label}: {report['diagnosis'] or 'no significant relief'} {counts}; "
                       f"lower Min Confidence, mark a region or set bone roles")
        if overrides:
            message += f"; {len(overrides)} bone role override{'s' if len(overrides) != 1 else ''}"
        if left_out:
            message += "; left out " + "; ".join(left_out)
        message += blender_io.skipped_message(skipped)
        note = last_extraction[arm.name]["scale_note"]
        if note:  # the body is far from the size the defaults are stated for
            message += f"; note: {note}"
        last_extraction[arm.name]["message"] = message
        return ('INFO' if muscles and not note else 'WARNING'), message


class MYOSKIN_OT_detect_bone_roles(_MuscleOperator, bpy.types.Operator):
    """Find each bone's role (limb, shoulder, spine, neck, pelvis, ignore) from the bone tree and the skin, as
    Extract will; your overrides of bones still there are kept"""
    bl_idname = "myoskin.detect_bone_roles"
    bl_label = "Detect"

    def run(self, context):
        skins, arm, _skipped = extraction_input(context.active_object)
        for skin in skins:
            blender_io.require_weights(skin, arm)
        _combined, _scale, character = extraction_character(skins, arm)
        detected = core_loader.core().bone_roles(character)
        dropped = set_detected_roles(arm, detected)
        overrides = role_overrides(arm)
        active = sum(1 for r in detected.values() if r != 'ignore')
        message = (f"Bone roles of '{arm.name}': {active} of {len(detected)} bones have a role"
                   f"{f', {len(overrides)} overridden' if overrides else ''}")
        if dropped:
            message += (f"; dropped the overrides of {', '.join(repr(b) for b in sorted(dropped))} (no such bone "
                        f"any more)")
            return 'WARNING', message
        return message


class MYOSKIN_OT_reset_bone_roles(_MuscleOperator, bpy.types.Operator):
    """Clear every bone role override: each bone gets its detected role again"""
    bl_idname = "myoskin.reset_bone_roles"
    bl_label = "Reset"

    def run(self, context):
        arm = blender_io.find_armature(context.active_object)  # a muscle object's parent is its armature
        if arm is None:
            raise ValueError("Select a skinned mesh or its armature")
        cleared = clear_role_overrides(arm)
        return f"Cleared {cleared} bone role override{'s' if cleared != 1 else ''} of '{arm.name}'"


class MYOSKIN_OT_add_muscle_from_region(_MuscleOperator, bpy.types.Operator):
    """Force a muscle in a marked skin region: the selected faces, or a vertex group"""
    bl_idname = "myoskin.add_muscle_from_region"
    bl_label = "Add Muscle from Region"

    source: EnumProperty(name="Region", items=(
        ('FACES', "Selected Faces", "The faces selected on the skin"),
        ('GROUP', "Vertex Group", "The vertices of a vertex group")), default='FACES')
    vertex_group: StringProperty(name="Vertex Group")

    def run(self, context):
        skins, arm = resolve_rig(context.active_object)
        for skin in skins:
            blender_io.require_weights(skin, arm)
        state = rig_state(arm)
        combined = blender_io.combined_character(skins, arm)
        if self.source == 'FACES':
            region = combined.mask(selection_masks(skins, faces=True))
            if not region.any():
                raise ValueError(f"No faces selected on {character_label(skins, arm)}: select the region in "
                                 f"Edit Mode")
        else:
            region = combined.mask(group_masks(skins, self.vertex_group))
            if not region.any():
                raise ValueError(f"Vertex group '{self.vertex_group}' is empty")
        scale = blender_io.armature_scale(arm)
        character = blender_io.scaled_character(combined.character, scale)  # the extraction space
        prefs = get_preferences(context)
        # Only the forced muscle survives: min_confidence 1 drops the others, and the cues that keep a chain below
        # the floors without its confidence (closed spindles, mirror twins) are off.
        muscles, report = core_loader.core().extract_muscles(
            character, spacing=prefs.section_spacing_radii, forced_regions=[region], min_confidence=1.0,
            min_sections=max(2, prefs.min_sections // 2), bone_roles=checked_role_overrides(arm),
            options={"filters.spindleEnds": 0.0, "filters.twinReach": 0.0})
        if not muscles or report["forced"] < 1:
            raise ValueError("No bump found in the marked region: mark a larger region across the muscle "
                             "(it needs several cutting planes)")
        vertices = np.asarray(character.vertices)[region]

        def overlap(m):
            """Region vertices within its sections' radius of the muscle's centre line (closest section)."""
            centres = np.asarray(m.section_centers)
            reach = 2.0 * np.sqrt(np.asarray(m.section_a) * np.asarray(m.section_b))  # per section
            d = np.linalg.norm(vertices[:, None, :] - centres[None, :, :], axis=2)
            nearest = d.argmin(axis=1)
            return int((d[np.arange(len(vertices)), nearest] < reach[nearest]).sum())
        best = max(muscles, key=overlap)
        best = muscle_io.scale_muscles([best], 1.0 / scale)[0]
        best.joints, best.bulge = prefs.joints_per_muscle, prefs.bulge_factor
        if not rig_skins(arm):
            set_rig_skins(arm, skins)
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
    edits_character = False

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


classes = (MYOSKIN_OT_extract_muscles, MYOSKIN_OT_detect_bone_roles, MYOSKIN_OT_reset_bone_roles,
           MYOSKIN_OT_add_muscle_from_region, MYOSKIN_OT_remove_muscle,
           MYOSKIN_OT_mirror_muscle, MYOSKIN_OT_select_muscle, MYOSKIN_OT_refresh_muscles,
           MYOSKIN_OT_snap_locator)
