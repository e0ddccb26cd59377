# SPDX-License-Identifier: GPL-3.0-or-later
"""The hybrid rig in Blender (DESIGN.md sections 2-3): muscle joints as deform bones of the character's own
armature, combined weights as vertex groups, posed joint matrices written to pose bones.

Spaces: every matrix is in the armature object's local space (the core's mesh space, see blender_io).
Combined joints (skinning.h): indices [0, #B) are the skeleton bones, [#B, #B + #J) the muscle joints; a
weight row refers to bones by position in the `bone_names` list given with it (skeleton names, then joint
names).

API
- create_muscle_bones(armature_obj, joint_names, bind_matrices, parent_bones, lengths=None,
                      layer=MUSCLE_LAYER, collection_name=MUSCLE_COLLECTION) -> list of bone names
- create_rig_bones(armature_obj, rig, skeleton_bone_names, layer=..., collection_name=...) -> names
      the same from a _core.MuscleRig (joint_names, bind_matrices, joint_parent_bone, rest_lengths)
- muscle_bone_names(armature_obj) -> names of the bones created here (tagged "myoskin_joint")
- remove_muscle_bones(armature_obj, names=None, remove_vertex_groups=True) -> number removed
- write_combined_weights(mesh_obj, bone_names, joints, weights) -> vertex groups (replaces same-named ones)
- read_combined_weights(mesh_obj, bone_names) -> (#V by K joints, #V by K weights)
- pose_bone_matrices(armature_obj, bone_names=None) -> #N by 4 by 4 PoseBone.matrix (evaluated pose)
- write_joint_matrices(armature_obj, joint_names, joint_matrices, parent_matrices=None) -> None
      sets the joints' pose (location, rotation_quaternion, scale) so that PoseBone.matrix ==
      joint_matrices[j], computed from the parents' posed matrices (parent_matrices: {bone name: 4x4} or
      (names, #N by 4 by 4), or read from the pose), then update_tag().

Blender conditions for the Armature modifier to compute Equation 3 exactly (DESIGN.md section 2):
B-Bone segments 1, Envelope Multiply off, Deform on, linear (not preserve-volume) modifier.
"""
import bpy
import numpy as np
from mathutils import Matrix, Quaternion, Vector

from . import blender_io, core_loader

JOINT_TAG = "myoskin_joint"          # Bone custom property marking a muscle-joint bone (value: 1)
MUSCLE_LAYER = 24                    # Blender 3.x bone layer of the muscle joints
MUSCLE_COLLECTION = "Muscle Joints"  # Blender 4.x bone collection of the muscle joints
DEFAULT_LENGTH = 0.02                # metres, display length of a joint bone when none is given
FLOAT32_EPS = float(np.finfo(np.float32).eps)
ROUND_OFF_ULPS = 64                  # float32 round-off accepted when Blender re-derives matrix_local
ROLL_FLOOR = 1e-4                    # Blender's roll <-> matrix conversion loses digits near the -Y axis
RIGID_TOLERANCE = 1e-4               # |R^T R - I| of a bind matrix (float32 data pass through it)


def rest_tolerance(bind, length):
    """(rotation, translation) round-off Blender's float32 head/tail/roll may put into a bone's
    matrix_local: the direction comes from the difference of coordinates as large as the bone's distance
    from the origin, so its error grows with that distance over the bone's length; the head's with the
    distance itself (bind: 4 by 4, length: the bone's length)."""
    size = max(float(np.linalg.norm(bind[:3, 3])), float(length), 1e-30)
    return (max(ROUND_OFF_ULPS * FLOAT32_EPS * size / float(length), ROLL_FLOOR),
            ROUND_OFF_ULPS * FLOAT32_EPS * size)


def _require_rigid(bind, names):
    for j, n in enumerate(names):
        r = bind[j, :3, :3]
        off = float(np.abs(r.T @ r - np.eye(3)).max())
        if off > RIGID_TOLERANCE or np.linalg.det(r) <= 0 or np.abs(bind[j, 3] - (0, 0, 0, 1)).max() > 0:
            raise RuntimeError(f"create_muscle_bones: the bind matrix of '{n}' is not rigid (|R^T R - I| = "
                               f"{off:.3g}, det {np.linalg.det(r):.3g}): a bind matrix must be a rotation and "
                               f"a translation")


# ------------------------------------------------------------------------------------------------
# Checks
# ------------------------------------------------------------------------------------------------


def _require_armature(armature_obj, what):
    if armature_obj is None or getattr(armature_obj, "type", None) != 'ARMATURE':
        raise ValueError(f"{what}: {getattr(armature_obj, 'name', None)!r} is not an armature object")


