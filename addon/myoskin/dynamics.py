# SPDX-License-Identifier: GPL-3.0-or-later
"""Secondary motion for the bakes (issue 16): what Bake PC2 and the batch's chunked bakes need beyond the rig,
read from the .blend and handed to the core's simulate.

Stored data (plain data, parsed never executed, readable without the add-on):
- the painted jiggle map: the skin's vertex group JIGGLE_GROUP (0..1 per vertex);
- sculpt deltas: the skin mesh's POINT attributes SCULPT_DELTA (FLOAT_VECTOR: the core's local deltas, tangent /
  binormal / normal components, in armature space units) and SCULPT_FRAMED (INT: 1 where the delta is in the
  local frame, 0 where in world space), and the object's ID property SCULPT_KEY: JSON {"version": 1,
  "armature", "frame", "source", "vertices"} saying where they came from.
Service layer: no operators, no UI."""
import json
import os

import numpy as np

from . import blender_io, core_loader

JIGGLE_GROUP = "myoskin_jiggle"  # a vertex group painted on a skin: how much jiggle reaches each vertex (0..1)
SCULPT_KEY = "myoskin_sculpt"
SCULPT_DELTA = "myoskin_sculpt_delta"
SCULPT_FRAMED = "myoskin_sculpt_framed"


# ------------------------------------------------------------------------------------------------
# Chunked bakes: the state files
# ------------------------------------------------------------------------------------------------


def state_file_frames(path):
    """(frame, start_frame) of a simulation state file (the core's myoskin.simulation_state); ValueError naming
    the file when it is missing or not one. The core checks the rest when it restores it."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as e:
        raise ValueError(f"Simulation state {path}: cannot read it ({e.strerror or e})") from None
    except ValueError as e:
        raise ValueError(f"Simulation state {path}: not valid JSON ({e})") from None
    if not isinstance(data, dict) or data.get("format") != "myoskin.simulation_state":
        raise ValueError(f"Simulation state {path}: not a simulation state (format 'myoskin.simulation_state')")
    frame, start = data.get("frame"), data.get("start_frame")
    if not isinstance(frame, int) or not isinstance(start, int) or frame < start:
        raise ValueError(f"Simulation state {path}: bad 'frame' / 'start_frame'")
    return frame, start


def check_state_target(path):
    """ValueError when a state file cannot be written at `path`."""
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        raise ValueError(f"Simulation state {path}: folder {folder} does not exist")


# ------------------------------------------------------------------------------------------------
# The painted jiggle map (per vertex)
# ------------------------------------------------------------------------------------------------


def vertex_influence(skin):
    """#V float64 in [0, 1]: the skin's painted JIGGLE_GROUP (0 outside the group), or None when it has none."""
    if JIGGLE_GROUP not in skin.vertex_groups:
        return None
    return np.clip(blender_io.vertex_group_weights(skin, JIGGLE_GROUP), 0.0, 1.0)


# ------------------------------------------------------------------------------------------------
# Shape keys: the mix Blender feeds its Armature modifier, per frame
# ------------------------------------------------------------------------------------------------


class ShapeKeyMix:
    """A mesh's relative shape keys, read once: offsets(values) is the mix Blender evaluates for those key values
    (basis + sum of value x vertex-group weight x (key - its relative key)) minus the mesh's vertices."""

    def __init__(self, skin):
        key = skin.data.shape_keys
        self.names = []
        if key is None or len(key.key_blocks) < 2:
            return
        if not key.use_relative:
            raise ValueError(f"'{skin.name}' has absolute shape keys: Bake PC2 takes relative shape keys only")
        count = len(skin.data.vertices)

        def coords(kb):
            co = np.empty(count * 3, dtype=np.float32)
            kb.data.foreach_get("co", co)
            return co.reshape(-1, 3).astype(np.float64)

        self.base = coords(key.reference_key) - blender_io.mesh_vertices(skin.data)
        self.deltas, self.masks, self.ranges = [], [], []
        for kb in key.key_blocks:
            if kb == key.reference_key or kb.relative_key == kb:
                continue
            self.names.append(kb.name)
            self.deltas.append(coords(kb) - coords(kb.relative_key))
            mask = None
            if kb.vertex_group:
                mask = blender_io.vertex_group_weights(skin, kb.vertex_group)[:, None] \
                    if kb.vertex_group in skin.vertex_groups else np.zeros((count, 1))
            self.masks.append(mask)
        for d in self.deltas:
            if not np.isfinite(d).all():
                raise ValueError(f"'{skin.name}' has a shape key with a NaN or infinite coordinate")

    def values(self, skin, depsgraph):
        """The key values Blender uses now (evaluated: drivers and animation applied; muted keys 0)."""
        key = skin.data.shape_keys
        evaluated = key.evaluated_get(depsgraph) if depsgraph is not None else key
        blocks = evaluated.key_blocks
        return [0.0 if blocks[n].mute else float(blocks[n].value) for n in self.names]

    def offsets(self, values):
        """#V by 3 float64 offsets of the rest mesh (mesh space) for the key values, or None when all are zero."""
        if not self.names or (not any(values) and not self.base.any()):
            return None
        out = self.base.copy()
        for value, delta, mask in zip(values, self.deltas, self.masks):
            if value:
                out += value * (delta if mask is None else mask * delta)
        return out


