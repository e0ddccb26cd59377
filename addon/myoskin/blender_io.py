# SPDX-License-Identifier: GPL-3.0-or-later
"""Converters between Blender data and the core's Character (numpy + foreach_get/foreach_set).

Coordinate convention (the core's "mesh space"): the ARMATURE OBJECT'S LOCAL SPACE. This is the space
in which Blender's Armature modifier evaluates Equation 3 (vertices are taken from the mesh object into
armature space, deformed with pose_matrix @ matrix_local^-1, and taken back), so:
- bone rest matrices are Bone.matrix_local unchanged (rigid, Y along head->tail, no object scale leaks in);
- mesh vertices are the mesh object's rest coordinates (Mesh.vertices, no modifiers, no shape keys
  applied) mapped by armature.matrix_world^-1 @ mesh.matrix_world;
- when the armature object sits at the world origin with no rotation/scale (what character_to_blender
  creates, and what Blender's glTF importer creates) mesh space is world space, in metres.
Results computed by the core in mesh space go back through armature_obj.matrix_world.

A CHARACTER is the armature and every mesh it deforms (character_meshes): their vertices are taken into
the armature's space (each mesh through its own transform), concatenated and welded by position, so pieces
that meet at open boundaries join (combined_character). Extraction sees that surface in the "extraction
space": the armature's space times the armature object's (uniform) world scale, i.e. at its size in the
scene, with the armature object's rotation and translation left out (they change nothing). So an FBX/Mixamo
export whose armature object is scaled x100 or x0.01 is analysed at its real size (extraction's options are
relative to the body: section spacing in limb radii). Muscles come back to the armature's space by 1/scale.

Only this module (and the operators/panels) touch bpy; the algorithms live in the core.
"""
import math
from contextlib import contextmanager

import bpy
import numpy as np
from mathutils import Matrix

from . import core_loader

# ------------------------------------------------------------------------------------------------
# Lookups
# ------------------------------------------------------------------------------------------------


def find_armature(obj):
    """The armature that deforms `obj`: itself if it is one, else the object of its first Armature
    modifier, else its parent if that is an armature. None when there is none."""
    if obj is None:
        return None
    if obj.type == 'ARMATURE':
        return obj
    for mod in getattr(obj, "modifiers", ()):
        if mod.type == 'ARMATURE' and mod.object is not None:
            return mod.object
    if obj.parent is not None and obj.parent.type == 'ARMATURE':
        return obj.parent
    return None


def find_skin_meshes(armature_obj):
    """Mesh objects deformed by `armature_obj` (Armature modifier or armature parent)."""
    return [o for o in bpy.data.objects if o.type == 'MESH' and find_armature(o) == armature_obj]


def resolve_skinned_mesh(obj):
    """(mesh_obj, armature_obj) for the active object: a skinned mesh, or an armature with one skin.
    Raises ValueError with a message for the user otherwise."""
    if obj is None:
        raise ValueError("No active object: select a skinned mesh (a mesh with an Armature modifier)")
    if obj.type == 'ARMATURE':
        meshes = find_skin_meshes(obj)
        if not meshes:
            raise ValueError(f"Armature '{obj.name}' deforms no mesh: add an Armature modifier to the skin")
        return meshes[0], obj
    if obj.type != 'MESH':
        raise ValueError(f"Active object '{obj.name}' is a {obj.type.lower()}, not a mesh: select the skin")
    arm = find_armature(obj)
    if arm is None:
        raise ValueError(f"Mesh '{obj.name}' has no armature: add an Armature modifier or parent it to "
                         f"an armature")
    return obj, arm


def require_weights(mesh_obj, arm_obj):
    """ValueError when no vertex group of the mesh names a deform bone of the armature (not skinned)."""
    bones = arm_obj.data.bones
    if not any(g.name in bones and bones[g.name].use_deform for g in mesh_obj.vertex_groups):
        raise ValueError(f"Mesh '{mesh_obj.name}' is not skinned: none of its vertex groups is a deform bone "
                         f"of '{arm_obj.name}' (weight-paint it or use Parent > With Automatic Weights)")


