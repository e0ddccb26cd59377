# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's side of bench_skinning: the same ~100k-vertex skin and weights (60 skeleton bones + 400
muscle joints as deform bones, 4 and 8 influences) skinned by Blender's own Armature modifier. Times one
frame = a pose change of every bone (rotation, and scale on the muscle joints) + view_layer.update(), and
prints the ratio to the core's Skinner figures that bench_skinning measured in the same run.

Run (./myoskin.sh bench does this after bench_skinning --export DIR):
    BLENDER_USER_SCRIPTS=build/blender_scripts blender -b --factory-startup -t N --addons myoskin \
        --python benchmarks/bench_blender_skinning.py -- DIR [--threads N] [--frames F]
"""
import argparse
import json
import os
import sys
import time

import bpy
import numpy as np

from myoskin import blender_io, core_loader, rig_io

BONES, JOINTS_PER_MUSCLE = 60, 10


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_blender_skinning.py")
    p.add_argument("dir", help="folder written by bench_skinning --export")
    p.add_argument("--threads", type=int, default=0, help="Blender's -t (for the printout)")
    p.add_argument("--frames", type=int, default=30)
    return p.parse_args(argv)


def bone_arrays(vertices, num_joints):
    """A chain of 60 skeleton bones along the arm (x) and the muscle joints as bones parented to the
    skeleton bone at their place; rest frames rigid (Y along +x)."""
    x0, x1 = float(vertices[:, 0].min()), float(vertices[:, 0].max())
    step = (x1 - x0) / BONES
    heads, tails, parents, names = [], [], [], []
    for b in range(BONES):
        heads.append([x0 + b * step, 0.0, 0.0])
        tails.append([x0 + (b + 1) * step, 0.0, 0.0])
        parents.append(b - 1)
        names.append(f"bone{b:02d}")
    muscles = (num_joints - BONES) // JOINTS_PER_MUSCLE
    for j in range(num_joints - BONES):
        m, k = divmod(j, JOINTS_PER_MUSCLE)
        sector, span = divmod(m, 5)
        s = (span + (k + 0.5) / JOINTS_PER_MUSCLE) / 5
        angle = (sector + 0.5) / 8 * 2 * np.pi - np.pi
        head = [x0 + s * (x1 - x0), 0.03 * np.cos(angle), 0.03 * np.sin(angle)]
        heads.append(head)
        tails.append([head[0] + 0.01, head[1], head[2]])
        parents.append(min(int(s * BONES), BONES - 1))
        names.append(f"muscle{m:02d}.j{k}")
    heads, tails = np.array(heads), np.array(tails)
    rest = np.tile(np.eye(4), (len(names), 1, 1))
    rest[:, :3, 0] = [0.0, -1.0, 0.0]  # X
    rest[:, :3, 1] = [1.0, 0.0, 0.0]   # Y along the arm
    rest[:, :3, 2] = [0.0, 0.0, 1.0]   # Z = X x Y
    rest[:, :3, 3] = heads
    assert muscles * JOINTS_PER_MUSCLE == num_joints - BONES
    return names, np.array(parents, dtype=np.int32), heads, tails, rest


def time_frames(arm_obj, frames):
    """Best-of-3 ms per frame of (pose change of every bone + view_layer.update())."""
    pose_bones = arm_obj.pose.bones
    n = len(pose_bones)
    for pb in pose_bones:
        pb.rotation_mode = 'QUATERNION'
    is_joint = np.array([pb.name.startswith("muscle") for pb in pose_bones])
    poses = []
    for f in range(8):
        a = 0.02 * np.sin(0.3 * f + np.arange(n))
        q = np.stack([np.cos(a), np.sin(a) * 0.3, np.sin(a) * 0.5, np.sin(a) * 0.8], axis=1).astype(np.float32)
        sc = np.ones((n, 3), dtype=np.float32)
        sc[is_joint] = [1.0 + 0.1 * np.sin(f), 0.9, 1.0 + 0.1 * np.sin(f)]
        poses.append((q.ravel(), sc.ravel()))
    layer = bpy.context.view_layer
    best = float("inf")
    for _rep in range(3):
        t0 = time.perf_counter()
        for f in range(frames):
            q, sc = poses[f % len(poses)]
            pose_bones.foreach_set("rotation_quaternion", q)
            pose_bones.foreach_set("scale", sc)
            arm_obj.update_tag()
            layer.update()
        best = min(best, 1e3 * (time.perf_counter() - t0) / frames)
    return best


def time_joint_writes(arm_obj, frames):
    """ms per frame of rig_io.write_joint_matrices for every muscle-joint bone (scaled matrices) + the
    view-layer update, the add-on's live route; and of the write alone."""
    names = [pb.name for pb in arm_obj.pose.bones if pb.name.startswith("muscle")]
    skeleton = [pb.name for pb in arm_obj.pose.bones if not pb.name.startswith("muscle")]
    parents = dict(zip(skeleton, rig_io.pose_bone_matrices(arm_obj, skeleton)))
    rest = blender_io.bone_rest_matrices(arm_obj.data.bones)
    index = [arm_obj.data.bones.find(n) for n in names]
    sets = []
    for f in range(8):
        m = rest[index].copy()
        m[:, :3, :3] *= np.array([1.0 + 0.05 * np.sin(f), 0.9, 1.0 + 0.05 * np.sin(f)])
        sets.append(m)
    layer = bpy.context.view_layer
    best_total = best_write = float("inf")
    for _rep in range(3):
        write = 0.0
        t0 = time.perf_counter()
        for f in range(frames):
            w0 = time.perf_counter()
            rig_io.write_joint_matrices(arm_obj, names, sets[f % len(sets)], parents)
            write += time.perf_counter() - w0
            layer.update()
        best_total = min(best_total, 1e3 * (time.perf_counter() - t0) / frames)
        best_write = min(best_write, 1e3 * write / frames)
    return best_total, best_write