# ------------------------------------------------------------------------------------------------
# Sculpt deltas
# ------------------------------------------------------------------------------------------------


def sculpt_info(skin):
    """The stored sculpt's description ({"frame", "source", "armature", "vertices"}) or None; ValueError when
    damaged."""
    text = skin.get(SCULPT_KEY)
    if text is None:
        return None
    try:
        data = json.loads(str(text))
        if not (isinstance(data.get("frame"), int) and isinstance(data.get("vertices"), int)):
            raise ValueError("frame / vertices")
        return data
    except (ValueError, TypeError, AttributeError) as e:
        raise ValueError(f"'{skin.name}'s stored sculpt deltas ({SCULPT_KEY}) are damaged ({e}): Remove Sculpt "
                         f"Deltas and capture them again") from None


def stored_sculpt(skin):
    """A core SculptDeltas from the skin's stored sculpt, or None; ValueError when the data does not fit the mesh."""
    info = sculpt_info(skin)
    if info is None:
        return None
    mesh = skin.data
    count = len(mesh.vertices)
    attrs = mesh.attributes
    delta, framed = attrs.get(SCULPT_DELTA), attrs.get(SCULPT_FRAMED)
    if delta is None or framed is None or delta.domain != 'POINT' or framed.domain != 'POINT' \
            or delta.data_type != 'FLOAT_VECTOR' or framed.data_type != 'INT':
        raise ValueError(f"'{skin.name}' lost its sculpt delta attributes ({SCULPT_DELTA}, {SCULPT_FRAMED}): Remove "
                         f"Sculpt Deltas and capture them again")
    if info["vertices"] != count:
        raise ValueError(f"'{skin.name}'s sculpt deltas were captured on {info['vertices']} vertices, the mesh has "
                         f"{count} now: Remove Sculpt Deltas and capture them again")
    local = np.empty(count * 3, dtype=np.float32)
    delta.data.foreach_get("vector", local)
    flags = np.empty(count, dtype=np.int32)
    framed.data.foreach_get("value", flags)
    local = local.reshape(-1, 3).astype(np.float64)
    if not np.isfinite(local).all():
        raise ValueError(f"'{skin.name}'s sculpt deltas have a NaN or infinite value: capture them again")
    return core_loader.core().SculptDeltas.from_local(blender_io.mesh_triangles(mesh), local, flags)


def store_sculpt(skin, arm, frame, source, deltas):
    """Stores a core SculptDeltas (over the skin's vertices) on the skin: attributes + the description."""
    mesh = skin.data
    remove_sculpt(skin)
    local = np.ascontiguousarray(deltas.local_deltas, dtype=np.float32).ravel()
    framed = np.ascontiguousarray(deltas.framed, dtype=np.int32)
    attr = mesh.attributes.new(SCULPT_DELTA, 'FLOAT_VECTOR', 'POINT')
    attr.data.foreach_set("vector", local)
    attr = mesh.attributes.new(SCULPT_FRAMED, 'INT', 'POINT')
    attr.data.foreach_set("value", framed)
    skin[SCULPT_KEY] = json.dumps({"version": 1, "armature": arm.name, "frame": int(frame), "source": source,
                                   "vertices": len(mesh.vertices)})
    mesh.update()


def remove_sculpt(skin):
    """Removes the stored sculpt deltas (True when there were any)."""
    had = SCULPT_KEY in skin
    if had:
        del skin[SCULPT_KEY]
    for name in (SCULPT_DELTA, SCULPT_FRAMED):
        attr = skin.data.attributes.get(name)
        if attr is not None:
            skin.data.attributes.remove(attr)
            had = True
    return had


def largest_delta(deltas):
    """The largest delta's length (for reports)."""
    local = np.asarray(deltas.local_deltas)
    return float(np.linalg.norm(local, axis=1).max()) if len(local) else 0.0