def has_weights(mesh_obj, arm_obj):
    """True when a vertex group of the mesh names a deform bone of the armature (the mesh is skinned)."""
    bones = arm_obj.data.bones
    return any(g.name in bones and bones[g.name].use_deform and not bones[g.name].get("myoskin_joint")
               for g in mesh_obj.vertex_groups)


def character_meshes(armature_obj):
    """(meshes, skipped) of the character an armature makes: the mesh objects it deforms (Armature modifier
    or armature parent; muscle surfaces and locators left out), by name. `skipped` lists (mesh, why) for
    those that cannot be part of it (no vertex group of a deform bone, no vertices)."""
    meshes, skipped = [], []
    for o in sorted(find_skin_meshes(armature_obj), key=lambda o: o.name):
        if o.get("myoskin_muscle") is not None:
            continue
        if len(o.data.vertices) == 0 or len(o.data.polygons) == 0:
            skipped.append((o, "no faces"))
        elif not has_weights(o, armature_obj):
            skipped.append((o, "no weights of its bones"))
        else:
            meshes.append(o)
    return meshes, skipped


def resolve_character(obj):
    """(meshes, armature, skipped) for the active object: a skinned mesh alone ([mesh]), or an armature with
    every mesh it deforms (the whole character; `skipped` names the meshes left out and why). Raises
    ValueError with a message for the user otherwise."""
    if obj is not None and obj.type == 'ARMATURE':
        meshes, skipped = character_meshes(obj)
        if not meshes:
            if skipped:
                raise ValueError(f"Armature '{obj.name}' deforms no skinned mesh: "
                                 + "; ".join(f"'{o.name}' has {why}" for o, why in skipped)
                                 + " (weight-paint them or use Parent > With Automatic Weights)")
            raise ValueError(f"Armature '{obj.name}' deforms no mesh: add an Armature modifier to the skin")
        return meshes, obj, skipped
    mesh_obj, arm = resolve_skinned_mesh(obj)
    require_weights(mesh_obj, arm)
    return [mesh_obj], arm, []


def _linked(id_block):
    """The library an ID comes from (read-only here), else None."""
    return getattr(id_block, "library", None) if id_block is not None else None


def require_editable(obj):
    """ValueError when the character of `obj` (the object, its armature and the meshes that armature deforms,
    and their data) is linked from a library: read-only, so nothing of it can change here."""
    if obj is None:
        return
    arm = find_armature(obj)
    if arm is None and obj.parent is not None and obj.parent.type == 'ARMATURE':
        arm = obj.parent
    objects = [obj] + ([arm] + find_skin_meshes(arm) if arm is not None else [])
    for o in objects:
        for block in (o, o.data):
            library = _linked(block)
            if library is not None:
                kind = "Object" if block == o else f"The data of '{o.name}',"
                name = f" '{o.name}'" if block == o else ""
                raise ValueError(f"{kind}{name} is linked from the library '{library.filepath}' (read-only): make "
                                 f"the character local (Object > Relations > Make Local) or add a Library "
                                 f"Override to change it")


def armature_scale(armature_obj):
    """The armature object's uniform world scale (the cube root of its matrix's determinant, so a
    non-uniform scale gives its geometric mean)."""
    det = abs(float(armature_obj.matrix_world.to_3x3().determinant()))
    if not det > 0.0:
        raise ValueError(f"Armature '{armature_obj.name}' has a zero scale")
    return det ** (1.0 / 3.0)


def skipped_message(skipped):
    """' (skipped A: why; B: why)' for a report, '' when nothing was skipped."""
    if not skipped:
        return ""
    return " (skipped " + "; ".join(f"{o.name}: {why}" for o, why in skipped) + ")"


# ------------------------------------------------------------------------------------------------
# Small numpy helpers
# ------------------------------------------------------------------------------------------------


def _matrix_to_numpy(m):
    return np.array([list(row) for row in m], dtype=np.float64)


def _transform_points(m, points):
    """Apply a 4x4 numpy matrix to #N by 3 points."""
    return points @ m[:3, :3].T + m[:3, 3]


