# SPDX-License-Identifier: GPL-3.0-or-later
"""The rig service: Bind / Unbind the muscles to the character's armature (muscle joints as deform bones,
combined weights, the Armature modifier), the skin's weight backup and the bind record
"<armature>.bind.json" that live update rebuilds from. No handler work here: bind() and unbind() drop the
runtime's cached rig, and after bind() the caller poses the new joints (live.update_armature).
Imports downward only: state, blender_io, rig_io, muscle_io, core_loader, runtime, volume_keys."""
import hashlib
import json

import bpy
import numpy as np

from . import blender_io, core_loader, core_skin, muscle_io, rig_io, runtime, volume_keys
from .state import rig_skins, rig_state, set_rig_skins

# ------------------------------------------------------------------------------------------------
# Bind record and weight backup (Text datablocks, so they live in the .blend)
# ------------------------------------------------------------------------------------------------


BACKUP_KEY = "myoskin_original_weights"
ADDED_KEY = "myoskin_added_groups"  # ID property on a bound mesh: the skeleton bones' groups Bind created


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


def note_added_groups(skin, bone_names):
    """Remember which of the skeleton's bones had no vertex group on the skin before Bind (Bind writes one
    per bone; Unbind removes those again, so the mesh gets back exactly the groups it had)."""
    skin[ADDED_KEY] = [n for n in bone_names if n not in skin.vertex_groups]


def check_backup(skin):
    """ValueError when the skin's weight backup (an ID property a user can edit) is not what backup_weights
    wrote: {group name: {"index": int, "vertices": [int in range], "weights": [number], same lengths}}."""
    backup = skin.get(BACKUP_KEY)
    if backup is None:
        return
    count = len(skin.data.vertices)
    problem = ""
    if not hasattr(backup, "items"):
        problem = "not a mapping"
    else:
        for name, entry in backup.items():
            try:
                index = int(entry["index"])
                ids = np.asarray(entry["vertices"], dtype=np.float64).ravel()
                ws = np.asarray(entry["weights"], dtype=np.float64).ravel()
            except (KeyError, TypeError, ValueError, IndexError):
                problem = f"group '{name}' is not {{index, vertices, weights}}"
                break
            if index < 0 or len(ids) != len(ws) or (len(ids) and (ids.min() < 0 or ids.max() >= count
                                                                    or np.any(ids != np.round(ids)))) \
                    or not np.all(np.isfinite(ws)):
                problem = (f"group '{name}' names vertices outside the mesh, or weights that are not numbers or "
                           f"not one per vertex")
                break
    if problem:
        raise ValueError(f"The weight backup of '{skin.name}' (its '{BACKUP_KEY}' property) is damaged: {problem} "
                         f"(edited by hand?); nothing was changed")


def restore_weights(skin):
    """Give every backed-up group exactly its backed-up members (groups keep their index; a group renamed
    since, e.g. with its bone, is found by index; missing ones are recreated; groups added since the backup
    are left alone), then drop the backup."""
    backup = skin.get(BACKUP_KEY)
    if backup is None:
        return False
    everyone = list(range(len(skin.data.vertices)))
    names = set(backup.keys())
    added = skin.get(ADDED_KEY)
    if added is not None:  # the groups Bind created for bones that had none (a damaged list: none removed)
        added = [n for n in added if isinstance(n, str)] if not isinstance(added, str) else []
        for n in added:
            group = skin.vertex_groups.get(n)
            if group is not None and n not in names:
                skin.vertex_groups.remove(group)
        del skin[ADDED_KEY]
    for name, entry in sorted(backup.items(), key=lambda kv: kv[1]["index"]):
        group = skin.vertex_groups.get(name)
        if group is None:  # renamed with its bone since the bind (a group keeps its index): restore into it
            index = int(entry["index"])
            if index < len(skin.vertex_groups) and skin.vertex_groups[index].name not in names:
                group = skin.vertex_groups[index]
            else:
                group = skin.vertex_groups.new(name=name)
        group.remove(everyone)
        blender_io.add_group_weights(group, entry["vertices"], entry["weights"])
    del skin[BACKUP_KEY]
    return True


