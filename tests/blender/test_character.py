# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: a character is the armature and every mesh it deforms, whatever the object transforms.

Asserts, on the synthetic arm built several ways in Blender (armature object scaled x100 / x0.01 with its data
scaled to match, as FBX and Mixamo exports are; armature rotated and translated; a mesh with its own
transform; the skin split into three meshes that meet at open boundaries): the same muscles as the plain
character (count and names equal, root curves equal in the scene to 1 % of the limb radius); Extract with
the armature active uses every mesh, with a mesh active that mesh alone; Bind writes weights to every mesh,
keeps the rest pose exact (1e-6 of the character's size), Blender equals the core's Equation 3 on every mesh
and the seams stay closed when posed; Unbind restores every mesh exactly; PC2 writes one file per mesh;
clear messages for an armature deforming no mesh, a mesh without weights among several, no active object.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_character.py
"""
import json
import os
import sys
import tempfile

import bpy
import numpy as np
from mathutils import Matrix

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, operator_error  # noqa: E402

TMP = tempfile.mkdtemp(prefix="myoskin_test_character_")
# An object transform with rotation, translation and scale (a mesh's own placement under the armature).
MESH_TRANSFORM = Matrix.Translation((0.3, -0.2, 0.1)) @ Matrix.Rotation(0.7, 4, (1.0, 2.0, 0.5)) @ \
    Matrix.Scale(2.5, 4)
ARM_TRANSFORM = Matrix.Translation((1.5, 2.0, -0.7)) @ Matrix.Rotation(1.1, 4, (0.3, -1.0, 0.4))


def np_matrix(m):
    return np.array([list(row) for row in m], dtype=np.float64)


def transform(m, points):
    m = np_matrix(m) if not isinstance(m, np.ndarray) else m
    return np.asarray(points, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]


def world_vertices(obj, evaluated=True):
    """#V by 3 world positions of a mesh (evaluated: modifiers applied)."""
    bpy.context.view_layer.update()
    io = module("blender_io")
    local = io.evaluated_vertices(obj) if evaluated else io.mesh_vertices(obj.data)
    return transform(obj.matrix_world, local)


def new_scene():
    bpy.ops.wm.read_homefile(use_empty=True)


def build(name, scale=1.0, arm_matrix=None, mesh_matrix=None):
    """The synthetic arm (seed 1) in Blender with its data scaled by 1/scale and the armature object scaled
    by `scale` (so it has its plain size in the scene), optionally a rotated/translated armature and a mesh
    with its own transform (its vertices mapped so that the skin stays where it was). (arm, mesh)."""
    io = module("blender_io")
    character, _truth = core().make_synthetic_arm(seed=1)
    arm, mesh = io.character_to_blender(io.scaled_character(character, 1.0 / scale), name)
    arm.matrix_world = (arm_matrix or Matrix.Identity(4)) @ Matrix.Scale(scale, 4)
    if mesh_matrix is not None:
        set_own_transform(mesh, mesh_matrix)
    bpy.context.view_layer.update()
    return arm, mesh


def set_own_transform(mesh, matrix):
    """Give a mesh parented to its armature the local transform `matrix`, keeping every vertex in place."""
    co = module("blender_io").mesh_vertices(mesh.data)
    mesh.data.vertices.foreach_set("co", transform(matrix.inverted(), co).astype(np.float32).ravel())
    mesh.data.update()
    mesh.matrix_basis = matrix


def split_mesh(mesh, parts):
    """Split a mesh object into len(parts) objects by face: part k gets the faces whose first vertex's
    strongest bone is in parts[k] (a set of bone names). Each part has its own vertices (the ones on a cut
    are duplicated, so the pieces meet at open boundaries), its vertex groups, the Armature modifier and the
    parent. Returns the new objects (the original is removed)."""
    io = module("blender_io")
    co = io.mesh_vertices(mesh.data)
    tris = io.mesh_triangles(mesh.data)
    names = [g.name for g in mesh.vertex_groups]
    groups = {g.index: g.name for g in mesh.vertex_groups}
    rows = [[(groups[g.group], g.weight) for g in v.groups] for v in mesh.data.vertices]
    strongest = np.array([names.index(max(r, key=lambda gw: gw[1])[0]) for r in rows])
    arm, basis = mesh.parent, mesh.matrix_basis.copy()
    out = []
    assert parts
    for k, bones in enumerate(parts):
        keep = np.array([names[strongest[t[0]]] in bones for t in tris])
        assert keep.any(), f"part {k} ({bones}) has no faces"
        used = np.unique(tris[keep])
        remap = np.full(len(co), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        data = io._new_mesh(f"{mesh.name}.part{k}", co[used], remap[tris[keep]])
        obj = bpy.data.objects.new(f"{mesh.name}.part{k}", data)
        bpy.context.scene.collection.objects.link(obj)
        obj.parent = arm
        obj.matrix_parent_inverse = Matrix.Identity(4)
        obj.matrix_basis = basis
        vgs = [obj.vertex_groups.new(name=n) for n in names]
        for new, old in enumerate(used):
            for name, w in rows[old]:
                vgs[names.index(name)].add([new], w, 'REPLACE')
        mod = obj.modifiers.new("Armature", 'ARMATURE')
        mod.object = arm
        out.append(obj)
    bpy.data.objects.remove(mesh)
    return out


def extract(active):
    bpy.context.view_layer.objects.active = active
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm = active if active.type == 'ARMATURE' else active.parent
    return arm


def world_curves(arm):
    """{muscle name: #N by 3 root curve in the scene} of an armature's muscles."""
    curves = {}
    for item in arm.myoskin.muscles:
        m = json.loads(item.data)["muscles"][0]
        curves[item.name] = transform(arm.matrix_world, m["root_curve"])
    return curves


def limb_radius(character):
    """Median distance of the skin to its nearest bone segment: the limb's radius."""
    v = np.asarray(character.vertices)
    heads, tails = np.asarray(character.bone_heads), np.asarray(character.bone_tails)
    best = np.full(len(v), np.inf)
    for h, t in zip(heads, tails):
        d = t - h
        s = np.clip((v - h) @ d / max(d @ d, 1e-30), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(v - (h + s[:, None] * d), axis=1))
    return float(np.median(best))


_reference = {}


def reference():
    """(world root curves, limb radius, character size) of the plain synthetic arm, extracted once."""
    if not _reference:
        new_scene()
        arm, mesh = build("Plain")
        character = module("blender_io").character_from_blender(mesh, arm)
        extract(mesh)
        curves = world_curves(arm)
        assert len(curves) == 6, f"the plain arm gave {len(curves)} muscles"  # seed 1's six, as the core tiers
        size = float(np.ptp(np.asarray(character.vertices), axis=0).max())
        _reference.update(curves=curves, radius=limb_radius(character), size=size)
    return _reference["curves"], _reference["radius"], _reference["size"]


def assert_same_muscles(curves, what, placement=None):
    """The muscles (world root curves) equal the plain arm's once the character's placement in the scene
    (a rigid motion: the armature object's rotation and translation) is undone."""
    ref, radius, _size = reference()
    if placement is not None:
        curves = {k: transform(placement.inverted(), v) for k, v in curves.items()}
    assert sorted(curves) == sorted(ref), f"{what}: muscles {sorted(curves)} != plain {sorted(ref)}"
    worst = 0.0
    for name, points in curves.items():
        assert points.shape == ref[name].shape, f"{what}: {name} has {len(points)} root points, plain " \
                                                f"{len(ref[name])}"
        worst = max(worst, float(np.linalg.norm(points - ref[name], axis=1).max()))
    assert worst < 0.01 * radius, f"{what}: root curves differ by {worst:.3g} (1 % of the limb radius: " \
                                  f"{0.01 * radius:.3g})"
    return worst


# ------------------------------------------------------------------------------------------------
# Object transforms
# ------------------------------------------------------------------------------------------------

def test_same_muscles_whatever_the_object_transforms():
    reference()
    worst = {}
    for what, kwargs in (("armature x100", dict(scale=100.0)), ("armature x0.01", dict(scale=0.01)),
                         ("armature rotated and translated", dict(arm_matrix=ARM_TRANSFORM)),
                         ("mesh with its own transform", dict(mesh_matrix=MESH_TRANSFORM))):
        new_scene()
        arm, mesh = build("Arm", **kwargs)
        extract(mesh)
        worst[what] = assert_same_muscles(world_curves(arm), what, kwargs.get("arm_matrix"))
    print("  root curves vs the plain arm:", ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))


# ------------------------------------------------------------------------------------------------
# A character in several meshes
# ------------------------------------------------------------------------------------------------

PARTS = ({"upper_arm", "shoulder"}, {"forearm"}, {"hand"})


def split_character():
    """The synthetic arm in three meshes (upper arm, forearm, hand) on an armature scaled x100 (its data
    x0.01), rotated and translated, the forearm piece with a transform of its own. (arm, meshes)."""
    new_scene()
    arm, mesh = build("Split", scale=100.0, arm_matrix=ARM_TRANSFORM)
    bones = {b.name for b in arm.data.bones}
    parts = [p & bones for p in PARTS]
    parts[0] |= bones - set().union(*parts)  # any other bone goes with the upper arm
    meshes = split_mesh(mesh, parts)
    set_own_transform(meshes[1], Matrix.Scale(0.01, 4) @ MESH_TRANSFORM)
    bpy.context.view_layer.update()
    return arm, meshes


def seam_pairs(meshes):
    """[(mesh a, vertex i, mesh b, vertex j)] of vertices of different meshes at the same rest position."""
    from mathutils.kdtree import KDTree
    world = [world_vertices(m, evaluated=False) for m in meshes]
    size = max(float(np.ptp(w, axis=0).max()) for w in world)
    pairs = []
    for b in range(1, len(meshes)):
        tree = KDTree(len(world[b]))
        for j, p in enumerate(world[b]):
            tree.insert(p, j)
        tree.balance()
        for a in range(b):
            for i, p in enumerate(world[a]):
                for _co, j, _d in tree.find_range(p, 1e-6 * size):
                    pairs.append((a, i, b, j))
    return pairs


def weights_of(mesh):
    """{group name: {vertex: weight}}: the exact state of every vertex group."""
    names = {g.index: g.name for g in mesh.vertex_groups}
    out = {n: {} for n in names.values()}
    for v in mesh.data.vertices:
        for g in v.groups:
            out[names[g.group]][v.index] = g.weight
    return out


def test_extract_bind_unbind_a_character_in_three_meshes():
    _ref, radius, size = reference()
    arm, meshes = split_character()
    pairs = seam_pairs(meshes)
    assert len(pairs) >= 20, f"the pieces share only {len(pairs)} boundary vertices"
    # a mesh active: that mesh alone
    extract(meshes[0])
    assert [s.object for s in arm.myoskin.skins] == [meshes[0]]
    # the armature active: every mesh, welded into one surface: the plain arm's muscles
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert [s.object for s in arm.myoskin.skins] == meshes
    worst = assert_same_muscles(world_curves(arm), "three meshes", ARM_TRANSFORM)
    print(f"  three meshes vs the plain arm: root curves within {worst:.2e} (limb radius {radius:.3g})")
    originals = [weights_of(m) for m in meshes]
    rest = [world_vertices(m) for m in meshes]
    bpy.context.view_layer.objects.active = meshes[2]  # any mesh of the character binds the whole character
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    joint_names = json.loads(arm.myoskin.bind_text.as_string())["joint_names"]
    assert joint_names
    for m, before in zip(meshes, rest):
        err = float(np.abs(world_vertices(m) - before).max())
        assert err < 1e-6 * size, f"{m.name}: rest pose moved by {err:.3g} after bind (size {size:.3g})"
        assert "myoskin_original_weights" in m
    muscled = [sum(1 for v in m.data.vertices for g in v.groups
                   if m.vertex_groups[g.group].name in joint_names and g.weight > 0.0) for m in meshes]
    assert muscled[0] > 100 and muscled[1] > 100, f"vertices with muscle weights per mesh: {muscled}"
    # posed: Blender equals the core's Equation 3 on every mesh, and the pieces stay joined
    for bone, degrees in (("forearm", 80.0), ("upper_arm", 35.0)):
        if bone in arm.pose.bones:
            pb = arm.pose.bones[bone]
            pb.rotation_mode = 'XYZ'
            pb.rotation_euler = (np.radians(degrees), 0.0, 0.0)
    posed = [world_vertices(m) for m in meshes]
    assert max(float(np.abs(p - r).max()) for p, r in zip(posed, rest)) > 0.05 * size  # it did move
    live, rig_io, io = module("live"), module("rig_io"), module("blender_io")
    rig = live.live_rig(arm)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    transforms = np.concatenate([pose @ np.linalg.inv(np.asarray(rig.character.bone_rest)),
                                 rig.rig.evaluate(pose)["joint_matrices"] @ np.linalg.inv(rig.rig.bind_matrices)])
    for m, p in zip(meshes, posed):
        joints, weights = rig_io.read_combined_weights(m, rig.bone_names + rig.joint_names)
        to_arm = io.mesh_to_armature_matrix(m, arm)
        rest = transform(to_arm, io.mesh_vertices(m.data))
        rest = rest + module("volume_keys").pose_offsets(m, arm, rig.character, pose)  # the volume keys, armature space
        skinned = module("binding").skinner_for(m, arm, rig, rest, joints, weights).deform(transforms)
        err = float(np.abs(transform(arm.matrix_world, skinned) - p).max())
        assert err < 1e-5 * size, f"{m.name}: Blender differs from the core by {err:.3g}"
    gap = max(float(np.linalg.norm(posed[a][i] - posed[b][j])) for a, i, b, j in pairs)
    assert gap < 1e-5 * size, f"the pieces separate by {gap:.3g} when posed (size {size:.3g})"
    # PC2: one file per mesh, each equal to Blender's skin
    path = os.path.join(TMP, "split.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=2) == {'FINISHED'}
    paths = module("operators.rig").pc2_paths(path, meshes)
    assert len(set(paths)) == 3 and not os.path.exists(path)
    for m, p in zip(meshes, paths):
        frames = core().read_pc2(p)["frames"]
        assert frames.shape == (2, len(m.data.vertices), 3), (p, frames.shape)
        err = float(np.abs(transform(m.matrix_world, frames[0]) - world_vertices(m)).max())
        assert err < 1e-5 * size, f"{p}: PC2 differs from Blender by {err:.3g}"
    # Unbind: every mesh gets its weights back exactly
    assert bpy.ops.myoskin.unbind() == {'FINISHED'}
    assert len(originals) == len(meshes) == 3
    for m, before in zip(meshes, originals):
        assert weights_of(m) == before, m.name
        assert "myoskin_original_weights" not in m


# ------------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------------

def test_bad_characters_say_why():
    new_scene()
    bpy.context.view_layer.objects.active = None
    assert "No active object" in operator_error(bpy.ops.myoskin.extract_muscles)
    # an armature deforming no mesh
    data = bpy.data.armatures.new("Lonely")
    lonely = bpy.data.objects.new("Lonely", data)
    bpy.context.scene.collection.objects.link(lonely)
    bpy.context.view_layer.objects.active = lonely
    text = operator_error(bpy.ops.myoskin.extract_muscles)
    assert "'Lonely' deforms no mesh" in text, text
    # a mesh without weights among several: skipped, and the report says so
    arm, meshes = split_character()
    for g in list(meshes[2].vertex_groups):
        meshes[2].vertex_groups.remove(g)
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert [s.object for s in arm.myoskin.skins] == meshes[:2]
    found, skipped = module("blender_io").character_meshes(arm)
    assert found == meshes[:2] and [(o, why) for o, why in skipped] == [(meshes[2], "no weights of its bones")]
    assert "skipped" in module("blender_io").skipped_message(skipped) and meshes[2].name in \
        module("blender_io").skipped_message(skipped)
    # ...and none with weights: an error naming them, nothing changed
    muscles = len(arm.myoskin.muscles)
    for m in meshes[:2]:
        for g in list(m.vertex_groups):
            m.vertex_groups.remove(g)
    text = operator_error(bpy.ops.myoskin.extract_muscles)
    assert "deforms no skinned mesh" in text and meshes[0].name in text and "no weights" in text, text
    assert len(arm.myoskin.muscles) == muscles


runner.run()