def mesh_to_armature_matrix(mesh_obj, armature_obj):
    """4x4 numpy matrix taking the mesh object's local coordinates to armature space (mesh space);
    ValueError when the armature object's matrix cannot be inverted (a zero scale)."""
    world = armature_obj.matrix_world
    if not abs(world.to_3x3().determinant()) > 1e-30 or not all(math.isfinite(x) for row in world for x in row):
        raise ValueError(f"Armature '{armature_obj.name}' has a zero scale (or a transform that is not finite): "
                         f"give its object a non-zero scale")
    return _matrix_to_numpy(world.inverted() @ mesh_obj.matrix_world)


def mesh_vertices(mesh):
    """#V by 3 float64 rest coordinates of a Mesh datablock (object space)."""
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def mesh_triangles(mesh):
    """#F by 3 int32 triangles of a Mesh datablock (its loop triangulation)."""
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return tris.reshape(-1, 3)


def evaluated_vertices(mesh_obj, armature_obj=None, depsgraph=None):
    """#V by 3 float64 positions of the evaluated mesh (modifiers applied), in the armature's space when
    armature_obj is given, else in the mesh object's space."""
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    evaluated = mesh_obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        points = mesh_vertices(mesh)
    finally:
        evaluated.to_mesh_clear()
    if armature_obj is not None:
        points = _transform_points(mesh_to_armature_matrix(mesh_obj, armature_obj), points)
    return points


def bone_order(bones):
    """Indices of `bones` (an armature's bone collection) with every parent before its children,
    keeping the collection's order where it already satisfies that."""
    index = {b.name: i for i, b in enumerate(bones)}
    order, placed = [], set()

    def place(i):
        if i in placed:
            return
        parent = bones[i].parent
        if parent is not None:
            place(index[parent.name])
        placed.add(i)
        order.append(i)

    for i in range(len(bones)):
        place(i)
    return order


def bone_rest_matrices(bones):
    """#B by 4 by 4 Bone.matrix_local in collection order (foreach_get gives column-major)."""
    flat = np.empty(len(bones) * 16, dtype=np.float32)
    bones.foreach_get("matrix_local", flat)
    return flat.reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)


def read_vertex_weights(mesh_obj, group_to_bone, num_vertices):
    """(#V by K int32 bone indices with -1 for empty, #V by K float64 weights) from the vertex groups
    that map to bones (group_to_bone: vertex group index -> bone index), strongest first.

    Blender has no bulk accessor for per-vertex group memberships, so this is the one Python loop
    over vertices in the converters (about 10 ms per 10k vertices)."""
    rows, cols, vals = [], [], []
    for v in mesh_obj.data.vertices:
        for g in v.groups:
            b = group_to_bone.get(g.group)
            if b is not None and g.weight > 0.0:
                rows.append(v.index)
                cols.append(b)
                vals.append(g.weight)
    if not rows:
        return np.zeros((0, 0), dtype=np.int32), np.zeros((0, 0), dtype=np.float64)
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int32)
    vals = np.asarray(vals, dtype=np.float64)
    # Sort by vertex, then by decreasing weight; slot k = rank within the vertex.
    order = np.lexsort((-vals, rows))
    rows, cols, vals = rows[order], cols[order], vals[order]
    counts = np.bincount(rows, minlength=num_vertices)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    slot = np.arange(len(rows)) - starts[rows]
    k = int(counts.max())
    joints = np.full((num_vertices, k), -1, dtype=np.int32)
    weights = np.zeros((num_vertices, k), dtype=np.float64)
    joints[rows, slot] = cols
    weights[rows, slot] = vals
    return joints, weights


def add_group_weights(group, vertex_ids, weights):
    """Add vertices with their weights to one vertex group (REPLACE): VertexGroup.add takes one weight for many
    vertices, so vertices are batched by equal weight."""
    ids = np.asarray(vertex_ids, dtype=np.int64)
    ws = np.asarray(weights, dtype=np.float64)
    order = np.argsort(ws, kind="stable")
    ids, ws = ids[order], ws[order]
    breaks = np.flatnonzero(np.diff(ws) != 0) + 1
    for a, b in zip(np.concatenate(([0], breaks)), np.concatenate((breaks, [len(ws)]))):
        if b > a:
            group.add(ids[a:b].tolist(), float(ws[a]), 'REPLACE')


