# SPDX-License-Identifier: GPL-3.0-or-later
"""Pose-space correctives (issue 16): a fix sculpted on the posed skin becomes a shape key in rest space (the
sculpt mapped back through the inverse of each vertex's blended skinning transform, by the core, in the mode the
mesh's Armature modifier skins with: linear or Preserve Volume, over every deform bone of the armature, so the
muscle joints of a bound rig count) with native drivers on its bone's local rotation (simple expressions: they
play without the add-on and with Auto Run Python Scripts off, and the glTF exporter bakes them to morph weights).

Stored data (all of it plain data, readable without the add-on):
- the shape keys, named as the correctives, relative to the mesh's first key (its basis), slider range -10..10;
- per driving sample a float custom property on the mesh's Key, `myoskin_rbf_<n>`, driven by
  pow(max(k0 + k1 (x*y - w*z) + k2 (x*x + z*z) + k3 (y*z + w*x), 0), 3) on the bone's Local Space quaternion;
- each corrective key's value driven by sum_j c_j * kernel_j (the bone's radial basis function);
- the mesh object's ID property `myoskin_correctives`: JSON {"version": 1, "armature", "correctives": [{"name",
  "bone", "direction", "falloff"}]} from which the drivers are rebuilt after an add or a removal.
Service layer: no operators, no UI."""
import contextlib
import json
import math

import bpy
import numpy as np
from mathutils import Matrix

from . import binding, blender_io, core_loader, core_skin, rig_io, volume_keys

STORE_KEY = "myoskin_correctives"
KERNEL_PREFIX = "myoskin_rbf_"
MAX_EXPRESSION = 255  # Blender's ChannelDriver.expression holds 256 bytes
SLIDER_RANGE = 10.0
DEFAULT_FALLOFF = math.radians(60.0)


# ------------------------------------------------------------------------------------------------
# The stored list
# ------------------------------------------------------------------------------------------------


def stored(skin):
    """(armature name, [entry dicts]) from the mesh's `myoskin_correctives`; ValueError when damaged."""
    text = skin.get(STORE_KEY)
    if text is None:
        return "", []
    try:
        data = json.loads(str(text))
        entries = data["correctives"]
        for e in entries:
            if not (isinstance(e["name"], str) and isinstance(e["bone"], str) and len(e["direction"]) == 3
                    and all(math.isfinite(float(x)) for x in e["direction"]) and float(e["falloff"]) > 0.0):
                raise ValueError(e)
        return str(data.get("armature", "")), entries
    except (ValueError, KeyError, TypeError) as ex:
        raise ValueError(f"'{skin.name}'s stored correctives ({STORE_KEY}) are damaged ({ex}): remove the property "
                         f"and add the correctives again") from None


def write_stored(skin, arm, entries):
    if not entries:
        if STORE_KEY in skin:
            del skin[STORE_KEY]
        return
    skin[STORE_KEY] = json.dumps({"version": 1, "armature": arm.name, "correctives": entries})


def corrective_names(skin):
    try:
        return [e["name"] for e in stored(skin)[1]]
    except ValueError:
        return []


# ------------------------------------------------------------------------------------------------
# What the Armature modifier does to the mesh
# ------------------------------------------------------------------------------------------------


def require_armature_modifier(skin, arm):
    if core_skin.modifier(skin) is not None:
        raise ValueError(f"'{skin.name}' is bound with the Anchored Skin deformer (the core moves it, not the Armature "
                         f"modifier): correctives work with the Muscle Joints deformer or plain skinning")
    mod = binding.armature_modifier(skin, arm)
    if mod is None:
        raise ValueError(f"'{skin.name}' has no Armature modifier of '{arm.name}': correctives drive the skin it "
                         f"deforms")
    if not mod.show_viewport:
        raise ValueError(f"'{skin.name}'s Armature modifier is off in the viewport: turn it on to sculpt at a pose")
    for m in skin.modifiers:
        if m == mod:
            break
        if m.show_viewport:
            raise ValueError(f"'{skin.name}'s modifier '{m.name}' comes before its Armature modifier: correctives need "
                             f"the shape keys to feed the Armature modifier directly (move it below, or turn it off)")
    blend_group = mod.vertex_group == binding.LINEAR_GROUP and binding.volume_blend_modifier(skin, arm) is not None
    if mod.use_bone_envelopes or not mod.use_vertex_groups or (mod.vertex_group and not blend_group):
        raise ValueError(f"'{skin.name}'s Armature modifier must deform by vertex groups only (no envelopes, no "
                         f"modifier vertex group) for correctives")
    return mod