def hybrid_weights(core, character, rig, max_influences=8):
    """(#V by K joints over combined joints, #V by K weights) for the skin, K = max_influences."""
    result = core.hybrid_weights(character, rig, max_influences=max_influences)
    return np.asarray(result[0]), np.asarray(result[1])


# ------------------------------------------------------------------------------------------------
# Volume blend: a second Armature modifier (Preserve Volume, Multi Modifier) mixed over a vertex group
# ------------------------------------------------------------------------------------------------

VOLUME_BLEND_GROUP = "myoskin_dqs_share"      # vertex group: the dual-quaternion share s (3.x: 1 - s)
VOLUME_BLEND_MODIFIER = "Myoskin Volume Blend"  # the second Armature modifier Bind adds
LINEAR_GROUP = "myoskin_linear"               # vertex group of the first modifier: the vertices with s < 1
MIX_GROUPS = (VOLUME_BLEND_GROUP, LINEAR_GROUP)  # the volume blend's vertex groups: no bone, no influence


def is_volume_blend_modifier(mod):
    """Whether `mod` is the volume blend's second Armature modifier (Multi Modifier over the share group)."""
    return mod.type == 'ARMATURE' and bool(mod.use_multi_modifier) and mod.vertex_group == VOLUME_BLEND_GROUP


def armature_modifier(skin, arm):
    """The mesh's (first) Armature modifier of `arm`, not the volume blend's second one."""
    for mod in skin.modifiers:
        if mod.type == 'ARMATURE' and mod.object == arm and not is_volume_blend_modifier(mod):
            return mod
    return None


def volume_blend_modifier(skin, arm):
    """The volume blend's second Armature modifier of `arm` on the mesh, or None."""
    for mod in skin.modifiers:
        if is_volume_blend_modifier(mod) and mod.object == arm:
            return mod
    return None


def armature_modifiers(skin, arm):
    """The mesh's Armature modifiers of `arm` that skin it: the first, and the volume blend's second if any."""
    return [m for m in (armature_modifier(skin, arm), volume_blend_modifier(skin, arm)) if m is not None]


def _move_modifier(skin, mod, index):
    """Put `mod` at `index` in the stack (ObjectModifiers.move where this Blender has it, else the operator)."""
    current = list(skin.modifiers).index(mod)
    if current == index:
        return
    if hasattr(skin.modifiers, "move"):
        skin.modifiers.move(current, index)
        return
    with bpy.context.temp_override(object=skin, active_object=skin):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=index)


def _group_weight_is_linear_share():
    """Whether this Blender's Multi Modifier takes the group's weight as the PREVIOUS modifier's share (3.x: measured on
    3.4.1) or as its own (4.x, 5.x: measured on 4.3, 4.5 and 5.2; the switch is placed at 4.0)."""
    return bpy.app.version < (4, 0, 0)


SHARE_CONVENTION_KEY = "myoskin_share_convention"  # ID property on a mesh: how its share group's weights read


def _share_convention():
    """How this Blender's Multi Modifier reads the share group: "previous" (3.x: the linear result's share) or
    "own" (4.x, 5.x: the second modifier's share)."""
    return "previous" if _group_weight_is_linear_share() else "own"