def vertex_group_weights(mesh_obj, name):
    """#V float64 weights of one vertex group (0 for vertices outside it; all 0 without the group)."""
    out = np.zeros(len(mesh_obj.data.vertices))
    group = mesh_obj.vertex_groups.get(name)
    if group is None:
        return out
    index = group.index
    for v in mesh_obj.data.vertices:
        for g in v.groups:
            if g.group == index:
                out[v.index] = g.weight
                break
    return out


# ------------------------------------------------------------------------------------------------
# Blender -> core
# ------------------------------------------------------------------------------------------------


def character_from_blender(mesh_obj, armature_obj=None, name=None):
    """A core Character from a skinned mesh object and its armature, at rest, in the armature's space
    (see the module docstring). Weights come from vertex groups named after deform bones; muscle-joint
    bones (tagged "myoskin_joint") and their groups are left out, so the skeleton is the character's own."""
    core = core_loader.core()
    if mesh_obj is None or mesh_obj.type != 'MESH':
        raise ValueError(f"character_from_blender: {getattr(mesh_obj, 'name', None)!r} is not a mesh object")
    armature_obj = armature_obj or find_armature(mesh_obj)
    if armature_obj is None or armature_obj.type != 'ARMATURE':
        raise ValueError(f"character_from_blender: mesh '{mesh_obj.name}' has no armature")
    if mesh_obj.mode == 'EDIT':  # edit-mode changes live in the BMesh until synced
        mesh_obj.update_from_editmode()
    mesh = mesh_obj.data
    bones = armature_obj.data.bones
    if len(bones) == 0:
        raise ValueError(f"character_from_blender: armature '{armature_obj.name}' has no bones")

    vertices = _transform_points(mesh_to_armature_matrix(mesh_obj, armature_obj), mesh_vertices(mesh))
    triangles = mesh_triangles(mesh)

    # Muscle-joint bones (rig_io tags them "myoskin_joint") are not part of the skeleton.
    order = [i for i in bone_order(bones) if not bones[i].get("myoskin_joint")]
    position = {old: new for new, old in enumerate(order)}
    names = [bones[i].name for i in order]
    parents = np.array([position[bones.find(bones[i].parent.name)] if bones[i].parent else -1 for i in order],
                       dtype=np.int32)
    heads = np.empty(len(bones) * 3, dtype=np.float32)
    tails = np.empty(len(bones) * 3, dtype=np.float32)
    bones.foreach_get("head_local", heads)
    bones.foreach_get("tail_local", tails)
    heads = heads.reshape(-1, 3)[order].astype(np.float64)
    tails = tails.reshape(-1, 3)[order].astype(np.float64)
    rest = bone_rest_matrices(bones)[order]

    bone_index = {n: i for i, n in enumerate(names)}
    group_to_bone = {g.index: bone_index[g.name] for g in mesh_obj.vertex_groups
                     if g.name in bone_index and bones[g.name].use_deform}
    joints, weights = read_vertex_weights(mesh_obj, group_to_bone, len(mesh.vertices))

    return core.character_from_arrays(name or mesh_obj.name, vertices, triangles, names, parents, heads, tails,
                                      np.ascontiguousarray(rest), joints, weights)


# ------------------------------------------------------------------------------------------------
# core -> Blender
# ------------------------------------------------------------------------------------------------


@contextmanager
def object_mode(obj, mode):
    """Temporarily make `obj` active and switch it to `mode` ('EDIT', 'POSE'); works in background mode.
    The object must be in the current view layer."""
    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    if previous is not None and previous.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    try:  # (view_layer.objects syncs lazily after a link; setting the active object syncs it)
        view_layer.objects.active = obj
    except (ValueError, RuntimeError, TypeError):
        pass
    if view_layer.objects.active != obj:
        raise RuntimeError(f"'{obj.name}' is not in the view layer '{view_layer.name}': link its collection "
                           f"to the scene to edit it")
    bpy.ops.object.mode_set(mode=mode)
    try:
        yield obj
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
        view_layer.objects.active = previous


