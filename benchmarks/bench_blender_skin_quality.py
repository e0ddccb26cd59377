# SPDX-License-Identifier: GPL-3.0-or-later
"""Skin quality at bent joints through Blender's own Armature modifier, beside the core's figure for the same
skin (issue 14 item 5; benchmarks/bench_skin_quality.py is the core-only half, benchmarks/skin_quality.py defines
the measures). Per character and joint, for

    LBS       the character's own Armature modifier on its skeleton weights, Preserve Volume off
    DQS       the same modifier with Preserve Volume on (Blender's dual quaternions)
    Myoskin   the character extracted and bound by the add-on's operators at their defaults (Volume Blend on: the
              linear and the dual-quaternion skin mixed per vertex by two Armature modifiers; the muscle joints'
              weights), posed live by the add-on's handlers

it prints the band's volume change (skin within 1.5 limb radii of the joint, cone volume from the joint), the
largest outward move of the upper segment's skin over the LBS skin (along the LBS normals) and the band's
triangle pairs that cross each other (over rest), once from Blender's evaluated mesh and once from the core's
skinner on the same rest skin (plus the volume keys at the core's weights), weights and transforms (core.skin, in
Blender's mode), with their largest vertex difference relative to the character's size (the Blender tests hold it
under 1e-5). The core Character is read
from the Blender scene through the add-on's reader (blender_io.combined_character: every mesh of the armature in
its space, welded), so both share the armature space; each joint is bent by skin_quality.bent_pose in that space
(Blender's characters face -Y) and the armature is posed so that every bone's PoseBone.matrix equals it.

Characters: makehuman_muscular_male, Quaternius' woman soldier (four meshes, x100) and horse (x100) through
Blender's glTF importer (the add-on's gltf_io), and the generated biped (seed 21: _core.make_synthetic_body written
by blender_io.character_to_blender). A character whose file is missing is skipped with a message; one that fails
to import, extract, bind or pose makes the run exit 1 with a message naming it (the others are still measured).
Never asserts on the figures. Run (./myoskin.sh bench does, on every Blender of the matrix):

    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup --python-exit-code 1 \\
        --addons myoskin --python benchmarks/bench_blender_skin_quality.py -- [SHARED_DIR]
"""
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import skin_quality  # noqa: E402

WORLD_FACING = (0.0, -1.0, 0.0)  # Blender's characters face -Y (the glTF importer turns glTF's +Z front into -Y)
POSE_TOLERANCE = 1e-5  # posed bone heads and tails (float32) against the core's bent pose, of the character's size
CHARACTERS = [  # (label, file under the shared folder or None for the generated biped, joints)
    ("makehuman_muscular_male", "characters/makehuman_muscular_male/makehuman_muscular_male.glb",
     skin_quality.MAKEHUMAN_JOINTS),
    ("generated biped, seed 21", None, skin_quality.SYNTHETIC_BODY_JOINTS),
    ("quaternius_woman_soldier", "characters/quaternius_woman_soldier/woman_soldier.glb",
     skin_quality.QUATERNIUS_JOINTS),
    ("quaternius_horse", "characters/quaternius_horse/horse.glb", skin_quality.HORSE_JOINTS),
]
METHODS = ("LBS", "DQS", "Myoskin")


class CharacterFailed(Exception):
    """A character could not be imported, extracted, bound or posed: the run exits 1 naming it."""


def addon_module(name):
    """A module of the enabled add-on, whatever its package ("myoskin" or "bl_ext.<repository>.myoskin")."""
    import importlib
    enabled = sorted(n for n in bpy.context.preferences.addons.keys() if n == "myoskin" or n.endswith(".myoskin"))
    return importlib.import_module(f"{(enabled or ['myoskin'])[0]}.{name}")


def shared_dir():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if argv:
        return argv[0]
    return os.environ.get("MYOSKIN_SHARED_DIR") or os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                                  "..", "..", "shared")