def local_rotation(arm_eval, bone_name):
    """(w, x, y, z) of the bone's rotation relative to its parent and its rest frame in the evaluated pose:
    what a driver reads as the bone's Local Space quaternion."""
    pb = arm_eval.pose.bones[bone_name]
    rest = np.array(pb.bone.matrix_local, dtype=np.float64)
    pose = np.array(pb.matrix, dtype=np.float64)
    if pb.parent is not None:
        parent_delta = np.array(pb.parent.matrix, dtype=np.float64) @ np.linalg.inv(
            np.array(pb.parent.bone.matrix_local, dtype=np.float64))
    else:
        parent_delta = np.eye(4)
    local = np.linalg.inv(parent_delta @ rest) @ pose
    r = local[:3, :3] / np.linalg.norm(local[:3, :3], axis=0)
    q = Matrix(r.tolist()).to_quaternion()
    return (q.w, q.x, q.y, q.z)


def deform_setup(skin, arm, depsgraph):
    """The core's skinner for what Blender's Armature modifier does to `skin` now: every deform bone of the
    armature (muscle joints of a bound rig too) with the mesh's vertex groups, the modifier's Preserve Volume (or
    the volume blend's share group with its second modifier), this Blender's dual-quaternion scale. Returns (skinner, #B by 4 by 4 transforms in armature space,
    mesh->armature 4x4)."""
    core = core_loader.core()
    mod = require_armature_modifier(skin, arm)
    bones = arm.data.bones
    names = [b.name for b in bones if b.use_deform]
    if not names:
        raise ValueError(f"Armature '{arm.name}' has no deform bones")
    joints, weights = rig_io.read_combined_weights(skin, names)
    num_vertices = len(skin.data.vertices)
    if joints.shape[0] == 0:
        joints, weights = np.full((num_vertices, 1), -1, np.int32), np.zeros((num_vertices, 1))
    to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
    rest_bones = np.array([np.array(bones[n].matrix_local, dtype=np.float64) for n in names])
    arm_eval = arm.evaluated_get(depsgraph)
    pose = np.array([np.array(arm_eval.pose.bones[n].matrix, dtype=np.float64) for n in names])
    transforms = pose @ np.linalg.inv(rest_bones)
    rest = blender_io.mesh_vertices(skin.data) @ to_arm[:3, :3].T + to_arm[:3, 3]
    share = binding.read_share_group(skin) if binding.volume_blend_modifier(skin, arm) is not None else None
    if share is not None:  # the volume blend (the first modifier linear, the second mixed in by the share group)
        skinner = core.Skinner(rest, joints, weights, len(names), dqs_share=share, rest_matrices=rest_bones,
                               dq_scale=binding.dq_scale())
    elif mod.use_deform_preserve_volume:
        skinner = core.Skinner(rest, joints, weights, len(names), preserve_volume=True, rest_matrices=rest_bones,
                               dq_scale=binding.dq_scale())
    else:
        skinner = core.Skinner(rest, joints, weights, len(names))
    return skinner, transforms, to_arm


class _Modifiers:
    """Turns the mesh's modifiers off in the viewport (all, or all but its Armature modifier) for an evaluation,
    and back as they were."""

    def __init__(self, skin, keep=None):
        keep = [] if keep is None else list(keep) if isinstance(keep, (list, tuple)) else [keep]
        self.skin, self.keep, self.saved = skin, keep, []

    def __enter__(self):
        for m in self.skin.modifiers:
            if m not in self.keep and m.show_viewport:
                self.saved.append(m)
                m.show_viewport = False
        return self

    def __exit__(self, *exc):
        for m in self.saved:
            m.show_viewport = True
        return False


def evaluated(skin, context, keep=None):
    """#V by 3 float64 evaluated positions (mesh space) with only `keep` (a modifier or a list) of the modifiers on
    (None: shape keys only: what the Armature modifier receives)."""
    with _Modifiers(skin, keep):
        context.view_layer.update()
        points = blender_io.evaluated_vertices(skin, depsgraph=context.evaluated_depsgraph_get())
    context.view_layer.update()
    if len(points) != len(skin.data.vertices):
        raise ValueError(f"'{skin.name}' evaluates to {len(points)} vertices, its mesh has {len(skin.data.vertices)}")
    return points


# ------------------------------------------------------------------------------------------------
# Drivers
# ------------------------------------------------------------------------------------------------