def _new_mesh(name, vertices, triangles):
    mesh = bpy.data.meshes.new(name)
    nv, nf = len(vertices), len(triangles)
    mesh.vertices.add(nv)
    mesh.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(3 * nf)
    mesh.loops.foreach_set("vertex_index", np.ascontiguousarray(triangles, dtype=np.int32).ravel())
    mesh.polygons.add(nf)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * nf, 3, dtype=np.int32))
    try:  # read-only (derived from loop_start) from Blender 4.0 on
        mesh.polygons.foreach_set("loop_total", np.full(nf, 3, dtype=np.int32))
    except (AttributeError, TypeError, RuntimeError):
        pass
    mesh.update(calc_edges=True)
    mesh.polygons.foreach_set("use_smooth", np.ones(nf, dtype=bool))
    return mesh


def write_vertex_weights(mesh_obj, bone_names, joints, weights):
    """One vertex group per bone filled from #V by K joints/weights (a group of that name already there is
    added to, in its place; on a mesh without groups, group index = bone index). VertexGroup.add takes one
    weight for many vertices, so vertices are batched by equal weight."""
    groups = [mesh_obj.vertex_groups.get(n) or mesh_obj.vertex_groups.new(name=n) for n in bone_names]
    joints = np.asarray(joints)
    weights = np.asarray(weights, dtype=np.float64)
    if joints.size == 0:
        return groups
    vertex_ids = np.broadcast_to(np.arange(joints.shape[0])[:, None], joints.shape)
    used = (joints >= 0) & (weights > 0.0)
    js, vs, ws = joints[used], vertex_ids[used], weights[used].astype(np.float32)
    order = np.lexsort((ws, js))
    js, vs, ws = js[order], vs[order], ws[order]
    # Runs of equal (bone, weight) -> one add() call each.
    breaks = np.flatnonzero((np.diff(js) != 0) | (np.diff(ws) != 0)) + 1
    for start, stop in zip(np.concatenate(([0], breaks)), np.concatenate((breaks, [len(js)]))):
        groups[js[start]].add(vs[start:stop].tolist(), float(ws[start]), 'ADD')
    return groups


def character_to_blender(character, name=None, collection=None, rest_tolerance=1e-5):
    """Build (armature_obj, mesh_obj) from a core Character at the world origin.

    Bones reproduce bone_rest exactly (edit_bone.matrix = rest, then Bone.matrix_local is checked
    against it; RuntimeError beyond rest_tolerance, e.g. for a rest matrix with scale), the mesh gets one
    vertex group per bone from the weights, a linear Armature modifier (no preserve volume, no
    envelopes) and the armature as parent."""
    name = name or character.name or "Character"
    collection = collection or bpy.context.scene.collection
    names = list(character.bone_names)
    parents = np.asarray(character.bone_parents)
    heads = np.asarray(character.bone_heads, dtype=np.float64)
    tails = np.asarray(character.bone_tails, dtype=np.float64)
    rest = np.asarray(character.bone_rest, dtype=np.float64)

    arm_data = bpy.data.armatures.new(name + "_rig")
    arm_obj = bpy.data.objects.new(name + "_rig", arm_data)
    collection.objects.link(arm_obj)
    arm_data.display_type = 'OCTAHEDRAL'
    arm_obj.show_in_front = True

    with object_mode(arm_obj, 'EDIT'):
        edit_bones = arm_data.edit_bones
        created = []
        for i, bone_name in enumerate(names):
            eb = edit_bones.new(bone_name)
            eb.head = heads[i]
            eb.tail = tails[i]
            eb.matrix = Matrix(rest[i].tolist())  # keeps the length, sets head, direction and roll
            eb.use_deform = True
            created.append(eb)
        for i, p in enumerate(parents):
            if p >= 0:
                created[i].parent = created[p]
                if np.linalg.norm(heads[i] - tails[p]) < 1e-9:
                    created[i].use_connect = True

    bones = arm_data.bones
    actual = bone_rest_matrices(bones)
    for i, bone_name in enumerate(names):
        err = float(np.abs(actual[bones.find(bone_name)] - rest[i]).max())
        if err > rest_tolerance:
            raise RuntimeError(f"character_to_blender: bone '{bone_name}' rest matrix differs from the core's "
                               f"by {err:.3g} (a rest matrix must be rigid: rotation and translation only)")

    mesh = _new_mesh(name, np.asarray(character.vertices), np.asarray(character.triangles))
    mesh_obj = bpy.data.objects.new(name, mesh)
    collection.objects.link(mesh_obj)
    mesh_obj.parent = arm_obj
    mesh_obj.matrix_parent_inverse = Matrix.Identity(4)
    write_vertex_weights(mesh_obj, names, character.weight_joints, character.weight_values)
    mod = mesh_obj.modifiers.new("Armature", 'ARMATURE')
    mod.object = arm_obj
    mod.use_vertex_groups = True
    mod.use_bone_envelopes = False
    mod.use_deform_preserve_volume = False
    mod.use_multi_modifier = False
    return arm_obj, mesh_obj