def main():
    args = arguments()
    core = core_loader.core()
    d = args.dir
    figures = json.load(open(os.path.join(d, "core.json")))
    nv, nf, nj = figures["vertices"], figures["triangles"], figures["joints"]
    vertices = np.fromfile(os.path.join(d, "vertices.f64"), dtype=np.float64).reshape(nv, 3)
    triangles = np.fromfile(os.path.join(d, "triangles.i32"), dtype=np.int32).reshape(nf, 3)
    names, parents, heads, tails, rest = bone_arrays(vertices, nj)
    threads = args.threads or os.cpu_count()
    print(f"Blender {bpy.app.version_string}, -t {threads}: {nv} vertices, {BONES} bones + {nj - BONES} muscle "
          f"joints as deform bones")
    for k in (4, 8):
        joints = np.fromfile(os.path.join(d, f"joints_k{k}.i32"), dtype=np.int32).reshape(nv, k)
        weights = np.fromfile(os.path.join(d, f"weights_k{k}.f64"), dtype=np.float64).reshape(nv, k)
        character = core.character_from_arrays(f"bench_k{k}", vertices, triangles, names, parents, heads, tails,
                                               np.ascontiguousarray(rest), joints, weights)
        t0 = time.perf_counter()
        arm_obj, mesh_obj = blender_io.character_to_blender(character)
        setup = time.perf_counter() - t0
        bpy.context.view_layer.update()
        ms = time_frames(arm_obj, args.frames)
        line = f"  {k} influences: Blender Armature modifier {ms:7.2f} ms/frame (setup {setup:.1f} s)"
        for t in (1, 2):
            core_ms = figures["core"].get(f"k{k}_t{t}")
            if core_ms:
                line += f" | core {t} thread{'s' if t > 1 else ''} {core_ms:.3f} ms -> {ms / core_ms:5.1f}x faster"
        print(line, flush=True)
        total, write = time_joint_writes(arm_obj, args.frames)
        print(f"    live route: rig_io.write_joint_matrices({nj - BONES} joints) {write:.2f} ms + update = "
              f"{total:.2f} ms/frame ({total / ms:.2f}x the plain pose change)", flush=True)
        for obj in (mesh_obj, arm_obj):
            data = obj.data
            bpy.data.objects.remove(obj)
            (bpy.data.meshes if isinstance(data, bpy.types.Mesh) else bpy.data.armatures).remove(data)


main()