# ================================================================================================
# Scene
# ================================================================================================

def load_scene(core, path):
    """A new empty scene with the character (a .glb through the add-on's glTF import, or the generated biped
    when `path` is None); returns its armature object."""
    bpy.ops.wm.read_homefile(use_empty=True)
    if path is None:
        character, _truth = core.make_synthetic_body(seed=21)
        arm, _skin = addon_module("blender_io").character_to_blender(character, "Biped")
        return arm
    try:
        result = addon_module("gltf_io").import_gltf(path)
    except RuntimeError as e:
        raise CharacterFailed(f"glTF import of {path} failed: {str(e).strip()}") from None
    if result != {'FINISHED'}:
        raise CharacterFailed(f"glTF import of {path} returned {result}")
    io = addon_module("blender_io")
    armatures = [o for o in bpy.context.scene.objects if o.type == 'ARMATURE' and io.character_meshes(o)[0]]
    if not armatures:
        raise CharacterFailed(f"{path}: no armature deforms a skinned mesh after import")
    arm = max(armatures, key=lambda a: len(io.character_meshes(a)[0]))
    arm.animation_data_clear()  # an imported Action (the horse's) would overwrite the poses set here
    return arm


def armature_modifiers(meshes, arm):
    """The Armature modifier of every mesh (Bind keeps the character's own)."""
    mods = []
    for mesh in meshes:
        mod = next((m for m in mesh.modifiers if m.type == 'ARMATURE' and m.object == arm), None)
        if mod is None:
            raise CharacterFailed(f"mesh '{mesh.name}' has no Armature modifier of '{arm.name}'")
        mods.append(mod)
    return mods


def facing_of(arm):
    """The direction the character faces (WORLD_FACING) in the armature's space, where the core's Character and
    the poses live (a glTF armature object may carry the file's rotation and scale)."""
    world = np.array([list(row) for row in arm.matrix_world.to_3x3()])
    facing = np.linalg.solve(world, np.asarray(WORLD_FACING))
    return tuple(facing / np.linalg.norm(facing))


def pose_armature(arm, character, pose):
    """Pose the skeleton bones so that each PoseBone.matrix equals `pose` (#B by 4 by 4, the core's order,
    armature space); the muscle-joint bones are left to the add-on. Returns the largest distance of a posed
    bone's head or tail, read back from Blender, from where `pose` puts it."""
    names = list(character.bone_names)
    parents = np.asarray(character.bone_parents)
    rest = np.asarray(character.bone_rest)
    for i, name in enumerate(names):
        # PoseBone.matrix = parent's pose @ parent's rest^-1 @ rest @ basis (full inheritance)
        relative = rest[i] if parents[i] < 0 else np.linalg.inv(rest[parents[i]]) @ rest[i]
        parent_pose = np.eye(4) if parents[i] < 0 else pose[parents[i]]
        basis = np.linalg.inv(relative) @ np.linalg.inv(parent_pose) @ pose[i]
        pb = arm.pose.bones[name]
        pb.rotation_mode = 'QUATERNION'
        pb.matrix_basis = Matrix(basis.tolist())
    update()
    got = addon_module("rig_io").pose_bone_matrices(arm, names)
    lengths = np.linalg.norm(np.asarray(character.bone_tails) - np.asarray(character.bone_heads), axis=1)
    ends = np.stack([np.zeros_like(lengths), lengths], axis=1)  # along each bone's Y axis
    points = lambda m: m[:, None, :3, 3] + ends[..., None] * m[:, None, :3, 1]  # noqa: E731
    return float(np.linalg.norm(points(got) - points(pose), axis=-1).max())


def update():
    """Evaluate the scene (twice: the add-on's depsgraph handler poses the muscle joints after the first)."""
    bpy.context.view_layer.update()
    bpy.context.view_layer.update()