def write_share_group(skin, share):
    """The share group on the mesh from #V dual-quaternion shares s. Blender 3.x's Multi Modifier takes the group's
    weight as the PREVIOUS (linear) modifier's share (weight 0, or a vertex not in the group, gives the second
    modifier's dual quaternions), so each vertex with s < 1 gets weight 1 - s and the others stay out; 4.x and 5.x
    take it as the second modifier's own share, so each vertex with s > 0 gets weight s (float32 in Blender).
    Also writes the linear group (weight 1 on the vertices with s < 1): the first modifier deforms only those, since
    the second one's dual quaternions replace the others whole (the mix takes 0 of the previous result; same result to
    the bit). With the shares 0 away from the joints (unblended_share) 4.x and 5.x then skin most vertices once."""
    group = skin.vertex_groups.get(VOLUME_BLEND_GROUP) or skin.vertex_groups.new(name=VOLUME_BLEND_GROUP)
    group.remove(list(range(len(skin.data.vertices))))
    share = np.asarray(share, dtype=np.float64)
    if _group_weight_is_linear_share():
        ids = np.flatnonzero(share < 1.0)
        values = 1.0 - share[ids]
    else:
        ids = np.flatnonzero(share > 0.0)
        values = share[ids]
    blender_io.add_group_weights(group, ids, values)
    skin[SHARE_CONVENTION_KEY] = _share_convention()
    linear = skin.vertex_groups.get(LINEAR_GROUP) or skin.vertex_groups.new(name=LINEAR_GROUP)
    linear.remove(list(range(len(skin.data.vertices))))
    needed = np.flatnonzero(share < 1.0)
    blender_io.add_group_weights(linear, needed, np.ones(len(needed)))
    return group


def read_share_group(skin):
    """#V float64 dual-quaternion shares s as this Blender mixes them from the group (write_share_group), or None
    without the group."""
    if skin.vertex_groups.get(VOLUME_BLEND_GROUP) is None:
        return None
    weight = blender_io.vertex_group_weights(skin, VOLUME_BLEND_GROUP)
    return 1.0 - weight if skin.get(SHARE_CONVENTION_KEY, _share_convention()) == "previous" else weight


def ensure_share_convention(skin):
    """A share group written by a Blender that reads it the other way (a .blend bound in 3.x opened in 4.x or the
    reverse) is rewritten for this one, so the volume blend mixes the same shares; True when it was."""
    written = skin.get(SHARE_CONVENTION_KEY)
    if skin.vertex_groups.get(VOLUME_BLEND_GROUP) is None or written in (None, _share_convention()):
        return False
    write_share_group(skin, read_share_group(skin))
    if not any(is_volume_blend_modifier(m) for m in skin.modifiers):  # switched off: no linear group to keep
        skin.vertex_groups.remove(skin.vertex_groups[LINEAR_GROUP])
    return True


def unblended_share(skins, arm):
    """The share of the skin no joint blends across (compute_dqs_share's unblended_share): 0 (linear, one Armature
    modifier there) where Blender's second modifier skips the vertices with s = 0, i.e. 4.x and 5.x (3.x evaluates every
    vertex in a Multi Modifier, measured in its armature_deform), and where the first modifier can be limited to the
    vertices with s < 1 (no vertex group of the artist's own: the core ignores such a mask, so the skin it leaves
    to the first modifier stays small); else 1 (dual quaternions there: the same skin, within 0.1 point of band
    volume on every benchmarked joint)."""
    if bpy.app.version < (4, 0, 0):
        return 1.0
    for skin in skins:
        first = armature_modifier(skin, arm)
        if first is not None and first.vertex_group not in ("", LINEAR_GROUP):
            return 1.0
    return 0.0


def add_volume_blend(skin, arm, share):
    """Volume blend on a bound mesh: the first Armature modifier linear (over the linear group when the artist gave it
    no vertex group of its own), then right after it a second one on the same armature with Preserve Volume and Multi
    Modifier over the share group (write_share_group), which Blender mixes as (1 - s) * linear + s * dual quaternions
    per vertex. Returns the second modifier."""
    first = armature_modifier(skin, arm)
    write_share_group(skin, share)
    mod = volume_blend_modifier(skin, arm)
    if mod is None:
        mod = skin.modifiers.new(VOLUME_BLEND_MODIFIER, 'ARMATURE')
    mod.object = arm
    mod.use_vertex_groups, mod.use_bone_envelopes = True, False
    mod.use_deform_preserve_volume = True
    mod.use_multi_modifier = True
    mod.vertex_group = VOLUME_BLEND_GROUP
    mod.invert_vertex_group = False
    mod.show_viewport, mod.show_render = bool(first.show_viewport), bool(first.show_render)
    first.use_deform_preserve_volume = False
    if first.vertex_group == LINEAR_GROUP or (first.vertex_group == "" and not first.invert_vertex_group):
        first.vertex_group = LINEAR_GROUP
    _move_modifier(skin, mod, list(skin.modifiers).index(first) + 1)
    return mod