def _matrices(array, count, what):
    m = np.asarray(array, dtype=np.float64)
    if m.ndim != 3 or m.shape[1:] != (4, 4) or m.shape[0] != count:
        raise ValueError(f"{what} must be {count} by 4 by 4, got shape {m.shape}")
    bad = np.flatnonzero(~np.isfinite(m).all(axis=(1, 2)))
    if len(bad):
        raise ValueError(f"{what}: matrix {int(bad[0])} has a NaN or infinite value")
    return m


def _check_weights(bone_names, joints, weights):
    joints = np.asarray(joints)
    weights = np.asarray(weights, dtype=np.float64)
    if joints.ndim == 1:
        joints, weights = joints[:, None], weights.reshape(-1, 1)
    if joints.shape != weights.shape or joints.ndim != 2:
        raise ValueError(f"joints {joints.shape} and weights {weights.shape} must both be #V by K")
    bad = (joints < -1) | (joints >= len(bone_names))
    if bad.any():
        v, k = np.argwhere(bad)[0]
        raise ValueError(f"weights: vertex {v} slot {k} uses joint {int(joints[v, k])}, outside "
                         f"0..{len(bone_names) - 1}")
    bad = ~np.isfinite(weights) | (weights < 0)
    if bad.any():
        v, k = np.argwhere(bad)[0]
        raise ValueError(f"weights: vertex {v} slot {k} has weight {weights[v, k]} (must be finite and >= 0)")
    return joints.astype(np.int32), weights


# ------------------------------------------------------------------------------------------------
# Bones
# ------------------------------------------------------------------------------------------------


def _put_in_layer(edit_bone, arm_data, layer, collection_name):
    """The joint's own bone layer (3.x) or bone collection (4.x)."""
    if hasattr(arm_data, "collections"):  # Blender 4.0+
        coll = arm_data.collections.get(collection_name) or arm_data.collections.new(collection_name)
        coll.assign(edit_bone)
    else:
        edit_bone.layers = [i == layer for i in range(32)]


def in_muscle_layer(bone, layer=MUSCLE_LAYER, collection_name=MUSCLE_COLLECTION):
    """True when `bone` lies in the muscle joints' own layer (3.x) or bone collection (4.x) and no other."""
    if hasattr(bone, "collections"):  # Blender 4.0+
        return [c.name for c in bone.collections] == [collection_name]
    return bool(bone.layers[layer]) and sum(bool(x) for x in bone.layers) == 1


def _show_layer(arm_data, layer):
    if not hasattr(arm_data, "collections"):
        layers = list(arm_data.layers)
        layers[layer] = True
        arm_data.layers = layers


def create_muscle_bones(armature_obj, joint_names, bind_matrices, parent_bones, lengths=None,
                        layer=MUSCLE_LAYER, collection_name=MUSCLE_COLLECTION):
    """Create one deform bone per muscle joint: matrix_local = bind_matrices[j] (#J by 4 by 4, rigid),
    parent = parent_bones[j] (a bone name, or None/"" for none), display length lengths[j] (metres; default
    DEFAULT_LENGTH), in its own bone layer/collection, B-Bone segments 1, Deform on, Envelope Multiply off,
    tagged JOINT_TAG. Existing bones of the same names are replaced. Returns the bone names.
    Raises ValueError on bad input (sizes, NaN, unknown parent) and RuntimeError when Blender cannot
    represent a bind matrix (it is not rigid)."""
    forget_structures()
    _require_armature(armature_obj, "create_muscle_bones")
    names = [str(n) for n in joint_names]
    if len(set(names)) != len(names) or any(not n for n in names):
        raise ValueError("create_muscle_bones: joint names must be unique and non-empty")
    bind = _matrices(bind_matrices, len(names), "bind_matrices")
    parents = [p or None for p in parent_bones]
    if len(parents) != len(names):
        raise ValueError(f"create_muscle_bones: {len(parents)} parent bones for {len(names)} joints")
    lengths = np.full(len(names), DEFAULT_LENGTH) if lengths is None else np.asarray(lengths, dtype=np.float64)
    if lengths.shape != (len(names),) or not (np.isfinite(lengths).all() and (lengths > 0).all()):
        raise ValueError(f"create_muscle_bones: lengths must be {len(names)} positive numbers")
    _require_rigid(bind, names)
    arm_data = armature_obj.data
    existing = set(arm_data.bones.keys())
    for p in parents:
        if p is not None and p not in existing and p not in names:
            raise ValueError(f"create_muscle_bones: parent bone '{p}' is not in armature '{armature_obj.name}'")

    with blender_io.object_mode(armature_obj, 'EDIT'):
        edit_bones = arm_data.edit_bones
        for n in names:
            if n in edit_bones:
                edit_bones.remove(edit_bones[n])
        created = []
        for j, n in enumerate(names):
            eb = edit_bones.new(n)
            eb.head = (0.0, 0.0, 0.0)
            eb.tail = (0.0, float(lengths[j]), 0.0)
            eb.matrix = Matrix(bind[j].tolist())  # head, direction and roll; keeps the length
            eb.use_deform = True
            eb.bbone_segments = 1
            eb.use_envelope_multiply = False
            eb.use_connect = False
            _put_in_layer(eb, arm_data, layer, collection_name)
            created.append(eb)
        for eb, p in zip(created, parents):
            if p is not None:
                eb.parent = edit_bones[p]
    _show_layer(arm_data, layer)

    bones = arm_data.bones
    actual = blender_io.bone_rest_matrices(bones)
    for j, n in enumerate(names):
        bones[n][JOINT_TAG] = 1
        armature_obj.pose.bones[n].rotation_mode = 'QUATERNION'  # write_joint_matrices' fast path
        diff = np.abs(actual[bones.find(n)] - bind[j])
        rot_err, move_err = float(diff[:3, :3].max()), float(diff[:3, 3].max())
        rot_tol, move_tol = rest_tolerance(bind[j], lengths[j])
        if rot_err > rot_tol or move_err > move_tol:
            raise RuntimeError(f"create_muscle_bones: bone '{n}' matrix_local differs from its bind matrix by "
                               f"{rot_err:.3g} in rotation and {move_err:.3g} in position, more than float32 "
                               f"round-off ({rot_tol:.3g}, {move_tol:.3g})")
    return names