def evaluated(combined, arm, first):
    """#welded by 3 evaluated skin (armature space): every mesh's evaluated vertices, welded like the rest."""
    io = addon_module("blender_io")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    points = np.concatenate([io.evaluated_vertices(m, arm, depsgraph) for m in combined.meshes])
    return points[first]


def combined_weights(combined, first, names):
    """(#welded by K joints into `names`, weights) read from every mesh's vertex groups, welded."""
    rig_io = addon_module("rig_io")
    parts = [rig_io.read_combined_weights(m, names) for m in combined.meshes]
    k = max(p[0].shape[1] for p in parts)
    joints = np.concatenate([np.pad(j, ((0, 0), (0, k - j.shape[1])), constant_values=-1) for j, _w in parts])
    weights = np.concatenate([np.pad(w, ((0, 0), (0, k - w.shape[1]))) for _j, w in parts])
    return np.ascontiguousarray(joints[first], dtype=np.int32), np.ascontiguousarray(weights[first])


# ================================================================================================
# Measures
# ================================================================================================

def figures(core, rest, tris, skins, joint_rest, joint_posed, radius, on_upper):
    """{method: (band change, bulge over LBS in the character's units, crossings over rest, bulge over DQS)} for
    one source's skins ({method: #V by 3}, LBS and DQS among them); None when no skin lies within the band.
    Bulges are the largest outward move of the upper segment's skin (`on_upper`, #V bools) along the base's
    normals; with Preserve Volume the muscles' own bulge is the one over DQS."""
    try:
        band = {k: skin_quality.band_volume_change(rest, v, tris, joint_rest, joint_posed, radius)
                for k, v in skins.items()}
    except ValueError:
        return None
    mask = skin_quality.band_triangles(rest, tris, joint_rest, radius)
    at_rest = core.self_intersections(rest, tris, mask)
    normals = {k: np.asarray(core.vertex_normals(skins[k], tris)) for k in ("LBS", "DQS")}

    def bulge(v, base):
        moved = ((v - skins[base]) * normals[base]).sum(1)
        return float(moved[on_upper].max()) if on_upper.any() else float("nan")
    return {k: (band[k], bulge(v, "LBS"), core.self_intersections(v, tris, mask) - at_rest, bulge(v, "DQS"))
            for k, v in skins.items()}