# ------------------------------------------------------------------------------------------------
# Display helpers
# ------------------------------------------------------------------------------------------------


def parent_to_bone(obj, armature_obj, bone_name):
    """Parent `obj` to a bone keeping its current world placement (the armature must be at rest)."""
    bone = armature_obj.data.bones[bone_name]
    obj.parent = armature_obj
    obj.parent_type = 'BONE'
    obj.parent_bone = bone_name
    # A bone child hangs off the bone's tail in the bone's rest frame.
    tail_frame = armature_obj.matrix_world @ bone.matrix_local @ Matrix.Translation((0.0, bone.length, 0.0))
    obj.matrix_parent_inverse = tail_frame.inverted()


def truth_to_curves(truth, collection=None, material=None, armature_obj=None, prefix="truth_",
                    bevel_resolution=4):
    """One curve object per ground-truth muscle (dicts with name, bone, center_line #N by 3, radius #N,
    as make_synthetic_arm returns): a poly spline along the centre line whose bevel follows the radius,
    so it renders as a tube. With armature_obj, each tube is parented to its bone (rigid display only).
    Points are taken in the armature's space when given, else in world space."""
    collection = collection or bpy.context.scene.collection
    to_world = _matrix_to_numpy(armature_obj.matrix_world) if armature_obj is not None else np.eye(4)
    objects = []
    for muscle in truth:
        line = _transform_points(to_world, np.asarray(muscle["center_line"], dtype=np.float64))
        radius = np.asarray(muscle["radius"], dtype=np.float64)
        curve = bpy.data.curves.new(prefix + muscle["name"], 'CURVE')
        curve.dimensions = '3D'
        curve.bevel_depth = 1.0  # point radius = tube radius in metres
        curve.bevel_resolution = bevel_resolution
        curve.use_fill_caps = True
        spline = curve.splines.new('POLY')
        spline.points.add(len(line) - 1)
        co = np.hstack([line, np.ones((len(line), 1))]).astype(np.float32)
        spline.points.foreach_set("co", co.ravel())
        spline.points.foreach_set("radius", radius.astype(np.float32))
        obj = bpy.data.objects.new(prefix + muscle["name"], curve)
        if material is not None:
            curve.materials.append(material)
        collection.objects.link(obj)
        if armature_obj is not None and muscle.get("bone") in armature_obj.data.bones:
            parent_to_bone(obj, armature_obj, muscle["bone"])
        objects.append(obj)
    return objects


def muscles_to_meshes(muscles, collection=None, material=None, armature_obj=None, prefix=""):
    """One mesh object per core Muscle from its lofted surface (surface_vertices #V by 3 in the character's
    mesh space, surface_triangles #F by 3). With armature_obj, positions are taken in the armature's space
    and each muscle is parented to its origin bone (rigid display until muscle deformation drives it)."""
    collection = collection or bpy.context.scene.collection
    to_world = _matrix_to_numpy(armature_obj.matrix_world) if armature_obj is not None else np.eye(4)
    objects = []
    for muscle in muscles:
        vertices = np.asarray(muscle.surface_vertices, dtype=np.float64)
        if len(vertices) == 0:
            continue
        mesh = _new_mesh(prefix + muscle.name, _transform_points(to_world, vertices), muscle.surface_triangles)
        if material is not None:
            mesh.materials.append(material)
        obj = bpy.data.objects.new(prefix + muscle.name, mesh)
        obj["myoskin_region"] = muscle.region
        obj["myoskin_confidence"] = float(muscle.confidence)
        collection.objects.link(obj)
        if armature_obj is not None and muscle.origin_bone in armature_obj.data.bones:
            parent_to_bone(obj, armature_obj, muscle.origin_bone)
        objects.append(obj)
    return objects