def create_rig_bones(armature_obj, rig, skeleton_bone_names, layer=MUSCLE_LAYER, collection_name=MUSCLE_COLLECTION):
    """create_muscle_bones from a _core.MuscleRig: parents from rig.joint_parent_bone (indices into
    skeleton_bone_names, the core Character's bone order), display length = the muscle's rest length over
    its joint count."""
    names = list(rig.joint_names)
    parent_index = np.asarray(rig.joint_parent_bone)
    muscle = np.asarray(rig.joint_muscle)
    counts = np.bincount(muscle, minlength=int(rig.num_muscles)) if len(muscle) else np.zeros(0)
    rest_lengths = np.asarray(rig.rest_lengths, dtype=np.float64)
    lengths = np.array([max(rest_lengths[m] / max(counts[m], 1), 1e-3) for m in muscle]) if len(muscle) else None
    parents = [skeleton_bone_names[i] if i >= 0 else None for i in parent_index]
    return create_muscle_bones(armature_obj, names, np.asarray(rig.bind_matrices), parents, lengths, layer,
                               collection_name)


def muscle_bone_names(armature_obj):
    """Names of the armature's muscle-joint bones (those tagged JOINT_TAG), in bone order."""
    _require_armature(armature_obj, "muscle_bone_names")
    return [b.name for b in armature_obj.data.bones if b.get(JOINT_TAG)]


def remove_muscle_bones(armature_obj, names=None, remove_vertex_groups=True):
    """Remove muscle-joint bones (names=None: every bone tagged JOINT_TAG; only tagged bones are ever
    removed) and, with remove_vertex_groups, their vertex groups on the meshes the armature deforms.
    Returns the number of bones removed."""
    forget_structures()
    _require_armature(armature_obj, "remove_muscle_bones")
    tagged = set(muscle_bone_names(armature_obj))
    targets = tagged if names is None else {n for n in names if n in tagged}
    if not targets:
        return 0
    with blender_io.object_mode(armature_obj, 'EDIT'):
        edit_bones = armature_obj.data.edit_bones
        for n in targets:
            if n in edit_bones:
                edit_bones.remove(edit_bones[n])
    if remove_vertex_groups:
        for mesh_obj in blender_io.find_skin_meshes(armature_obj):
            for g in [g for g in mesh_obj.vertex_groups if g.name in targets]:
                mesh_obj.vertex_groups.remove(g)
    return len(targets)


# ------------------------------------------------------------------------------------------------
# Weights
# ------------------------------------------------------------------------------------------------


