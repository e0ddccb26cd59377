# SPDX-License-Identifier: GPL-3.0-or-later
"""Converters between the muscle state stored in the .blend (state.py) and the core's Muscle lists, and the
Blender objects that show a muscle: its surface mesh, its origin/insertion locators and its wrap display.

Spaces: every position is in the armature's space (the core's mesh space, see blender_io). A surface
object is parented to the armature with an identity parent inverse, so its mesh coordinates ARE armature
space. A locator is an empty parented to its bone with the parent inverse chosen so that its `location`
is its rest position in armature space (whatever the current pose).

Layer: muscle service. Imports downward only (state, blender_io, core_loader).
"""
import json

import bpy
import numpy as np
from mathutils import Matrix

from . import blender_io, core_loader
from .state import rig_state, set_rig_skins

LOCATOR_ENDS = ("origin", "insertion")
COLLECTION_NAME = "Muscles"


# ------------------------------------------------------------------------------------------------
# One muscle <-> its stored data
# ------------------------------------------------------------------------------------------------


def muscle_to_data(muscle):
    """A one-muscle muscles.json document (str) for a core Muscle (no surface: it is re-lofted on load)."""
    return core_loader.core().muscles_to_json([muscle], indent=-1)


MAX_DATA_CHARS = 16 * 1024 * 1024  # one muscle's stored muscles.json (a few kB when written by the add-on)


def data_to_muscle(data, name="?"):
    """The core Muscle stored in a MyoskinMuscle.data string; ValueError naming the muscle when unusable."""
    if not data:
        raise ValueError(f"Muscle '{name}' has no stored data (was it added by hand?): extract it again")
    if len(data) > MAX_DATA_CHARS:  # parsed as data only (the core's JSON reader), and bounded
        raise ValueError(f"Muscle '{name}': its stored data holds {len(data):,} characters, more than the "
                         f"{MAX_DATA_CHARS:,} allowed (edited by hand?): extract it again")
    try:
        muscles = core_loader.core().muscles_from_json(data)
    except ValueError as e:
        raise ValueError(f"Muscle '{name}': its stored data cannot be read ({e}; edited by hand?): extract it "
                         f"again or remove it") from None
    if len(muscles) != 1:
        raise ValueError(f"Muscle '{name}': stored data holds {len(muscles)} muscles")
    return muscles[0]


def locator_rest_position(locator):
    """Rest position (armature space) of a locator empty: its location (see the module docstring)."""
    return np.array(locator.location, dtype=np.float64)


def item_to_core(arm_obj, item):
    """The core Muscle for a MyoskinMuscle with every UI setting applied: name, bulge, joints, wrap,
    attachment bones and the locators' positions. Raises ValueError with a message for the user."""
    m = data_to_muscle(item.data, item.name)
    bones = arm_obj.data.bones
    m.name = item.name
    m.bulge = float(item.bulge)
    m.joints = int(item.joints)
    m.wrap_type = item.wrap_type
    if item.wrap_type != 'none':
        if item.wrap_bone not in bones:
            raise ValueError(f"Muscle '{item.name}': wrap bone '{item.wrap_bone}' is not in armature "
                             f"'{arm_obj.name}' (renamed or deleted?): pick a wrap bone")
        if item.wrap_radius <= 0.0:
            raise ValueError(f"Muscle '{item.name}': wrap radius must be > 0")
        m.wrap_bone = item.wrap_bone
        m.wrap_radius = float(item.wrap_radius)
        m.wrap_side = int(item.wrap_side)
    for end in LOCATOR_ENDS:
        bone = getattr(item, end + "_bone")
        if bone not in bones:
            raise ValueError(f"Muscle '{item.name}': {end} bone '{bone}' is not in armature '{arm_obj.name}' "
                             f"(renamed or deleted?): snap the {end} locator to a bone")
        setattr(m, end + "_bone", bone)
        locator = getattr(item, end + "_locator")
        if locator is not None:
            setattr(m, end, locator_rest_position(locator))
    return m


def state_to_core(arm_obj, enabled_only=True):
    """Core Muscles of an armature's state, in list order (only enabled ones by default)."""
    state = rig_state(arm_obj)
    if state is None:
        raise ValueError("Not an armature: select the character's armature or its skin")
    return [item_to_core(arm_obj, item) for item in state.muscles if item.enabled or not enabled_only]