# ------------------------------------------------------------------------------------------------
# Welded characters (extraction needs a closed skin; Blender splits vertices at UV seams)
# ------------------------------------------------------------------------------------------------


class CombinedCharacter:
    """Several meshes of one armature as one core Character (armature space, welded by position).

    meshes        the mesh objects, in order; their vertices are concatenated in that order
    offsets       #meshes + 1: mesh k's vertices are rows offsets[k]:offsets[k+1] of the concatenation
    weld_map      #concatenated vertices -> welded vertex (the character's vertex)
    character     the core Character (welded; weights of a welded vertex are those of its first vertex)
    """

    def __init__(self, meshes, character, weld_map, offsets):
        self.meshes = list(meshes)
        self.character = character
        self.weld_map = np.asarray(weld_map, dtype=np.int64)
        self.offsets = list(offsets)

    @property
    def num_vertices(self):
        return self.character.num_vertices

    def rows(self, k):
        """Welded vertex of every vertex of mesh k (#V_k)."""
        return self.weld_map[self.offsets[k]:self.offsets[k + 1]]

    def split(self, array):
        """Per-mesh rows of a #welded-rows array: [array[rows(k)] for every mesh]."""
        array = np.asarray(array)
        return [array[self.rows(k)] for k in range(len(self.meshes))]

    def source_meshes(self, welded):
        """The mesh object each welded vertex index of `welded` comes from (its first Blender vertex's)."""
        _values, first = np.unique(self.weld_map, return_index=True)  # every welded vertex occurs
        rows = first[np.asarray(welded, dtype=np.int64)]
        return [self.meshes[int(np.searchsorted(self.offsets, r, side='right')) - 1] for r in rows]

    def mask(self, masks):
        """#welded booleans from one #V_k boolean mask per mesh (None = none of that mesh's vertices)."""
        out = np.zeros(self.num_vertices, dtype=bool)
        for k, m in enumerate(masks):
            if m is not None:
                out[self.rows(k)[np.asarray(m, dtype=bool)]] = True
        return out


WELD_RELATIVE = 1e-4  # weld tolerance, relative to the median edge length (~1e-6 m on a 13k-vertex body)


def _median_edge(vertices, triangles):
    if len(triangles) == 0:
        return 0.0
    t = np.asarray(triangles)
    v = np.asarray(vertices)
    edges = np.concatenate([v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 1]], v[t[:, 0]] - v[t[:, 2]]])
    return float(np.median(np.linalg.norm(edges, axis=1)))