def add_volume_keys(core, character, combined, skins, arm, share, rig, joints, weights):
    """The volume keys of the combined character (compute_volume_keys on Bind's skin: its shares, the muscle rig and
    its hybrid weights, this Blender's dual-quaternion scale) as driven shape keys on each mesh they reach (volume_keys.add_key; one key's #V by 3 offsets in
    memory at a time). Returns the number of shape keys added."""
    keys = core.compute_volume_keys(character, share, rig=rig, weight_joints=joints, weight_values=weights,
                                    dq_scale=dq_scale())
    entries = {skin.name: [] for skin in skins}
    counts = {}
    for key in keys:
        counts[key["bone"]] = counts.get(key["bone"], 0) + 1
    seen = {}
    for key in keys:
        seen[key["bone"]] = seen.get(key["bone"], 0) + 1
        name = volume_keys.key_name(key["bone"], counts[key["bone"]] > 1, seen[key["bone"]])
        full = np.zeros((character.num_vertices, 3))
        full[np.asarray(key["vertices"], dtype=np.int64)] = np.asarray(key["offsets"])
        for skin, moves in zip(skins, combined.split(full)):
            entry = volume_keys.add_key(skin, arm, key, name, moves)
            if entry is not None:
                entries[skin.name].append(entry)
    for skin in skins:
        volume_keys.set_stored(skin, entries[skin.name])
    return sum(len(e) for e in entries.values())


def _switch_volume_blend_off(skin, arm):
    """Remove the volume blend's second modifier and linear group and give the first modifier its whole skin back
    (the share group and the volume keys stay, muted)."""
    volume_keys.set_muted(skin, True)
    mod = volume_blend_modifier(skin, arm)
    if mod is not None:
        skin.modifiers.remove(mod)
    first = armature_modifier(skin, arm)
    if first is not None and first.vertex_group == LINEAR_GROUP:
        first.vertex_group = ""
    group = skin.vertex_groups.get(LINEAR_GROUP)
    if group is not None:
        skin.vertex_groups.remove(group)


def remove_volume_blend(skin, arm):
    """Unbind: remove the volume blend's modifier, share group and linear group, and give the first modifier its
    whole skin back (its Preserve Volume is restored by the caller from the bind record)."""
    _switch_volume_blend_off(skin, arm)
    volume_keys.remove(skin)
    group = skin.vertex_groups.get(VOLUME_BLEND_GROUP)
    if group is not None:
        skin.vertex_groups.remove(group)
    if SHARE_CONVENTION_KEY in skin:
        del skin[SHARE_CONVENTION_KEY]