def _number(x):
    return f"{x:.9f}".rstrip("0").rstrip(".") if x != 0.0 else "0"


def kernel_expression(k):
    """A simple expression (no Python) of the kernel on the quaternion variables w, x, y, z."""
    terms = f"{_number(k[0])}+{_number(k[1])}*(x*y-w*z)+{_number(k[2])}*(x*x+z*z)+{_number(k[3])}*(y*z+w*x)"
    return "pow(max(" + terms.replace("+-", "-") + ",0),3)"


def weight_expression(coefficients):
    terms = "+".join(f"{_number(c)}*k{j}" for j, c in enumerate(coefficients) if _number(c) not in ("0", "-0"))
    return (terms.replace("+-", "-") or "0")


def _remove_drivers(key, key_names):
    ad = key.animation_data
    if ad is None:
        return
    paths = {f'key_blocks["{bpy.utils.escape_identifier(n)}"].value' for n in key_names}
    for fc in list(ad.drivers):
        if fc.data_path.startswith(f'["{KERNEL_PREFIX}') or fc.data_path in paths:
            ad.drivers.remove(fc)
    for prop in [p for p in key.keys() if p.startswith(KERNEL_PREFIX)]:
        del key[prop]


def write_drivers(skin, arm, drivers, entries):
    """(Re)write the kernel properties and every corrective key's driver from a core CorrectiveDrivers built on
    `entries` (in the same order)."""
    key = skin.data.shape_keys
    _remove_drivers(key, [e["name"] for e in entries])
    bone_names = [b.name for b in arm.data.bones]
    counter = 0
    for rbf in drivers.bones:
        bone = bone_names[rbf["bone"]]
        props = []
        for k in np.asarray(rbf["kernels"]):
            prop = f"{KERNEL_PREFIX}{counter}"
            counter += 1
            key[prop] = 0.0
            fc = key.driver_add(f'["{prop}"]')
            d = fc.driver
            d.type = 'SCRIPTED'
            for name, channel in zip("wxyz", ("ROT_W", "ROT_X", "ROT_Y", "ROT_Z")):
                var = d.variables.new()
                var.name, var.type = name, 'TRANSFORMS'
                t = var.targets[0]
                t.id, t.bone_target, t.transform_type = arm, bone, channel
                t.rotation_mode, t.transform_space = 'QUATERNION', 'LOCAL_SPACE'
            d.expression = kernel_expression(k)
            props.append(prop)
        coefficients = np.asarray(rbf["coefficients"])
        for column, index in enumerate(rbf["correctives"]):
            kb = key.key_blocks[entries[index]["name"]]
            fc = kb.driver_add("value")
            d = fc.driver
            d.type = 'SCRIPTED'
            for j, prop in enumerate(props):
                var = d.variables.new()
                var.name, var.type = f"k{j}", 'SINGLE_PROP'
                t = var.targets[0]
                t.id_type, t.id, t.data_path = 'KEY', key, f'["{prop}"]'
            expression = weight_expression(coefficients[:, column])
            if len(expression) > MAX_EXPRESSION:
                raise ValueError(f"Bone '{bone}' drives too many correctives for one Blender driver expression "
                                 f"({len(expression)} characters, at most {MAX_EXPRESSION}): remove some")
            d.expression = expression


def build_drivers(entries, arm):
    """The core's CorrectiveDrivers for stored entries (ValueError on identical poses, a pose at rest...)."""
    bone_index = {b.name: i for i, b in enumerate(arm.data.bones)}
    poses = []
    for e in entries:
        if e["bone"] not in bone_index:
            raise ValueError(f"Corrective '{e['name']}' is driven by bone '{e['bone']}', which armature "
                             f"'{arm.name}' does not have")
        poses.append({"name": e["name"], "bone": bone_index[e["bone"]], "direction": [float(x) for x in e["direction"]],
                      "falloff": float(e["falloff"])})
    return core_loader.core().CorrectiveDrivers(poses)