def combined_character(meshes, armature_obj, name=None, weld=True):
    """A CombinedCharacter: every mesh at rest in the armature's space (each through its own transform),
    concatenated, with the skeleton of the armature; welded by position when `weld` (vertices closer than
    WELD_RELATIVE x the median edge length merge, so UV seams and pieces meeting at open boundaries
    join)."""
    core = core_loader.core()
    meshes = list(meshes)
    if not meshes:
        raise ValueError("No mesh to build the character from")
    parts = [character_from_blender(m, armature_obj) for m in meshes]
    offsets = np.concatenate(([0], np.cumsum([p.num_vertices for p in parts]))).tolist()
    vertices = np.concatenate([np.asarray(p.vertices) for p in parts])
    triangles = np.concatenate([np.asarray(p.triangles) + offsets[k] for k, p in enumerate(parts)])
    k_max = max((np.asarray(p.weight_joints).shape[1] if np.asarray(p.weight_joints).size else 0) for p in parts)
    joints = np.full((len(vertices), k_max), -1, dtype=np.int32)
    weights = np.zeros((len(vertices), k_max), dtype=np.float64)
    for k, p in enumerate(parts):
        pj, pw = np.asarray(p.weight_joints), np.asarray(p.weight_values)
        if pj.size:
            joints[offsets[k]:offsets[k + 1], :pj.shape[1]] = pj
            weights[offsets[k]:offsets[k + 1], :pw.shape[1]] = pw
    weld_map = np.arange(len(vertices), dtype=np.int64)
    if weld:
        tolerance = WELD_RELATIVE * _median_edge(vertices, triangles)
        welded_v, welded_t, weld_map = core.weld_mesh(vertices, triangles, tolerance)
        weld_map = np.asarray(weld_map, dtype=np.int64)
        if len(welded_v) != len(vertices):
            _, first = np.unique(weld_map, return_index=True)
            vertices, triangles = np.asarray(welded_v), np.asarray(welded_t)
            if k_max:
                joints, weights = joints[first], weights[first]
    first = parts[0]
    character = core.character_from_arrays(
        name or (meshes[0].name if len(meshes) == 1 else armature_obj.name), vertices,
        np.ascontiguousarray(triangles, dtype=np.int32), list(first.bone_names), np.asarray(first.bone_parents),
        np.asarray(first.bone_heads), np.asarray(first.bone_tails), np.asarray(first.bone_rest),
        np.ascontiguousarray(joints), np.ascontiguousarray(weights))
    return CombinedCharacter(meshes, character, weld_map, offsets)


def scaled_character(character, scale):
    """The same core Character with every position multiplied by `scale` (vertices, bone heads and tails,
    the translations of the rest matrices): the extraction space (module docstring)."""
    if scale == 1.0:
        return character
    rest = np.array(character.bone_rest, dtype=np.float64)
    rest[:, :3, 3] *= scale
    return core_loader.core().character_from_arrays(
        character.name, np.asarray(character.vertices) * scale, np.asarray(character.triangles),
        list(character.bone_names), np.asarray(character.bone_parents), np.asarray(character.bone_heads) * scale,
        np.asarray(character.bone_tails) * scale, np.ascontiguousarray(rest),
        np.ascontiguousarray(np.asarray(character.weight_joints)),
        np.ascontiguousarray(np.asarray(character.weight_values)))


def welded_mask(mask, weld_map, num_welded):
    """#W booleans: a welded vertex is in the mask when any of its Blender vertices is."""
    out = np.zeros(num_welded, dtype=bool)
    out[weld_map[np.asarray(mask, dtype=bool)]] = True
    return out


def selected_vertex_mask(mesh_obj, faces=False):
    """#V booleans of the selected vertices (or of the vertices of selected faces), edit mode included."""
    if mesh_obj.mode == 'EDIT':
        mesh_obj.update_from_editmode()
    mesh = mesh_obj.data
    if faces:
        sel = np.zeros(len(mesh.polygons), dtype=bool)
        mesh.polygons.foreach_get("select", sel)
        mask = np.zeros(len(mesh.vertices), dtype=bool)
        if sel.any():
            loops = np.empty(len(mesh.loops), dtype=np.int32)
            mesh.loops.foreach_get("vertex_index", loops)
            starts = np.empty(len(mesh.polygons), dtype=np.int32)
            totals = np.empty(len(mesh.polygons), dtype=np.int32)
            mesh.polygons.foreach_get("loop_start", starts)
            mesh.polygons.foreach_get("loop_total", totals)
            idx = np.concatenate([np.arange(s, s + t) for s, t in zip(starts[sel], totals[sel])])
            mask[loops[idx]] = True
        return mask
    mask = np.zeros(len(mesh.vertices), dtype=bool)
    mesh.vertices.foreach_get("select", mask)
    return mask


def vertex_group_mask(mesh_obj, group_name, threshold=0.0):
    """#V booleans of the vertices in a vertex group with weight > threshold; ValueError when missing."""
    group = mesh_obj.vertex_groups.get(group_name)
    if group is None:
        raise ValueError(f"Mesh '{mesh_obj.name}' has no vertex group '{group_name}'")
    mask = np.zeros(len(mesh_obj.data.vertices), dtype=bool)
    gi = group.index
    for v in mesh_obj.data.vertices:
        for g in v.groups:
            if g.group == gi and g.weight > threshold:
                mask[v.index] = True
    return mask