def write_combined_weights(mesh_obj, bone_names, joints, weights):
    """Write combined weights (#V by K joints indexing bone_names, -1 = empty; #V by K weights) as one
    vertex group per name, replacing groups of those names. Returns the groups (in bone_names order)."""
    if mesh_obj is None or mesh_obj.type != 'MESH':
        raise ValueError(f"write_combined_weights: {getattr(mesh_obj, 'name', None)!r} is not a mesh object")
    bone_names = [str(n) for n in bone_names]
    joints, weights = _check_weights(bone_names, joints, weights)
    if joints.shape[0] != len(mesh_obj.data.vertices):
        raise ValueError(f"write_combined_weights: {joints.shape[0]} weight rows for "
                         f"{len(mesh_obj.data.vertices)} vertices of '{mesh_obj.name}'")
    wanted = set(bone_names)
    everyone = list(range(len(mesh_obj.data.vertices)))
    for g in [g for g in mesh_obj.vertex_groups if g.name in wanted]:
        g.remove(everyone)  # emptied, not removed: every group keeps its place (index) in the list
    return blender_io.write_vertex_weights(mesh_obj, bone_names, joints, weights)


def read_combined_weights(mesh_obj, bone_names):
    """(#V by K int32 indices into bone_names, #V by K float64 weights), strongest first, from the vertex
    groups named in bone_names (other groups are ignored)."""
    index = {str(n): i for i, n in enumerate(bone_names)}
    group_to_bone = {g.index: index[g.name] for g in mesh_obj.vertex_groups if g.name in index}
    return blender_io.read_vertex_weights(mesh_obj, group_to_bone, len(mesh_obj.data.vertices))


# ------------------------------------------------------------------------------------------------
# Pose
# ------------------------------------------------------------------------------------------------


def pose_bone_matrices(armature_obj, bone_names=None):
    """#N by 4 by 4 PoseBone.matrix (armature space, as of the last evaluation) of bone_names (default:
    every bone, in pose.bones order). foreach_get gives column-major matrices."""
    _require_armature(armature_obj, "pose_bone_matrices")
    pose_bones = armature_obj.pose.bones
    flat = np.empty(len(pose_bones) * 16, dtype=np.float32)
    pose_bones.foreach_get("matrix", flat)
    m = flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)
    if bone_names is None:
        return m
    idx = []
    for n in bone_names:
        i = pose_bones.find(n)
        if i < 0:
            raise ValueError(f"pose_bone_matrices: no bone '{n}' in '{armature_obj.name}'")
        idx.append(i)
    return m[idx]


_structure_cache = {}  # cleared whenever joint bones are created or removed (and on file load/undo)


def forget_structures():
    """Drop the cached joint layouts (bones were re-created: same names may now have other parents)."""
    _structure_cache.clear()


_CHANNEL_SIZES = (("location", 3), ("rotation_quaternion", 4), ("scale", 3))


class _JointStructure:
    """One armature layout's joint bookkeeping: bone indices of the joints and of their parents (-1 = none),
    parent names, pose-bone indices of the joints; plus what only the rest pose decides (inv(rest_joint) @
    rest_parent, kept while the rest matrices stay the same) and, per list of given parent names, where
    each joint's parent is in it."""

    def __init__(self, armature_obj, names):
        bones = armature_obj.data.bones
        keys = tuple(bones.keys())
        position = {n: i for i, n in enumerate(keys)}
        missing = [n for n in names if n not in position]
        if missing:
            raise ValueError(f"write_joint_matrices: no bone '{missing[0]}' in '{armature_obj.name}'")
        self.index = np.array([position[n] for n in names], dtype=np.int64)
        self.parent_names = [bones[n].parent.name if bones[n].parent else None for n in names]
        self.parent_index = np.array([position[p] if p else -1 for p in self.parent_names], dtype=np.int64)
        pose_position = {n: i for i, n in enumerate(armature_obj.pose.bones.keys())}
        self.pose_index = np.array([pose_position[n] for n in names], dtype=np.int64)
        self.rest_flat = None  # Bone.matrix_local of every bone as last read (foreach_get layout)
        self.rest_part = None
        self.given = {}
        count = len(armature_obj.pose.bones)
        self.buffers = {prop: np.empty(count * n, dtype=np.float32) for prop, n in _CHANNEL_SIZES}

    def rest_to_parent(self, bones):
        """#J by 4 by 4 inv(rest_joint) @ rest_parent (rest_parent = identity for a joint without a parent),
        recomputed when the bones' rest matrices changed."""
        flat = np.empty(len(bones) * 16, dtype=np.float32)
        bones.foreach_get("matrix_local", flat)
        if self.rest_flat is None or not np.array_equal(flat, self.rest_flat):
            rest = flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)
            parent_rest = np.tile(np.eye(4), (len(self.index), 1, 1))
            has_parent = self.parent_index >= 0
            parent_rest[has_parent] = rest[self.parent_index[has_parent]]
            self.rest_part = np.linalg.inv(rest[self.index]) @ parent_rest
            self.rest_flat = flat
        return self.rest_part

    def given_positions(self, given_names):
        """#J position of each joint's parent in given_names (-1 when absent or no parent)."""
        key = tuple(given_names)
        hit = self.given.get(key)
        if hit is None:
            where = {n: i for i, n in enumerate(key)}
            hit = self.given[key] = np.array([where.get(p, -1) if p else -1 for p in self.parent_names],
                                             dtype=np.int64)
        return hit