def store_core(item, muscle):
    """Write a core Muscle into a MyoskinMuscle (data + settings), without firing update callbacks twice."""
    item.data = muscle_to_data(muscle)
    item["region"] = muscle.region
    item["confidence"] = float(muscle.confidence)
    item["bulge"] = float(muscle.bulge)
    item["joints"] = int(muscle.joints)
    item["wrap_type"] = {'none': 0, 'joint': 1, 'bone': 2}[muscle.wrap_type]
    item["wrap_bone"] = muscle.wrap_bone
    if muscle.wrap_radius > 0.0:
        item["wrap_radius"] = float(muscle.wrap_radius)
    item["wrap_side"] = 0 if muscle.wrap_side >= 0 else 1
    item["origin_bone"] = muscle.origin_bone
    item["insertion_bone"] = muscle.insertion_bone
    item["origin_rest"] = [float(x) for x in muscle.origin]  # float64 here; compared against the locators
    item["insertion_rest"] = [float(x) for x in muscle.insertion]


def sync_text(arm_obj):
    """Rewrite the armature's muscles.json Text datablock from its state (all muscles, enabled flag kept as
    an extra field), so the file carries a readable muscles.json even without the add-on."""
    state = rig_state(arm_obj)
    text = state.muscles_text
    if text is None:
        text = bpy.data.texts.new(f"{arm_obj.name}.muscles.json")
        state.muscles_text = text
    doc = {"format": "myoskin.muscles", "version": 1, "muscles": []}
    for item in state.muscles:
        try:
            entry = json.loads(muscle_to_data(item_to_core(arm_obj, item)))["muscles"][0]
        except ValueError:  # kept as stored when it reads as a muscle, else just its name (damaged by hand?)
            try:
                entry = json.loads(item.data)["muscles"][0] if len(item.data) <= MAX_DATA_CHARS else None
            except (ValueError, KeyError, TypeError, IndexError, RecursionError):
                entry = None
            if not isinstance(entry, dict):
                entry = {"name": item.name}
        entry["enabled"] = bool(item.enabled)
        doc["muscles"].append(entry)
    text.from_string(json.dumps(doc, indent=1))
    return text


# ------------------------------------------------------------------------------------------------
# Display objects
# ------------------------------------------------------------------------------------------------


def muscles_collection(arm_obj):
    """The armature's "Muscles" collection (created under the scene collection when missing)."""
    state = rig_state(arm_obj)
    coll = state.collection
    if coll is None or coll.name not in bpy.data.collections:
        coll = bpy.data.collections.new(COLLECTION_NAME)
        bpy.context.scene.collection.children.link(coll)
        state.collection = coll
    elif not any(c == coll for c in bpy.context.scene.collection.children_recursive):
        bpy.context.scene.collection.children.link(coll)
    return coll


def write_surface(arm_obj, item, vertices, triangles=None):
    """Set a muscle's surface mesh to #V by 3 armature-space vertices (and #F by 3 triangles when the
    topology changes); creates the surface object when missing. Returns the object."""
    obj = item.surface
    vertices = np.ascontiguousarray(vertices, dtype=np.float32)
    if obj is None or obj.name not in bpy.data.objects or triangles is not None and \
            len(obj.data.polygons) != len(triangles) or len(obj.data.vertices) != len(vertices):
        if triangles is None:
            raise ValueError(f"Muscle '{item.name}': surface topology unknown")
        mesh = blender_io._new_mesh(item.name, vertices, triangles)
        if obj is None or obj.name not in bpy.data.objects:
            obj = bpy.data.objects.new(item.name, mesh)
            muscles_collection(arm_obj).objects.link(obj)
            obj.parent = arm_obj
            obj.matrix_parent_inverse = Matrix.Identity(4)
            obj["myoskin_muscle"] = item.name
            item.surface = obj
        else:
            old = obj.data
            obj.data = mesh
            if old.users == 0:
                bpy.data.meshes.remove(old)
        return obj
    obj.data.vertices.foreach_set("co", vertices.ravel())
    obj.data.update()
    return obj


