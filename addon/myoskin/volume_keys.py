# SPDX-License-Identifier: GPL-3.0-or-later
"""The volume blend's volume keys in Blender: one shape key per key the core computed (compute_volume_keys: rest-space
offsets around a limb joint that give back the volume its band still loses as it bends, or take back what it gains;
its value in [-1, 1], negative where the bend moves the skin the other way), its value driven natively by
the joint's child bone (a simple expression of the bone's Local Space quaternion, no Python):

    value = s (k1 + k2 s) [x max(sx (xy - wz) + sz (yz + wx), 0)^2 / max((xy - wz)^2 + (yz + wx)^2, 1e-12)],
    s = x^2 + z^2,

the bracket only for a directional key (a limb's root: one key per quarter of swing directions). Shape keys come
before the Armature modifiers, so Blender skins the keyed rest exactly as the core does (volume_key_weights, then the
skinner); Bake PC2 and the correctives read them through the evaluated shape key mix.

The mesh keeps what it needs to undo and to check: ID property KEYS_PROPERTY, a list of {name, bone, k1, k2, swing}
per key Bind added (binding.add_volume_keys -> add_key, set_stored), and ADDED_BASIS when Bind added the Basis key
itself. The keys are ordinary shape keys: while they are on the mesh Blender will not apply its modifiers (Unbind
removes them), and each adds one copy of the mesh's coordinates to the .blend.

Layer: service (imports blender_io, core_loader)."""

import numpy as np

from . import blender_io, core_loader

KEYS_PROPERTY = "myoskin_volume_keys"
ADDED_BASIS = "myoskin_volume_keys_added_basis"
KEY_PREFIX = "myoskin_volume."
LEAN_FLOOR = "0.000000000001"  # the core's kLeanFloor (1e-12), written out: simple expressions take no exponent


def _number(x):
    text = f"{float(x):.15f}".rstrip("0").rstrip(".")
    return text if text not in ("", "-0") else "0"


def weight_expression(k1, k2, swing):
    """The driver's simple expression on the quaternion variables w, x, y, z (volumeKeyWeight in the core)."""
    s = "(x*x+z*z)"
    expression = f"{s}*({_number(k1)}+{_number(k2)}*{s})"
    if swing is not None and (swing[0] != 0.0 or swing[1] != 0.0):
        a, c = "(x*y-w*z)", "(y*z+w*x)"
        expression += (f"*pow(max({_number(swing[0])}*{a}+{_number(swing[1])}*{c},0),2)"
                       f"/max({a}*{a}+{c}*{c},{LEAN_FLOOR})")
    return expression.replace("+-", "-")


def _driven_bone(block):
    """The bone a volume key's driver reads now (Blender renames it with the bone), or None without a driver."""
    ad = block.id_data.animation_data
    if ad is None:
        return None
    path = block.path_from_id("value")
    for fc in ad.drivers:
        if fc.data_path == path and fc.driver.variables:
            return fc.driver.variables[0].targets[0].bone_target or None
    return None


def stored(skin):
    """The volume keys Bind added to `skin` (a list of dicts {name, bone, k1, k2, swing}; the bone as the key's driver
    reads it now, so a bone renamed after Bind is followed), [] without any."""
    entries = [dict(e) for e in skin.get(KEYS_PROPERTY, [])]
    key = skin.data.shape_keys
    for e in entries:
        e["swing"] = [float(x) for x in e["swing"]]
        block = key.key_blocks.get(e["name"]) if key is not None else None
        bone = _driven_bone(block) if block is not None else None
        if bone:
            e["bone"] = bone
    return entries


def key_name(bone, directional, index):
    """The shape key name of a volume key: myoskin_volume.<bone> (a limb root's quarters: .1 to .4)."""
    return KEY_PREFIX + bone + (f".{index}" if directional else "")


def add_key(skin, arm, key, name, moves):
    """Add one driven shape key for a core volume key (compute_volume_keys' dict) to `skin`: `moves` is this mesh's
    #V by 3 armature-space offsets at weight 1. Returns its entry for set_stored, or None when the key does not reach
    this mesh. Adds the Basis key first when the mesh has none (remembered for Unbind)."""
    moves = np.asarray(moves, dtype=np.float64)
    if not np.any(moves):
        return None
    if arm.data.bones.get(key["bone"]) is None:
        raise ValueError(f"Volume key of bone '{key['bone']}': armature '{arm.name}' has no such bone")
    if skin.data.shape_keys is None:
        skin.shape_key_add(name="Basis", from_mix=False)
        skin[ADDED_BASIS] = True
    to_mesh = np.linalg.inv(blender_io.mesh_to_armature_matrix(skin, arm)[:3, :3])
    block = skin.shape_key_add(name=name, from_mix=False)
    basis = np.empty(len(skin.data.vertices) * 3, dtype=np.float32)
    block.relative_key.data.foreach_get("co", basis)
    co = basis.reshape(-1, 3).astype(np.float64) + moves @ to_mesh.T
    block.data.foreach_set("co", co.astype(np.float32).ravel())
    block.slider_min, block.slider_max, block.value = -1.0, 1.0, 0.0  # negative: the skin moved back
    # Blender shortens long names and renames clashes (".001"): the entry keeps the name the key really has.
    entry = {"name": block.name, "bone": key["bone"], "k1": float(key["k1"]), "k2": float(key["k2"]),
             "swing": [float(v) for v in key.get("swing", (0.0, 0.0))]}
    drive(block, arm, entry)
    return entry