def _joint_structure(armature_obj, names):
    """The _JointStructure of this armature's current bone layout; cached per layout (bone names are read
    each call, so adding, removing or renaming bones refreshes it)."""
    key = (armature_obj.data.as_pointer(), tuple(armature_obj.data.bones.keys()), tuple(names))
    hit = _structure_cache.get(key)
    if hit is None:
        if len(_structure_cache) > 64:
            _structure_cache.clear()
        hit = _structure_cache[key] = _JointStructure(armature_obj, names)
    return hit


def _parent_poses(armature_obj, st, parent_matrices):
    """#J by 4 by 4 posed matrix of each joint's parent (identity for none): from parent_matrices ({name:
    4 by 4}, or a pair (names, #N by 4 by 4)), else from the pose as last evaluated."""
    count = len(st.index)
    has_parent = st.parent_index >= 0
    if isinstance(parent_matrices, tuple):
        pos = st.given_positions(parent_matrices[0])
        given = np.asarray(parent_matrices[1], dtype=np.float64)
        if (pos >= 0).all():
            return given[pos]
        out = np.tile(np.eye(4), (count, 1, 1))
        out[pos >= 0] = given[pos[pos >= 0]]
        missing = has_parent & (pos < 0)
    else:
        out = np.tile(np.eye(4), (count, 1, 1))
        missing = has_parent.copy()
        for j in np.flatnonzero(has_parent):
            p = st.parent_names[j]
            if parent_matrices and p in parent_matrices:
                out[j] = parent_matrices[p]
                missing[j] = False
    if missing.any():
        out[missing] = pose_bone_matrices(armature_obj)[st.parent_index[missing]]
    return out


def write_joint_matrices(armature_obj, joint_names, joint_matrices, parent_matrices=None):
    """Pose the muscle-joint bones so that PoseBone.matrix == joint_matrices[j] (#J by 4 by 4, armature space;
    rotation times a scale in the joint's own axes, e.g. diag(s, lambda, s)). The parents' posed matrices
    come from parent_matrices ({bone name: 4 by 4}, or a pair (bone names, #N by 4 by 4), e.g. the skeleton
    pose the joints were computed from; exact and free of evaluation lag) or else from the pose as last
    evaluated. The joints' channels come from the core (pose_channels: Blender's full inheritance and
    matrix_basis decomposition); joints in quaternion rotation mode (as created) get location,
    rotation_quaternion and scale with one foreach_set each (every other bone's values are written back
    bit for bit, whatever its rotation mode), a joint in another mode gets matrix_basis. Then update_tag()."""
    _require_armature(armature_obj, "write_joint_matrices")
    names = [str(n) for n in joint_names]
    matrices = np.asarray(joint_matrices, dtype=np.float64)
    if matrices.ndim != 3 or matrices.shape[1:] != (4, 4) or matrices.shape[0] != len(names):
        raise ValueError(f"joint_matrices must be {len(names)} by 4 by 4, got shape {matrices.shape}")
    st = _joint_structure(armature_obj, names)
    channels = core_loader.core().pose_channels(st.rest_to_parent(armature_obj.data.bones),
                                                _parent_poses(armature_obj, st, parent_matrices), matrices)
    pose_bones = armature_obj.pose.bones
    modes = [pose_bones[int(i)].rotation_mode for i in st.pose_index]
    fast = None if all(m == 'QUATERNION' for m in modes) else np.array([m == 'QUATERNION' for m in modes])
    rows = st.pose_index if fast is None else st.pose_index[fast]
    if len(rows):
        for (prop, size), values in zip(_CHANNEL_SIZES, channels):
            flat = st.buffers[prop]
            pose_bones.foreach_get(prop, flat)
            flat.reshape(-1, size)[rows] = values if fast is None else values[fast]
            pose_bones.foreach_set(prop, flat)
    if fast is not None:
        location, quaternion, scale = channels
        for j in np.flatnonzero(~fast):
            pose_bones[int(st.pose_index[j])].matrix_basis = Matrix.LocRotScale(
                Vector(location[j]), Quaternion(quaternion[j]), Vector(scale[j]))
    armature_obj.update_tag()
