# SPDX-License-Identifier: GPL-3.0-or-later
"""Playback benchmark (Blender background): frames per second of scene.frame_set over 100 frames of an
animated elbow + shoulder on the synthetic arm at ~50k vertices, in one run:

    skeleton only      the plain Armature modifier, the character's own weights (baseline)
    bound, live        muscles bound, live update handlers on (muscle surfaces hidden): F-curve prediction
    bound, live, 2-pass  the same with a bone constraint that changes the pose slightly every frame (a Limit
                       Rotation at influence 0.02), so the pose is read after evaluation and Blender
                       evaluates twice (the route for IK / constraint-driven skeletons)
    bound, live+surf   the same with the muscle surfaces shown (written every frame)
    bound, baked       muscle joints baked to the Action, live update off (what a farm / no add-on plays)
    bound, baked, linear  the same with the Volume Blend off (linear blending, as the paper; its volume keys muted)
    bound, baked, no keys  the Volume Blend on, its volume keys muted (what the driven shape keys cost)
    bound, baked, 4 infl.  bound with Max Influences 4 instead of 8, baked (Volume Blend on)
    bound, PC2 cache   the skin baked to a PC2 by the core and played by a Mesh Cache modifier, the Armature
                       modifier muted (Bake PC2 with Add Mesh Cache Modifier; no add-on needed to play)
    anchored, live     Bind with the Anchored Skin deformer: the core's AnchoredSkin per frame, written as offsets
                       for the Core Skin (Geometry Nodes) modifier by the live handlers
    plain, Preserve Volume  the plain character with the Armature modifier's Preserve Volume (what Bind sets)

Timing: every bound case plays the same 100 frames in each of --repeats passes (cases interleaved, their
order reversed every other pass), alternating in chunks of 10 frames with the same frames of the baseline
scene, so load from other processes on a shared machine hits a case and its paired baseline alike. Each
frame's time is its best over the passes (load only ever adds time); ms/frame is the mean of those, the
ratio is the case's paired baseline over it. The median ratio is the median over passes of (paired
baseline time / case time), for comparison. Steady load still pulls every ratio towards 1.
Prints fps and the ratios to the baseline; never asserts. Run through `./myoskin.sh bench`, or
    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup --python-exit-code 1 \\
        --addons myoskin --python benchmarks/bench_blender_playback.py [-- --frames 100 --rings 600]
"""
import argparse
import os
import sys
import time

import bpy
import numpy as np


def addon_module(name):
    """A module of the enabled add-on, whatever its package ("myoskin" or "bl_ext.<repository>.myoskin")."""
    import importlib
    enabled = sorted(n for n in bpy.context.preferences.addons.keys() if n == "myoskin" or n.endswith(".myoskin"))
    return importlib.import_module(f"{(enabled or ['myoskin'])[0]}.{name}")


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_blender_playback.py")
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--rings", type=int, default=600, help="rings per metre (600 -> ~50k vertices)")
    p.add_argument("--repeats", type=int, default=7, help="passes per case (per-frame best of N)")
    return p.parse_args(argv)