@contextlib.contextmanager
def weights_baked_for_export(context, skins, arm):
    """While the body runs (a glTF export): every corrective key and volume key of `skins` keyed on each frame of the
    scene's range with the value its drivers give there, its drivers removed, so an exporter that does not follow a
    driver (Blender 4.x's glTF exporter) writes the morph weights animation. Afterwards the Key's action and the
    drivers are as before (the drivers rebuilt from the stored correctives and volume keys)."""
    targets = []
    for skin in skins:
        entries = stored(skin)[1]
        key = skin.data.shape_keys
        volume = [e for e in volume_keys.stored(skin) if key is not None and e["name"] in key.key_blocks
                  and not key.key_blocks[e["name"]].mute]  # muted (Volume Blend off): Blender adds nothing
        names = [e["name"] for e in entries] + [e["name"] for e in volume]
        if names and key is not None:
            targets.append((skin, entries, volume, names))
    if not targets:
        yield
        return
    scene = context.scene
    frames = list(range(scene.frame_start, scene.frame_end + 1))
    values = {skin.name: [] for skin, _entries, _volume, _names in targets}
    current = scene.frame_current
    try:
        for frame in frames:
            scene.frame_set(frame)
            depsgraph = context.evaluated_depsgraph_get()
            for skin, _entries, _volume, names in targets:
                key = skin.data.shape_keys.evaluated_get(depsgraph)
                values[skin.name].append([float(key.key_blocks[n].value) for n in names])
    finally:
        scene.frame_set(current)
    saved = []
    try:
        for skin, entries, volume, names in targets:
            key = skin.data.shape_keys
            ad = key.animation_data or key.animation_data_create()
            saved.append((skin, entries, volume, ad.action))
            _remove_drivers(key, names)
            ad.action = bpy.data.actions.new(f"{key.name}Correctives")
            for k, frame in enumerate(frames):
                for j, n in enumerate(names):
                    kb = key.key_blocks[n]
                    kb.value = values[skin.name][k][j]
                    kb.keyframe_insert("value", frame=frame)
        yield
    finally:
        for skin, entries, volume, action in saved:
            ad = skin.data.shape_keys.animation_data
            baked = ad.action
            ad.action = action
            if baked is not None and baked != action:
                bpy.data.actions.remove(baked)
            if entries:
                write_drivers(skin, arm, build_drivers(entries, arm), entries)
            volume_keys.rebuild_drivers(skin, arm, volume)


# ------------------------------------------------------------------------------------------------
# Add / remove
# ------------------------------------------------------------------------------------------------


def _finite(points, what):
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if len(bad):
        raise ValueError(f"{what}: vertex {bad[0]} has a NaN or infinite coordinate")


def sculpt_target(context, skin, arm, source_key="", source_object=None):
    """#V by 3 (mesh space) of the sculpt on the posed skin: the Armature modifier's result with the shape key
    `source_key` at 1 (sculpted in Sculpt Mode on the posed mesh), or the vertices of `source_object` (a posed
    copy that was sculpted) in the skin's object space."""
    num_vertices = len(skin.data.vertices)
    if source_object is not None:
        if source_object.type != 'MESH':
            raise ValueError(f"The sculpt '{source_object.name}' is not a mesh")
        if source_object == skin:
            raise ValueError("The sculpt object is the skin itself: give a sculpted copy, or a shape key")
        count = len(source_object.data.vertices)
        if count != num_vertices:
            raise ValueError(f"The sculpt '{source_object.name}' has {count} vertices, the skin '{skin.name}' has "
                             f"{num_vertices}: sculpt a copy of the posed skin with the same vertices")
        points = blender_io.mesh_vertices(source_object.data)
        _finite(points, f"The sculpt '{source_object.name}'")
        m = np.linalg.inv(np.array(skin.matrix_world)) @ np.array(source_object.matrix_world)
        return points @ m[:3, :3].T + m[:3, 3]
    key = skin.data.shape_keys
    if not source_key or key is None or source_key not in key.key_blocks:
        raise ValueError(f"'{skin.name}' has no shape key '{source_key}' to take the sculpt from")
    kb = key.key_blocks[source_key]
    if kb == key.reference_key:
        raise ValueError(f"'{source_key}' is the basis shape key: sculpt the fix in a shape key of its own")
    if source_key in corrective_names(skin):
        raise ValueError(f"'{source_key}' is a corrective already: sculpt the fix in a new shape key")
    co = np.empty(num_vertices * 3, dtype=np.float32)
    kb.data.foreach_get("co", co)
    _finite(co.reshape(-1, 3), f"Shape key '{source_key}'")
    saved = (kb.value, kb.mute)
    kb.value, kb.mute = 1.0, False
    try:
        target = evaluated(skin, context, keep=binding.armature_modifiers(skin, arm))
    finally:
        kb.value, kb.mute = saved
    return target