def set_stored(skin, entries):
    """Remember the volume keys Bind added to `skin` (add_key's entries)."""
    skin[KEYS_PROPERTY] = entries


def drive(block, arm, entry):
    """(Re)write the driver of one volume key's shape key `block` from its stored entry."""
    block.driver_remove("value")
    driver = block.driver_add("value").driver
    driver.type = 'SCRIPTED'
    for variable, channel in zip("wxyz", ("ROT_W", "ROT_X", "ROT_Y", "ROT_Z")):
        var = driver.variables.new()
        var.name, var.type = variable, 'TRANSFORMS'
        target = var.targets[0]
        target.id, target.bone_target, target.transform_type = arm, entry["bone"], channel
        target.rotation_mode, target.transform_space = 'QUATERNION', 'LOCAL_SPACE'
    driver.expression = weight_expression(entry["k1"], entry["k2"], entry["swing"])


def rebuild_drivers(skin, arm, entries):
    """The drivers of the volume keys `entries` (stored(skin) taken before they were removed) written again."""
    key = skin.data.shape_keys
    for e in entries:
        block = key.key_blocks.get(e["name"]) if key is not None else None
        if block is not None:
            drive(block, arm, e)


def remove(skin):
    """Unbind: remove the shape keys (and their drivers) Bind added, and the Basis when Bind added it and no other key
    is left."""
    entries = stored(skin)
    key = skin.data.shape_keys
    if key is not None:
        for e in entries:
            block = key.key_blocks.get(e["name"])
            if block is not None:
                block.driver_remove("value")
                skin.shape_key_remove(block)
        key = skin.data.shape_keys
        if skin.get(ADDED_BASIS) and key is not None and len(key.key_blocks) == 1:
            skin.shape_key_remove(key.key_blocks[0])
    for prop in (KEYS_PROPERTY, ADDED_BASIS):
        if prop in skin:
            del skin[prop]


def set_muted(skin, muted):
    """Volume Blend switched off (muted) or on again on a bound rig: the keys stay, muted keys add nothing."""
    key = skin.data.shape_keys
    if key is None:
        return
    for e in stored(skin):
        block = key.key_blocks.get(e["name"])
        if block is not None:
            block.mute = bool(muted)


def offsets_by_key(skin, arm):
    """{name: #V by 3 armature-space offsets at weight 1} of the keys Bind added (what the core adds per weight)."""
    key = skin.data.shape_keys
    if key is None:
        return {}
    to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
    out = {}
    n = len(skin.data.vertices)
    for e in stored(skin):
        block = key.key_blocks.get(e["name"])
        if block is None:
            continue
        co, basis = np.empty(n * 3, dtype=np.float32), np.empty(n * 3, dtype=np.float32)
        block.data.foreach_get("co", co)
        block.relative_key.data.foreach_get("co", basis)
        out[e["name"]] = (co.reshape(-1, 3).astype(np.float64) - basis.reshape(-1, 3)) @ to_arm[:3, :3].T
    return out




def pose_weights(skin, character, pose):
    """{shape key name: weight} of the mesh's unmuted volume keys under `pose` (#B by 4 by 4 posed matrices of
    `character`'s bones, PoseBone.matrix), computed by the core (volume_key_weights: the drivers' formula)."""
    entries = stored(skin)
    key = skin.data.shape_keys
    if not entries or key is None:
        return {}
    names = list(character.bone_names)
    live = [e for e in entries if e["bone"] in names and key.key_blocks.get(e["name"]) is not None
            and not key.key_blocks[e["name"]].mute]
    if not live:
        return {}
    core = core_loader.core()
    rotations = np.asarray(core.bone_local_rotations(character, np.asarray(pose)))
    weights = core.volume_key_weights([dict(e, bone_index=names.index(e["bone"])) for e in live], rotations)
    return {e["name"]: float(w) for e, w in zip(live, weights)}


def pose_offsets(skin, arm, character, pose):
    """#V by 3 armature-space offsets the volume keys add to the mesh's rest under `pose` (pose_weights): what
    Blender's shape keys hand its Armature modifiers, so the core's skinner on rest + these equals Blender's skin.
    Muted keys (Volume Blend off) add nothing."""
    out = np.zeros((len(skin.data.vertices), 3))
    weights = pose_weights(skin, character, pose)
    if weights:
        offsets = offsets_by_key(skin, arm)
        for name, weight in weights.items():
            out += weight * offsets[name]
    return out