def _bone_tail_frame(arm_obj, bone_name):
    bone = arm_obj.data.bones[bone_name]
    return bone.matrix_local @ Matrix.Translation((0.0, bone.length, 0.0))


def attach_locator(arm_obj, locator, bone_name, position):
    """Parent an empty to a bone so that its location is `position` (armature space, rest)."""
    locator.parent = arm_obj
    locator.parent_type = 'BONE'
    locator.parent_bone = bone_name
    locator.matrix_parent_inverse = _bone_tail_frame(arm_obj, bone_name).inverted()
    locator.matrix_basis = Matrix.Translation(tuple(float(x) for x in position))


def make_locator(arm_obj, item, end, position):
    """The origin/insertion empty of a muscle (created when missing), at `position` on its bone."""
    locator = getattr(item, end + "_locator")
    if locator is None or locator.name not in bpy.data.objects:
        locator = bpy.data.objects.new(f"{item.name}.{end}", None)
        locator.empty_display_type = 'SPHERE' if end == "origin" else 'CUBE'
        locator.empty_display_size = 0.006 / blender_io.armature_scale(arm_obj)  # 6 mm in the scene
        muscles_collection(arm_obj).objects.link(locator)
        setattr(item, end + "_locator", locator)
    locator["myoskin_muscle"] = item.name
    locator["myoskin_end"] = end
    attach_locator(arm_obj, locator, getattr(item, end + "_bone"), position)
    return locator


def update_wrap_display(arm_obj, item):
    """The wrap display empty: a sphere of the wrap radius at the wrap bone's head (joint wrap); a cone of
    that base radius round the bone's middle, pointing along the bone for side +1 and back for -1 (bone
    wrap, right-hand rule); none otherwise."""
    display = item.wrap_locator
    if item.wrap_type == 'none' or item.wrap_bone not in arm_obj.data.bones:
        if display is not None and display.name in bpy.data.objects:
            bpy.data.objects.remove(display)
        item.wrap_locator = None
        return None
    if display is None or display.name not in bpy.data.objects:
        display = bpy.data.objects.new(f"{item.name}.wrap", None)
        muscles_collection(arm_obj).objects.link(display)
        display["myoskin_muscle"] = item.name
        display.hide_select = True
        item.wrap_locator = display
    bone = arm_obj.data.bones[item.wrap_bone]
    display.empty_display_size = max(float(item.wrap_radius), 1e-4)
    display.parent = arm_obj
    display.parent_type = 'BONE'
    display.parent_bone = bone.name
    display.matrix_parent_inverse = _bone_tail_frame(arm_obj, bone.name).inverted()
    if item.wrap_type == 'joint':
        display.empty_display_type = 'SPHERE'
        display.matrix_basis = bone.matrix_local
    else:  # a cone round the bone's middle: base radius = the cylinder's, pointing along +-bone Y = the side
        display.empty_display_type = 'CONE'
        flip = Matrix.Identity(4) if item.wrap_side == '1' else Matrix.Rotation(np.pi, 4, 'X')
        display.matrix_basis = bone.matrix_local @ Matrix.Translation((0.0, 0.5 * bone.length, 0.0)) @ flip
    return display


def fit_joint_wrap(arm_obj, item):
    """A joint wrap's sphere shrinks to 0.8 of the nearer locator's distance when a locator was moved into
    it (the core refuses an end inside the sphere). It only shrinks: moving the locator out again keeps the
    smaller sphere (set Wrap Radius to grow it). Returns True when the radius changed."""
    if item.wrap_type != 'joint' or item.wrap_bone not in arm_obj.data.bones:
        return False
    centre = np.array(arm_obj.data.bones[item.wrap_bone].head_local, dtype=np.float64)
    ends = [getattr(item, end + "_locator") for end in LOCATOR_ENDS]
    if any(loc is None for loc in ends):
        return False
    nearest = min(float(np.linalg.norm(locator_rest_position(loc) - centre)) for loc in ends)
    if item.wrap_radius < nearest or nearest <= 1e-6:
        return False
    item["wrap_radius"] = 0.8 * nearest  # no update callback: the caller refreshes
    update_wrap_display(arm_obj, item)
    return True