def bind(context, skins, arm):
    """Create the muscle joints as deform bones, write the combined weights to every mesh of the character
    (`skins`: computed once on the meshes welded into one surface, then split back per mesh, so vertices
    where pieces meet get the same weights), keep/add the Armature modifier of each (and, with the rig's Volume
    Blend, the share group and the second modifier: add_volume_blend), write the bind record.
    Returns the number of joints; the caller then poses them (live.update_armature(arm, force=True))."""
    core = core_loader.core()
    state = rig_state(arm)
    skins = list(skins)
    if not skins:
        raise ValueError(f"No mesh to bind '{arm.name}' to: select the skinned mesh or the armature")
    for skin in skins:
        blender_io.require_weights(skin, arm)
    if arm.name not in context.view_layer.objects:
        raise ValueError(f"Armature '{arm.name}' is not in the view layer: link it to bind")
    combined = blender_io.combined_character(skins, arm)
    character = combined.character
    # Re-lofted and kept inside the skin at rest, as extraction keeps them (the hybrid weights use these surfaces).
    muscles = [core.reattach_muscle(m, character=character) for m in muscle_io.state_to_core(arm)]
    if not muscles:
        raise ValueError(f"Every muscle of '{arm.name}' is disabled: enable at least one to bind")
    rig = core.MuscleRig(character, muscles, joints_slide=bool(state.joints_slide))
    stuffing = core_skin.stuffing_of(arm) if state.deformer == 'ANCHORED' else []
    if stuffing:  # the core's own checks of the artist's ellipsoids, before anything changes
        core.AnchoredSkin(character, muscles, stuffing=stuffing)
    joints, weights = hybrid_weights(core, character, rig, state.max_influences)
    if joints.shape[0] != character.num_vertices or weights.shape[0] != character.num_vertices:
        raise ValueError(f"Bind: {joints.shape[0]} weight rows for the {character.num_vertices} vertices of "
                         f"'{arm.name}''s character")
    if rig.joints_slide:  # each joint slides along its bone no further than the skin it carries follows unfolded
        rig = core.MuscleRig(character, muscles, joints_slide=True,
                             slide_limits=np.asarray(core.slide_limits(character, rig, joints, weights)).tolist())
    # Volume blend: the shares from the skeleton weights of the combined character (before anything changes)
    volume_blend = bool(state.volume_blend) and state.deformer != 'ANCHORED'
    share = (np.asarray(core.compute_dqs_share(character, unblended_share=unblended_share(skins, arm)),
                        dtype=np.float64) if volume_blend else None)
    names = list(character.bone_names)
    for skin in skins:
        backup_weights(skin)
        note_added_groups(skin, names)
    try:
        rig_io.create_rig_bones(arm, rig, names)
        for skin, mesh_joints, mesh_weights in zip(skins, combined.split(joints), combined.split(weights)):
            rig_io.write_combined_weights(skin, names + list(rig.joint_names), mesh_joints, mesh_weights)
    except Exception:  # leave the rig as it was: no joint bones, the original weights
        rig_io.remove_muscle_bones(arm)
        for skin in skins:
            restore_weights(skin)
        raise
    added, preserve_volume_before = [], {}
    for skin in skins:
        mod = armature_modifier(skin, arm)
        if mod is None:
            mod = skin.modifiers.new("Armature", 'ARMATURE')
            mod.object = arm
            mod.use_vertex_groups, mod.use_bone_envelopes = True, False
            added.append(skin.name)
        else:
            preserve_volume_before[skin.name] = bool(mod.use_deform_preserve_volume)
        mod.use_deform_preserve_volume = state.preserve_volume
    for skin in skins:  # a Bind again replaces the keys of the last one
        volume_keys.remove(skin)
    if volume_blend:  # the shares and the volume keys, split back per mesh
        for skin, mesh_share in zip(skins, combined.split(share)):
            add_volume_blend(skin, arm, np.asarray(mesh_share).ravel())
        add_volume_keys(core, character, combined, skins, arm, share, rig, joints, weights)
    core_skin_was = {}
    if state.deformer == 'ANCHORED':  # the core moves these meshes (live.py); their Armature modifiers rest
        for skin in skins:
            core_skin_was[skin.name] = core_skin.attach(skin, armature_modifier(skin, arm))
    surfaces = {m.name: item.surface.name for item in rig_state(arm).muscles
                for m in muscles if m.name == item.name and item.surface is not None}
    record = {
        "skin": skins[0].name, "added_modifier": skins[0].name in added,
        "skins": [o.name for o in skins], "added_modifiers": added,
        "preserve_volume_before": preserve_volume_before, "bone_names": names,
        "bone_parents": np.asarray(character.bone_parents).tolist(),
        "bone_heads": np.asarray(character.bone_heads).tolist(),
        "bone_tails": np.asarray(character.bone_tails).tolist(),
        "bone_rest": np.asarray(character.bone_rest).tolist(),
        "joint_names": list(rig.joint_names), "muscles": core.muscles_to_json(muscles),
        "surfaces": [surfaces.get(m.name, "") for m in muscles],
        "deformer": "anchored" if state.deformer == 'ANCHORED' else "joints", "core_skin_was": core_skin_was,
        "stuffing": stuffing, "volume_blend": volume_blend, "joints_slide": rig.joints_slide,
        "slide_limits": np.asarray(rig.slide_limits).tolist(),
    }
    write_bind_record(arm, record)
    set_rig_skins(arm, skins)
    state.bound, state.dirty = True, False
    context.scene.render.use_lock_interface = True  # handlers run on the render thread during F12
    runtime.forget(arm.name)
    return rig.num_joints