def animate(arm, frames):
    for name, axis, amplitude in (("forearm", 0, 2.0), ("upper_arm", 2, 0.6)):
        pb = arm.pose.bones[name]
        pb.rotation_mode = 'XYZ'
        for f in (1, frames // 2, frames):
            rot = [0.0, 0.0, 0.0]
            rot[axis] = amplitude * np.sin(np.pi * (f - 1) / max(frames - 1, 1))
            pb.rotation_euler = rot
            pb.keyframe_insert("rotation_euler", frame=f)


def frame_seconds(scene, base_scene, frames, chunk=10):
    """(#frames seconds of each scene.frame_set(1..frames), #frames seconds of base_scene.frame_set of the
    same frames), alternating in chunks of `chunk` frames (baseline chunk first), both started from the
    last frame."""
    scene.frame_set(frames)
    base_scene.frame_set(frames)
    out, base = np.empty(frames), np.empty(frames)
    for first in range(1, frames + 1, chunk):
        for target, times in ((base_scene, base), (scene, out)):
            for f in range(first, min(first + chunk, frames + 1)):
                start = time.perf_counter()
                target.frame_set(f)
                times[f - 1] = time.perf_counter() - start
    return out, base


def add_character(core, blender_io, scene, name, rings, frames):
    """The synthetic arm, animated, built in the context scene and then moved to `scene`."""
    character, _ = core.make_synthetic_arm(seed=1, rings_per_metre=rings)
    here = bpy.context.scene.collection
    arm, skin = blender_io.character_to_blender(character, name, here)
    animate(arm, frames)
    if scene != bpy.context.scene:
        for obj in (arm, skin):
            scene.collection.objects.link(obj)
            here.objects.unlink(obj)
    return arm, skin


def mean_influences(skin):
    """Mean bones + muscle joints per vertex with weight > 0 (the volume blend's groups are no influence)."""
    skip = {skin.vertex_groups[n].index for n in addon_module("binding").MIX_GROUPS if n in skin.vertex_groups}
    return float(np.mean([sum(g.weight > 0 for g in v.groups if g.group not in skip) for v in skin.data.vertices]))


def main():
    args = parse_args()
    blender_io, core_loader = (addon_module(n) for n in ("blender_io", "core_loader"))
    core = core_loader.core()
    bpy.ops.wm.read_homefile(use_empty=True)
    bound_scene = bpy.context.scene
    plain_scene = bpy.data.scenes.new("SkeletonOnly")
    for scene in (bound_scene, plain_scene):
        scene.frame_start, scene.frame_end = 1, args.frames
    _plain_arm, plain_skin = add_character(core, blender_io, plain_scene, "PlainArm", args.rings, args.frames)
    arm, skin = add_character(core, blender_io, bound_scene, "BoundArm", args.rings, args.frames)
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    t0 = time.perf_counter()
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    bind_seconds = time.perf_counter() - t0
    state = arm.myoskin
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=args.frames) == {'FINISHED'}
    joints = len(__import__("json").loads(state.bind_text.as_string())["joint_names"])
    print(f"bench_blender_playback: {len(skin.data.vertices):,} vertices, {len(arm.data.bones) - joints} "
          f"bones + {joints} muscle joints ({len(state.muscles)} muscles), {args.frames} frames; bind "
          f"{bind_seconds:.2f} s; {args.repeats} interleaved passes, per-frame best; influences per vertex "
          f"{mean_influences(skin):.2f} bound, {mean_influences(plain_skin):.2f} plain", flush=True)

    def bound_in_own_scene(name, deformer='JOINTS', after_bind=None, max_influences=None):
        """The character extracted and bound (with `deformer`, `max_influences`) in the context scene,
        `after_bind(arm)` run, then moved with its muscle objects into a new scene of its own (surfaces hidden);
        returns the scene."""
        scene = bpy.data.scenes.new(name)
        scene.frame_start, scene.frame_end = 1, args.frames
        own_arm, own_skin = add_character(core, blender_io, bpy.context.scene, name + "Arm", args.rings, args.frames)
        bpy.context.view_layer.objects.active = own_skin
        assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
        own_arm.myoskin.deformer = deformer
        if max_influences is not None:
            own_arm.myoskin.max_influences = max_influences
        assert bpy.ops.myoskin.bind() == {'FINISHED'}
        print(f"  {name}: {mean_influences(own_skin):.2f} influences per vertex", flush=True)
        if after_bind is not None:
            after_bind(own_arm)
        own_arm.myoskin.collection.hide_viewport = True
        for obj in [own_arm, own_skin] + list(own_arm.myoskin.collection.objects):
            scene.collection.objects.link(obj)
            for coll in list(obj.users_collection):
                if coll != scene.collection:
                    coll.objects.unlink(obj)
        return scene

    def baked(own_arm):
        assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=args.frames) == {'FINISHED'}

    def bake_to_pc2(own_arm):
        import tempfile
        pc2 = os.path.join(tempfile.mkdtemp(prefix="myoskin_bench_"), "arm.pc2")
        assert bpy.ops.myoskin.bake_pc2(filepath=pc2, frame_start=1, frame_end=args.frames,
                                        add_modifier=True) == {'FINISHED'}
        own_arm.myoskin.live = False

    # The skin baked to a PC2 that a Mesh Cache modifier plays; the character bound with the anchored deformer.
    cached_scene = bound_in_own_scene("Cached", after_bind=bake_to_pc2)
    anchored_scene = bound_in_own_scene("Anchored", deformer='ANCHORED')
    four_scene = bound_in_own_scene("FourInfluences", after_bind=baked, max_influences=4)

    # The plain character with Preserve Volume (what Bind sets by default), to separate the dual-quaternion
    # blend's own cost from Myoskin's.
    pv_scene = bpy.data.scenes.new("SkeletonOnlyPV")
    pv_scene.frame_start, pv_scene.frame_end = 1, args.frames
    _pv_arm, pv_skin = add_character(core, blender_io, pv_scene, "PlainArmPV", args.rings, args.frames)
    for mod in pv_skin.modifiers:
        if mod.type == 'ARMATURE':
            mod.use_deform_preserve_volume = True

    constraint = arm.pose.bones["forearm"].constraints.new('LIMIT_ROTATION')  # x towards 0 by 2 %
    constraint.use_limit_x, constraint.min_x, constraint.max_x, constraint.influence = True, 0.0, 0.0, 0.02

    binding = addon_module("binding")
    first_mod, blend_mod = binding.armature_modifier(skin, arm), binding.volume_blend_modifier(skin, arm)
    first_group = first_mod.vertex_group

    volume_keys = addon_module("volume_keys")
    print(f"  volume keys on the bound arm: {len(volume_keys.stored(skin))}")

    def configure(live, surfaces, constrained=False, volume_blend=True, keys=True):
        """The bound scene's settings; without the volume blend, its second modifier off and the first one over
        the whole skin, its volume keys muted (as Bind leaves a rig bound with Volume Blend off)."""
        volume_keys.set_muted(skin, not (volume_blend and keys))
        state.live = live
        state.collection.hide_viewport = not surfaces
        constraint.mute = not constrained
        blend_mod.show_viewport = volume_blend
        first_mod.vertex_group = first_group if volume_blend else ""

    cases = [("bound, live", (True, False)), ("bound, live, 2-pass", (True, False, True)),
             ("bound, live+surfaces", (True, True)), ("bound, baked", (False, False)),
             ("bound, baked, linear", (False, False, False, False)),
             ("bound, baked, no keys", (False, False, False, True, False)), ("bound, baked, 4 infl.", four_scene),
             ("bound, PC2 cache", cached_scene), ("anchored, live", anchored_scene),
             ("plain, Preserve Volume", pv_scene)]
    passes = {name: [] for name, _c in cases}
    for r in range(args.repeats):
        for name, config in (cases if r % 2 == 0 else cases[::-1]):
            if isinstance(config, bpy.types.Scene):
                passes[name].append(frame_seconds(config, plain_scene, args.frames))
                continue
            configure(*config)
            passes[name].append(frame_seconds(bound_scene, plain_scene, args.frames))
    rows = []
    for name, _c in cases:
        times, bases = np.array([p[0] for p in passes[name]]), np.array([p[1] for p in passes[name]])
        best, base = times.min(axis=0).mean(), bases.min(axis=0).mean()
        median = float(np.median(bases.sum(axis=1) / times.sum(axis=1)))
        rows.append((name, best, base, median))
    base_all = min(base for _n, _b, base, _m in rows)
    print(f"  {'skeleton only':<22} {1 / base_all:7.1f} fps  {1000 * base_all:6.2f} ms/frame   (best paired baseline)")
    for name, best, base, median in rows:
        print(f"  {name:<22} {1 / best:7.1f} fps  {1000 * best:6.2f} ms/frame   ratio {base / best:5.2f}  "
              f"(baseline {1000 * base:4.2f} ms, median ratio {median:4.2f})")

if __name__ == "__main__":
    main()