def refresh_muscle(arm_obj, item):
    """Re-attach a muscle to its locators' positions through the core (root-curve ends and surface are
    rebuilt), store the result and redraw its surface. Returns the core Muscle."""
    fit_joint_wrap(arm_obj, item)
    muscle = core_loader.core().reattach_muscle(item_to_core(arm_obj, item))
    store_core(item, muscle)
    write_surface(arm_obj, item, muscle.surface_vertices, muscle.surface_triangles)
    return muscle


# ------------------------------------------------------------------------------------------------
# Adding and removing muscles
# ------------------------------------------------------------------------------------------------


def unique_name(state, name, skip_last=False):
    """`name`, or `name.002`, `name.003`, ... when another muscle has it (skip_last: ignore the last item,
    the one being added)."""
    items = list(state.muscles)
    taken = {m.name for m in (items[:-1] if skip_last else items)}
    if name not in taken:
        return name
    k = 2
    while f"{name}.{k:03d}" in taken:
        k += 1
    return f"{name}.{k:03d}"


def add_muscle(arm_obj, muscle):
    """Append a core Muscle to the armature's state with its surface and locators; returns the item."""
    state = rig_state(arm_obj)
    item = state.muscles.add()
    name = unique_name(state, muscle.name, skip_last=True)
    item["name"] = name
    item.previous_name = name
    muscle.name = name
    store_core(item, muscle)
    if len(muscle.surface_vertices) == 0:
        muscle = core_loader.core().reattach_muscle(muscle)
    write_surface(arm_obj, item, muscle.surface_vertices, muscle.surface_triangles)
    for end in LOCATOR_ENDS:
        make_locator(arm_obj, item, end, getattr(muscle, end))
    update_wrap_display(arm_obj, item)
    return item


def _remove_objects(item):
    for attr in ("surface", "origin_locator", "insertion_locator", "wrap_locator"):
        obj = getattr(item, attr)
        if obj is not None and obj.name in bpy.data.objects:
            data = obj.data
            bpy.data.objects.remove(obj)
            if data is not None and data.users == 0 and isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)


def remove_muscle(arm_obj, index):
    """Remove one muscle: its item, surface, locators and wrap display."""
    state = rig_state(arm_obj)
    _remove_objects(state.muscles[index])
    state.muscles.remove(index)
    state.active_index = min(state.active_index, max(0, len(state.muscles) - 1))


def clear_muscles(arm_obj):
    state = rig_state(arm_obj)
    while len(state.muscles):
        remove_muscle(arm_obj, len(state.muscles) - 1)


def set_muscles(arm_obj, skins, muscles):
    """Replace an armature's muscles by core Muscles (extraction result) of the character made of the mesh
    objects `skins` (recorded in the state); writes muscles.json."""
    state = rig_state(arm_obj)
    clear_muscles(arm_obj)
    set_rig_skins(arm_obj, list(skins))
    items = [add_muscle(arm_obj, m) for m in muscles]
    state.active_index = 0
    state.dirty = state.bound
    sync_text(arm_obj)
    return items


def scale_muscles(muscles, factor):
    """Core Muscles with every position and length multiplied by `factor` (root curve, origin, insertion,
    section centres and radii, wrap radius; directions and u unchanged), through muscles.json. The
    surfaces are not carried: add_muscle re-lofts them (reattach_muscle)."""
    if factor == 1.0 or not muscles:
        return list(muscles)
    core = core_loader.core()
    doc = json.loads(core.muscles_to_json(list(muscles), indent=-1))

    def scaled(p):
        return [float(x) * factor for x in p]

    for m in doc["muscles"]:
        for end in LOCATOR_ENDS:
            m[end]["position"] = scaled(m[end]["position"])
        m["root_curve"] = [scaled(p) for p in m["root_curve"]]
        for sec in m["sections"]:
            sec["center"] = scaled(sec["center"])
            sec["a"], sec["b"] = float(sec["a"]) * factor, float(sec["b"]) * factor
        if "radius" in m.get("wrap", {}):
            m["wrap"]["radius"] = float(m["wrap"]["radius"]) * factor
    return list(core.muscles_from_json(json.dumps(doc)))


def find_item(arm_obj, name):
    state = rig_state(arm_obj)
    for i, item in enumerate(state.muscles):
        if item.name == name:
            return i, item
    return -1, None