def measure_character(core, label, path, joints):
    """Rows (joint label, method, Blender figures, core figures, max |Blender - core| / size) of one character,
    and a summary line."""
    io, binding, live, volume_keys = (addon_module(n) for n in ("blender_io", "binding", "live", "volume_keys"))
    start = time.perf_counter()
    arm = load_scene(core, path)
    meshes, _skipped = io.character_meshes(arm)
    combined = io.combined_character(meshes, arm)
    character = combined.character
    _values, first = np.unique(combined.weld_map, return_index=True)
    rest = np.asarray(character.vertices)
    tris = np.asarray(character.triangles)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    names = list(character.bone_names)
    heads = np.asarray(character.bone_heads)
    bone_rest = np.asarray(character.bone_rest)
    sj, sw = np.asarray(character.weight_joints), np.asarray(character.weight_values)
    dominant = sj[np.arange(len(sj)), np.argmax(sw, axis=1)]
    scale = io.armature_scale(arm)  # the add-on extracts at the scene's size; the band is in armature units
    _m, report = core.extract_muscles(io.scaled_character(character, scale), build_surfaces=False)
    radius = 1.5 * report["limb_radius"] / scale
    mods = armature_modifiers(meshes, arm)
    for mod in mods:
        mod.use_bone_envelopes = False
    dq_scale = binding.dq_scale()

    # Skeleton only: LBS and DQS through the character's own modifiers, the core's skinner beside them.
    facing = facing_of(arm)
    bent = [(j, skin_quality.bent_pose(character, j[1], j[2], j[4], j[5], facing)) for j in joints if j[1] in names]
    if not bent:
        raise CharacterFailed(f"none of the joints' bones ({', '.join(j[1] for j in joints)}) is in the rig")
    skins = {}
    for (jlabel, *_), pose in bent:
        err = pose_armature(arm, character, pose)
        if err > POSE_TOLERANCE * size:
            raise CharacterFailed(f"{jlabel}: the posed bones differ from the core's pose by {err / size:.1e} of "
                                  f"the size (bone constraints or inheritance the pose does not follow?)")
        skel = core.skeleton_transforms(character, pose)
        blender = {}
        for method, pv in (("LBS", False), ("DQS", True)):
            for mod in mods:
                mod.use_deform_preserve_volume = pv
            update()
            blender[method] = evaluated(combined, arm, first)
        ours = {"LBS": np.asarray(core.skin(rest, sj, sw, skel), float),
                "DQS": np.asarray(core.skin(rest, sj, sw, skel, preserve_volume=True, rest_matrices=bone_rest,
                                            dq_scale=dq_scale), float)}
        skins[jlabel] = (pose, blender, ours)
    pose_armature(arm, character, bone_rest)

    # Myoskin: Extract and Bind at their defaults, the whole character (the armature active).
    for obj in bpy.context.view_layer.objects:
        obj.select_set(False)
    bpy.context.view_layer.objects.active = arm
    arm.select_set(True)
    for op, what in ((bpy.ops.myoskin.extract_muscles, "extract"), (bpy.ops.myoskin.bind, "bind")):
        try:
            result = op()
        except RuntimeError as e:
            raise CharacterFailed(f"failed to {what}: {str(e).strip()}") from None
        if result != {'FINISHED'}:
            raise CharacterFailed(f"failed to {what}: the operator returned {result}")
    state = arm.myoskin
    rig = live.live_rig(arm)
    if list(rig.bone_names) != names:
        raise CharacterFailed("the bind record's skeleton differs from the character read before the bind")
    hj, hw = combined_weights(combined, first, rig.bone_names + rig.joint_names)
    combined_rest = core.combined_rest_matrices(rig.character, rig.rig)
    bind_inverse = np.linalg.inv(np.asarray(rig.rig.bind_matrices))
    pv = all(m.use_deform_preserve_volume for m in mods)
    binding = addon_module("binding")
    share = None  # the volume blend (the rig's default): the share groups Bind wrote, welded like the weights
    if all(binding.volume_blend_modifier(m, arm) is not None for m in combined.meshes):
        share = np.concatenate([binding.read_share_group(m) for m in combined.meshes])[first]
    pose_armature(arm, character, bone_rest)
    rest_error = float(np.abs(evaluated(combined, arm, first) - rest).max()) / size

    rows = []
    for (jlabel, bone, _hinge, upper, _direction, degrees), _pose in bent:
        pose, blender, ours = skins[jlabel]
        err = pose_armature(arm, character, pose)
        if err > POSE_TOLERANCE * size:
            raise CharacterFailed(f"{jlabel}: the bound rig's posed bones differ from the core's pose by "
                                  f"{err / size:.1e} of the size")
        blender["Myoskin"] = evaluated(combined, arm, first)
        evaluated_pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
        joint_matrices = np.asarray(rig.rig.evaluate(evaluated_pose)["joint_matrices"])
        transforms = np.concatenate([core.skeleton_transforms(character, evaluated_pose),
                                     joint_matrices @ bind_inverse])
        if share is not None:  # with the volume keys at the core's weights (shape keys before the modifiers)
            keyed = rest + np.concatenate([volume_keys.pose_offsets(m, arm, rig.character, evaluated_pose)
                                           for m in combined.meshes])[first]
            ours["Myoskin"] = np.asarray(core.skin(keyed, hj, hw, transforms, dqs_share=share,
                                                   rest_matrices=combined_rest, dq_scale=dq_scale), float)
        else:
            ours["Myoskin"] = np.asarray(core.skin(rest, hj, hw, transforms, preserve_volume=pv,
                                                   rest_matrices=combined_rest, dq_scale=dq_scale), float)
        b = names.index(bone)
        on_upper = np.isin(dominant, [names.index(u) for u in upper if u in names])
        mine = figures(core, rest, tris, blender, heads[b], pose[b][:3, 3], radius, on_upper)
        theirs = figures(core, rest, tris, ours, heads[b], pose[b][:3, 3], radius, on_upper)
        if mine is None or theirs is None:
            rows.append((f"{jlabel} {degrees:g}", None, None, None, None))
            continue
        for method in METHODS:
            diff = float(np.abs(blender[method] - ours[method]).max()) / size
            rows.append((f"{jlabel} {degrees:g}", method, mine[method], theirs[method], diff))
    pose_armature(arm, character, bone_rest)
    summary = (f"{label}: {len(rest):,} vertices ({len(meshes)} mesh{'es' if len(meshes) > 1 else ''}), "
               f"{len(state.muscles)} muscles, {len(rig.joint_names)} muscle joints, facing {np.round(facing, 3).tolist()} "
               f"in the armature's space, Myoskin "
               f"{'volume blend' if share is not None else 'Preserve Volume on' if pv else 'linear'}, limb radius {report['limb_radius'] / scale:.4g}; bound rest pose "
               f"{rest_error:.1e} of the size; {time.perf_counter() - start:.1f} s")
    return rows, report["limb_radius"] / scale, summary