def apply_preserve_volume(arm):
    """Set the Armature modifier of every bound mesh to the rig's Preserve Volume setting (a bound rig
    follows the setting at once); returns the number of modifiers set."""
    state = rig_state(arm)
    if not state.bound:
        return 0
    count = 0
    for skin in rig_skins(arm):
        mod = armature_modifier(skin, arm)
        if mod is not None and volume_blend_modifier(skin, arm) is None:  # a volume blend keeps its first linear
            mod.use_deform_preserve_volume = state.preserve_volume
            count += 1
    return count


def apply_volume_blend(arm):
    """Follow the rig's Volume Blend setting on a bound rig at once: off removes the second modifier and the linear
    group (the share group stays, so switching back needs no Bind) and gives the first modifier the rig's Preserve
    Volume; on adds them back from the share group. Returns the meshes that still need a Bind (bound with Volume
    Blend off: no shares yet; the caller marks the rig edited)."""
    state = rig_state(arm)
    if not state.bound or state.deformer == 'ANCHORED':
        return []
    waiting = []
    for skin in rig_skins(arm):
        first = armature_modifier(skin, arm)
        if first is None:
            continue
        if state.volume_blend:
            share = read_share_group(skin)
            if share is None:
                waiting.append(skin.name)
            elif volume_blend_modifier(skin, arm) is None:
                add_volume_blend(skin, arm, share)
            volume_keys.set_muted(skin, False)
            continue
        _switch_volume_blend_off(skin, arm)
        first.use_deform_preserve_volume = state.preserve_volume
    record, problem = read_bind_record_or_empty(arm)
    if not problem and record and not waiting:
        record["volume_blend"] = bool(state.volume_blend)
        write_bind_record(arm, record)
    runtime.forget(arm.name)
    return waiting


def dq_scale():
    """How this Blender's Preserve Volume carries bone scale, for the core's skinner (dq_scale=): 'blended'
    (scale matrices blended, measured on 3.4.1) or 'pivot' (add_weighted_dq_dq_pivot, measured on 4.5 and 5.2).
    The switch is placed at 4.0; 3.5-4.1 were not measured."""
    return 'pivot' if bpy.app.version >= (4, 0, 0) else 'blended'


def preserve_volume_of(skin, arm):
    """Whether Blender skins `skin` with Preserve Volume (its Armature modifier's setting; the rig's
    setting when it has none), the mode the core must use to equal it."""
    mod = armature_modifier(skin, arm)
    return bool(mod.use_deform_preserve_volume) if mod is not None else bool(rig_state(arm).preserve_volume)


def skinner_for(skin, arm, live_rig, rest, joints, weights):
    """The core's skinner for `skin` in the mode Blender skins it with (its Armature modifier's Preserve
    Volume): rest (#V by 3, armature space), joints/weights over the live rig's bones + muscle joints."""
    core = core_loader.core()
    count = len(live_rig.bone_names) + len(live_rig.joint_names)
    share = read_share_group(skin) if volume_blend_modifier(skin, arm) is not None else None
    if share is not None:  # the volume blend: Blender's two modifiers, the share as Blender reads it
        return core.Skinner(rest, joints, weights, count, dqs_share=share,
                            rest_matrices=core.combined_rest_matrices(live_rig.character, live_rig.rig),
                            dq_scale=dq_scale())
    if preserve_volume_of(skin, arm):
        return core.Skinner(rest, joints, weights, count, preserve_volume=True,
                            rest_matrices=core.combined_rest_matrices(live_rig.character, live_rig.rig),
                            dq_scale=dq_scale())
    return core.Skinner(rest, joints, weights, count)