# ------------------------------------------------------------------------------------------------
# Mirroring (across the armature's X = 0 plane, bone names flipped as Blender's "flip name" does)
# ------------------------------------------------------------------------------------------------


def _mirror_vec(v):
    return [-float(v[0]), float(v[1]), float(v[2])]


def mirrored_muscle(arm_obj, item):
    """The core Muscle mirrored across the armature's YZ plane with .L/.R (etc.) names flipped."""
    muscle = item_to_core(arm_obj, item)
    doc = json.loads(muscle_to_data(muscle))
    m = doc["muscles"][0]
    bones = arm_obj.data.bones
    m["name"] = bpy.utils.flip_name(m["name"])
    if m["name"] == item.name:
        m["name"] = item.name + ".mirror"
    m["region"] = bpy.utils.flip_name(m.get("region", ""))
    for end in LOCATOR_ENDS:
        m[end]["bone"] = bpy.utils.flip_name(m[end]["bone"])
        m[end]["position"] = _mirror_vec(m[end]["position"])
        if m[end]["bone"] not in bones:
            raise ValueError(f"Mirror of '{item.name}': no bone '{m[end]['bone']}' in '{arm_obj.name}'")
    m["root_curve"] = [_mirror_vec(p) for p in m["root_curve"]]
    for s in m["sections"]:
        s["center"], s["axis_a"], s["normal"] = (_mirror_vec(s["center"]), _mirror_vec(s["axis_a"]),
                                                 _mirror_vec(s["normal"]))
    if m["wrap"]["type"] != "none":
        m["wrap"]["bone"] = bpy.utils.flip_name(m["wrap"]["bone"])
        m["wrap"]["side"] = -int(m["wrap"].get("side", 1))
    mirrored = core_loader.core().muscles_from_json(json.dumps(doc))[0]
    return core_loader.core().reattach_muscle(mirrored)


# ------------------------------------------------------------------------------------------------
# Service functions of the property callbacks and the locator watcher (called from handlers.py)
# ------------------------------------------------------------------------------------------------


def on_renamed(arm_obj, item):
    """Rename a muscle's objects with it (names must stay unique: a clash gets a suffix)."""
    state = rig_state(arm_obj)
    wanted = item.name
    if not wanted:
        item["name"] = item.previous_name
        return
    if sum(1 for m in state.muscles if m.name == wanted) > 1:
        wanted = unique_name(state, wanted)
        item["name"] = wanted
    for attr, suffix in (("surface", ""), ("origin_locator", ".origin"), ("insertion_locator", ".insertion"),
                         ("wrap_locator", ".wrap")):
        obj = getattr(item, attr)
        if obj is not None and obj.name in bpy.data.objects:
            obj.name = wanted + suffix
            obj["myoskin_muscle"] = wanted
    item.previous_name = wanted
    state.dirty = state.bound
    sync_text(arm_obj)


def moved_locator_muscles(arm_obj, tolerance=1e-6):
    """Items whose origin/insertion locator's rest position differs from the stored one (tolerance in
    metres: locations are float32)."""
    moved = []
    for item in rig_state(arm_obj).muscles:
        for end in LOCATOR_ENDS:
            locator = getattr(item, end + "_locator")
            stored = item.get(end + "_rest")
            if locator is None or stored is None:
                continue
            if np.abs(locator_rest_position(locator) - np.asarray(stored)).max() > tolerance:
                moved.append(item)
                break
    return moved


def nearest_bone(arm_obj, position, deform_only=True):
    """(bone name, nearest point on that bone's rest segment) for an armature-space position."""
    best = (None, None, np.inf)
    p = np.asarray(position, dtype=np.float64)
    for bone in arm_obj.data.bones:
        if deform_only and not bone.use_deform or bone.get("myoskin_joint"):
            continue
        a, b = np.array(bone.head_local), np.array(bone.tail_local)
        ab = b - a
        t = np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-18), 0.0, 1.0)
        q = a + t * ab
        d = np.linalg.norm(p - q)
        if d < best[2]:
            best = (bone.name, q, d)
    if best[0] is None:
        raise ValueError(f"Armature '{arm_obj.name}' has no deform bones")
    return best[0], best[1]