# ================================================================================================
# Table
# ================================================================================================

def print_table(label, rows, limb_radius):
    """One line per joint and method: Blender's figure, then the core's."""
    print(f"{'character':24s} {'joint':24s} {'method':8s} {'band: Blender':>13s} {'core':>7s} "
          f"{'bulge over LBS: Blender':>23s} {'core':>8s} {'over DQS: Blender':>17s} {'core':>8s} "
          f"{'crossings B/core':>16s} {'max |B-core|':>12s}")
    def r(x):  # in limb radii, without a "-0.000" for float noise
        return round(x / limb_radius, 3) + 0.0

    for joint, method, mine, theirs, diff in rows:
        if method is None:
            print(f"{label[:24]:24s} {joint:24s} no skin within 1.5 limb radii of the joint, not measured")
            continue
        over_dqs = (f"{r(mine[3]):+15.3f} r {r(theirs[3]):+6.3f} r" if method == "Myoskin"
                    else f"{'':17s} {'':8s}")
        print(f"{label[:24]:24s} {joint:24s} {method:8s} {100 * mine[0]:+12.1f}% {100 * theirs[0]:+6.1f}% "
              f"{r(mine[1]):+21.3f} r {r(theirs[1]):+6.3f} r {over_dqs} "
              f"{mine[2]:>9d}/{theirs[2]:<6d} {diff:12.1e}")


def main():
    core = addon_module("core_loader").core()
    shared = shared_dir()
    print(f"bench_blender_skin_quality: Blender {bpy.app.version_string}, shared folder {os.path.abspath(shared)}; "
          f"bulge in limb radii (r), max |B-core| relative to the character's size", flush=True)
    failed = []
    for label, relative, joints in CHARACTERS:
        path = None if relative is None else os.path.join(shared, relative)
        if path is not None and not os.path.exists(path):
            print(f"{label}: skipped, needs {path}", flush=True)
            continue
        try:
            rows, limb_radius, summary = measure_character(core, label, path, joints)
        except (CharacterFailed, ValueError) as e:  # ValueError: the add-on's or the core's message on bad input
            print(f"ERROR {label}: {e}", flush=True)
            failed.append(label)
            continue
        print_table(label, rows, limb_radius)
        print(summary, flush=True)
    if failed:
        print(f"bench_blender_skin_quality: {len(failed)} character(s) failed: {', '.join(failed)}", flush=True)
        sys.exit(1)


if __name__ == "__main__":
    main()