def add_corrective(context, skin, arm, bone_name, name="", falloff=DEFAULT_FALLOFF, source_key="",
                   source_object=None):
    """Store the sculpt at the current pose as a corrective of `bone_name`. Returns (name, the largest rest-space
    offset, the sculpt's largest move of the posed skin), mesh units."""
    core = core_loader.core()
    if skin is None or skin.type != 'MESH':
        raise ValueError("Select the skinned mesh (or its armature with one skin) to add a corrective to")
    if arm is None or arm.type != 'ARMATURE':
        raise ValueError(f"'{skin.name}' has no armature")
    if not bone_name or bone_name not in arm.data.bones:
        raise ValueError(f"Armature '{arm.name}' has no bone '{bone_name}'")
    if not (0.0 < falloff <= math.pi):
        raise ValueError(f"Falloff must be in (0, 180] degrees, got {math.degrees(falloff):.1f}")
    require_armature_modifier(skin, arm)
    _arm_name, entries = stored(skin)
    name = name or source_key or f"corrective_{bone_name}"
    taken = set(skin.data.shape_keys.key_blocks.keys()) if skin.data.shape_keys else set()
    if any(e["name"] == name for e in entries):
        raise ValueError(f"'{skin.name}' already has a corrective '{name}': remove it first or pick another name")
    if name in taken and name != source_key:
        raise ValueError(f"'{skin.name}' already has a shape key '{name}': pick another name")
    depsgraph = context.evaluated_depsgraph_get()
    target = sculpt_target(context, skin, arm, source_key, source_object)
    before = evaluated(skin, context, keep=binding.armature_modifiers(skin, arm))  # the posed skin as it is
    rotation = local_rotation(arm.evaluated_get(depsgraph), bone_name)
    entry = {"name": name, "bone": bone_name, "direction": list(core.bone_direction(rotation)), "falloff": falloff}
    new_entries = entries + [entry]
    drivers = build_drivers(new_entries, arm)  # identical poses, a pose at rest: refused before anything changes
    if skin.data.shape_keys is None:
        skin.shape_key_add(name="Basis", from_mix=False)
    key = skin.data.shape_keys
    if source_key:
        key.key_blocks[source_key].value = 0.0  # its sculpt becomes the corrective
        if name == source_key:
            key.key_blocks[source_key].name = name + ".sculpt"
    kb = skin.shape_key_add(name=name, from_mix=False)
    kb.relative_key = key.reference_key
    kb.slider_min, kb.slider_max = -SLIDER_RANGE, SLIDER_RANGE
    try:
        write_drivers(skin, arm, drivers, new_entries)
        base = evaluated(skin, context)  # what the Armature modifier receives, the new key still flat
        skinner, transforms, to_arm = deform_setup(skin, arm, context.evaluated_depsgraph_get())
        to_arm_points = lambda p: p @ to_arm[:3, :3].T + to_arm[:3, 3]  # noqa: E731
        offsets_arm = np.asarray(core.rest_space_offsets(skinner, transforms, to_arm_points(base),
                                                         to_arm_points(target)))
        offsets = offsets_arm @ np.linalg.inv(to_arm[:3, :3]).T
        basis = np.empty(len(skin.data.vertices) * 3, dtype=np.float32)
        key.reference_key.data.foreach_get("co", basis)
        kb.data.foreach_set("co", (basis.reshape(-1, 3) + offsets).astype(np.float32).ravel())
        skin.data.update()
    except Exception:
        _remove_drivers(key, [e["name"] for e in new_entries])
        skin.shape_key_remove(kb)
        if entries:
            write_drivers(skin, arm, build_drivers(entries, arm), entries)
        raise
    write_stored(skin, arm, new_entries)
    context.view_layer.update()
    return name, float(np.linalg.norm(offsets, axis=1).max()), float(np.linalg.norm(target - before, axis=1).max())


def remove_corrective(context, skin, arm, name):
    """Remove a corrective's shape key and rebuild the drivers of the others."""
    _arm_name, entries = stored(skin)
    if not any(e["name"] == name for e in entries):
        raise ValueError(f"'{skin.name}' has no corrective '{name}'")
    rest = [e for e in entries if e["name"] != name]
    key = skin.data.shape_keys
    _remove_drivers(key, [e["name"] for e in entries])
    if name in key.key_blocks:
        skin.shape_key_remove(key.key_blocks[name])
    if rest:
        write_drivers(skin, arm, build_drivers(rest, arm), rest)
    write_stored(skin, arm, rest)
    context.view_layer.update()
    return len(rest)