PC2_MODIFIER = "Myoskin PC2"  # the Mesh Cache modifiers Bake PC2 adds
MUTED_KEY = "myoskin_muted_armature"  # ID property on a mesh: its Armature modifier's visibility before a cache


def mute_armature_for_cache(skin, arm):
    """A baked PC2 now plays the skin: switch its Armature modifier off (its result is overwritten anyway),
    remembering the visibility it had (the first time) for Unbind."""
    mod = armature_modifier(skin, arm)
    if mod is None:
        return
    if MUTED_KEY not in skin:
        skin[MUTED_KEY] = {"show_viewport": bool(mod.show_viewport), "show_render": bool(mod.show_render)}
    mod.show_viewport = mod.show_render = False
    blend = volume_blend_modifier(skin, arm)
    if blend is not None:  # without the first, the second would deform the cache again
        blend.show_viewport = blend.show_render = False


def remove_caches(skin, arm):
    """Unbind: remove the PC2 modifiers Bake added and give the Armature modifier its visibility back."""
    for mod in [m for m in skin.modifiers if m.type == 'MESH_CACHE' and m.name.startswith(PC2_MODIFIER)]:
        skin.modifiers.remove(mod)
    was = skin.get(MUTED_KEY)
    if was is None:
        return
    for mod in (armature_modifier(skin, arm), volume_blend_modifier(skin, arm)):
        if mod is not None:
            mod.show_viewport = bool(was.get("show_viewport", True))
            mod.show_render = bool(was.get("show_render", True))
    del skin[MUTED_KEY]


def bound_skins(arm):
    """The meshes a bind changed: those named in the bind record, the character's recorded meshes, and any
    mesh of the armature holding a weight backup (e.g. renamed since), in that order, each once."""
    record, _problem = read_bind_record_or_empty(arm)
    names = record.get("skins") or ([record["skin"]] if record.get("skin") else [])
    names = [n for n in names if isinstance(n, str)] if isinstance(names, list) else []
    found = [bpy.data.objects[n] for n in names if n in bpy.data.objects]
    found += rig_skins(arm) + [o for o in blender_io.find_skin_meshes(arm) if BACKUP_KEY in o]
    unique = []
    for o in found:
        if o.type == 'MESH' and o not in unique:
            unique.append(o)
    return unique


def unbind(arm):
    """Remove the muscle-joint bones and their groups, restore the original weights of every bound mesh
    exactly, remove the Armature modifiers Bind added. Returns the reason the bind record could not be read
    ("" when it could; without it the Armature modifiers Bind added stay)."""
    state = rig_state(arm)
    record, problem = read_bind_record_or_empty(arm)
    skins = bound_skins(arm)
    for skin in skins:  # a damaged weight backup stops here, before anything changed
        check_backup(skin)
    rig_io.remove_muscle_bones(arm)
    for skin in skins:
        restore_weights(skin)
    added = record.get("added_modifiers")
    if added is None:  # a bind record from before several meshes
        added = [record["skin"]] if record.get("added_modifier") and record.get("skin") else []
    added = added if isinstance(added, list) else []
    before = record.get("preserve_volume_before", {})
    before = before if isinstance(before, dict) else {}
    for skin in skins:
        remove_caches(skin, arm)
        remove_volume_blend(skin, arm)
    was = record.get("core_skin_was")
    was = was if isinstance(was, dict) else {}
    for skin in skins:
        if core_skin.modifier(skin) is not None or skin.name in was:
            entry = was.get(skin.name)
            core_skin.detach(skin, armature_modifier(skin, arm), entry if isinstance(entry, dict) else {})
    for skin in skins:
        mod = armature_modifier(skin, arm)
        if mod is None:
            continue
        if skin.name in added:
            skin.modifiers.remove(mod)
        elif skin.name in before:  # a modifier the character had: its Preserve Volume as it was
            mod.use_deform_preserve_volume = bool(before[skin.name])
    if state.bind_text is not None:
        bpy.data.texts.remove(state.bind_text)
    state.bound, state.dirty = False, False
    runtime.forget(arm.name)
    return problem


RECORD_KEY = "myoskin_key"  # ID property on the bind record Text: a digest of its content
# The bind record is data a user can edit by hand (it is a Text block): it is only ever parsed as JSON, never
# executed, and refused beyond this size (a 1000-bone rig with 200 muscles writes about 3 MB).
MAX_RECORD_CHARS = 64 * 1024 * 1024
_RECORD_LISTS = ("bone_names", "bone_parents", "bone_heads", "bone_tails", "bone_rest", "joint_names")


def parse_json_text(content, what, limit=None):
    """A JSON object from text a user may have edited (a Text block, an ID property): parsed as data only,
    at most `limit` characters (default MAX_RECORD_CHARS); ValueError with a message naming `what` otherwise."""
    limit = MAX_RECORD_CHARS if limit is None else limit
    if not isinstance(content, str):
        raise ValueError(f"{what} is not text (edited by hand?)")
    if len(content) > limit:
        raise ValueError(f"{what} holds {len(content):,} characters, more than the {limit:,} allowed (edited by hand?)")
    try:
        data = json.loads(content)
    except RecursionError:
        raise ValueError(f"{what} is nested too deeply to be read (edited by hand?)") from None
    except ValueError as e:
        where = f" at line {e.lineno}, column {e.colno}" if hasattr(e, "lineno") else ""
        raise ValueError(f"{what} is not valid JSON{where} (edited by hand?)") from None
    if not isinstance(data, dict):
        raise ValueError(f"{what} is not a JSON object (edited by hand?)")
    return data


def read_bind_record(arm_obj):
    """The armature's bind record (a dict), checked: the lists live update needs, of matching lengths.
    ValueError saying what is wrong and what to do (Unbind works without it; bind again)."""
    text = arm_obj.myoskin.bind_text
    if text is None:
        raise ValueError(f"'{arm_obj.name}' has no bind record: bind again")
    what = f"The bind record '{text.name}' of '{arm_obj.name}'"
    record = parse_json_text(text.as_string(), what)
    bad = [k for k in _RECORD_LISTS if not isinstance(record.get(k), list)]
    if not bad and not isinstance(record.get("muscles"), str):
        bad = ["muscles"]
    if not bad:
        n = len(record["bone_names"])
        bad = [k for k in _RECORD_LISTS[1:5] if len(record[k]) != n]
    if not bad and not all(isinstance(x, str) for x in record["bone_names"] + record["joint_names"]):
        bad = ["bone_names"]
    if bad:
        raise ValueError(f"{what} is damaged ('{bad[0]}' missing or wrong; edited by hand?): Unbind, then Bind again")
    return record


def read_bind_record_or_empty(arm_obj):
    """(record, problem): the bind record, or {} and the reason it cannot be read (Unbind goes on without it:
    the meshes and the weight backup are found from the armature)."""
    if arm_obj.myoskin.bind_text is None:
        return {}, ""
    try:
        return read_bind_record(arm_obj), ""
    except ValueError as e:
        return {}, str(e)


def write_bind_record(arm_obj, record):
    """Store the bind record (a dict) in the armature's "<armature>.bind.json" Text, with its digest."""
    content = json.dumps(record, indent=1)
    state = arm_obj.myoskin
    text = state.bind_text or bpy.data.texts.get(f"{arm_obj.name}.bind.json") or \
        bpy.data.texts.new(f"{arm_obj.name}.bind.json")
    text.from_string(content)
    text[RECORD_KEY] = hashlib.sha1(content.encode("utf-8")).hexdigest()
    state.bind_text = text
    return text
