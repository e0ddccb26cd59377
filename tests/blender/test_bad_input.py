# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: the bad-input matrix (issue 15, "never crash Blender, never lose work"). Each case runs the
operators an artist would use (bpy.ops.myoskin.*: Character Info, Extract, Bind, Unbind, Bake, live update
through frame changes; batch.py for files) on damaged or unusual input and checks three things:
- a clear message: the operator finishes with a report, or is CANCELLED with an ERROR report, never a Python
  traceback or a bare exception text (batch: one line "myoskin batch: error: ...", exit status 1);
- no crash: the test process survives every case;
- the .blend is unchanged (vertex positions, vertex groups with their weights and order, modifiers, shape
  keys, bones) or restorable (Unbind restores the weights exactly).
Undo and Redo in the middle of live update, Undo of a Bake and an F12 render while playback runs need a
window: tests/blender/test_undo.py (gui/undo_during_live.py under xvfb-run).

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_bad_input.py
"""
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager

import bmesh
import bpy
import numpy as np

SOURCE = os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module  # noqa: E402

BATCH = os.path.join(SOURCE, "addon", "myoskin", "batch.py")
MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TMP = tempfile.mkdtemp(prefix="myoskin_test_bad_input_")

# What a message the user reads must not look like: a traceback or a bare Python/JSON exception text.
RAW = re.compile(r"Traceback|\b(KeyError|TypeError|AttributeError|IndexError|NameError|UnboundLocalError|"
                 r"ZeroDivisionError|OverflowError|JSONDecodeError|LinAlgError)\b|Expecting value|bpy_struct|"
                 r"line \d+ column \d+ \(char \d+\)|object has no attribute|unsupported operand")


# ------------------------------------------------------------------------------------------------
# Helpers: reports, snapshots, small generated characters
# ------------------------------------------------------------------------------------------------

@contextmanager
def captured_output():
    """Everything written to the process's stdout and stderr while the block runs (file-descriptor level:
    background Blender prints an operator's INFO and WARNING reports there, "Info: ..."), as a list
    holding one string after the block."""
    seen = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as f:
        os.dup2(f.fileno(), 1)
        os.dup2(f.fileno(), 2)
        try:
            yield seen
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            f.seek(0)
            text = f.read().decode("utf-8", "replace")
            seen.append(text)
            sys.stdout.write(text)  # still in the test's log


REPORT = re.compile(r"^(Info|Warning|Error): (.*)$", re.M)


def assert_clear(message, *expected):
    assert message and message.strip(), "empty message"
    assert not RAW.search(message), f"not a clear message: {message!r}"
    for part in expected:  # hygiene: a message may be checked for clarity alone
        assert part in message, f"{part!r} not in {message!r}"


def call(op, **kwargs):
    """Run an operator; returns (status, message): 'FINISHED' or 'CANCELLED' and the text of its reports.
    Every report must be clear, and a cancelled operator must say why (background Blender raises an
    operator's ERROR report as RuntimeError and prints INFO and WARNING reports)."""
    error = ""
    with captured_output() as out:
        try:
            result = op(**kwargs)
        except RuntimeError as e:
            error = str(e)
            result = {'CANCELLED'}
    assert "Traceback" not in error and "Traceback" not in out[0], \
        f"{op.idname_py()} raised instead of reporting:\n{error}\n{out[0]}"
    status = next(iter(result))
    assert status in ('FINISHED', 'CANCELLED'), (op.idname_py(), result)
    if status == 'CANCELLED':
        reports = [m for _level, m in REPORT.findall(error)] or [error.strip()]
        assert error.strip(), f"{op.idname_py()} cancelled without a message"
    else:
        reports = [m for _level, m in REPORT.findall(out[0])]
    message = "; ".join(r.strip() for r in reports if r.strip())
    for r in reports:  # hygiene: a finished operator need not report anything
        assert_clear(r)
    return status, message


def vertex_groups(obj):
    names = {g.index: g.name for g in obj.vertex_groups}
    out = {n: {} for n in names.values()}
    for v in obj.data.vertices:
        for g in v.groups:
            out[names[g.group]][v.index] = g.weight
    return out


def snapshot(*objs):
    """What must not change: per object its mesh (positions, faces), vertex groups with weights, modifiers
    in order, shape keys; an armature's bones (names, heads, tails, parents, deform)."""
    state = {}
    for o in objs:
        entry = {"name": o.name, "matrix": [tuple(r) for r in o.matrix_world]}
        if o.type == 'MESH':
            me = o.data
            co = np.empty(len(me.vertices) * 3, dtype=np.float32)
            me.vertices.foreach_get("co", co)
            loops = np.empty(len(me.loops), dtype=np.int32)
            me.loops.foreach_get("vertex_index", loops)
            entry.update(co=co.tobytes(), loops=loops.tobytes(), polygons=len(me.polygons),
                         groups=vertex_groups(o) if len(me.vertices) <= 200000 else len(o.vertex_groups),
                         group_order=[g.name for g in o.vertex_groups],
                         modifiers=[(m.name, m.type, getattr(getattr(m, "object", None), "name", None))
                                    for m in o.modifiers],
                         shape_keys=[(k.name, np.array([p.co[:] for p in k.data]).tobytes())
                                     for k in me.shape_keys.key_blocks] if me.shape_keys else [])
        elif o.type == 'ARMATURE':
            entry["bones"] = [(b.name, b.head_local[:], b.tail_local[:], b.parent.name if b.parent else None,
                               b.use_deform) for b in o.data.bones]
            entry["muscles"] = len(o.myoskin.muscles)
            entry["bound"] = o.myoskin.bound
        state[o.name] = entry
    return state


def assert_unchanged(before, *objs):
    after = snapshot(*objs)
    assert after.keys() == before.keys(), (after.keys(), before.keys())
    for name in before:
        for key in before[name]:  # hygiene: every snapshot entry holds at least the name and matrix
            assert after[name][key] == before[name][key], f"{name}: {key} changed"


def new_scene():
    bpy.ops.wm.read_homefile(use_empty=True)


def synthetic_arm():
    """The procedural arm through its operator: (armature, skin)."""
    new_scene()
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    return skin.parent, skin


def make_armature(name, heads_tails, parents=None):
    """An armature object with one bone per (head, tail), chained (each the parent of the next) unless
    `parents` is given."""
    data = bpy.data.armatures.new(name)
    arm = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    bones = []
    for i, (head, tail) in enumerate(heads_tails):
        eb = data.edit_bones.new(f"b{i:04d}")
        eb.head, eb.tail = head, tail
        parent = (i - 1 if i else -1) if parents is None else parents[i]
        if parent >= 0:
            eb.parent = bones[parent]
        bones.append(eb)
    bpy.ops.object.mode_set(mode='OBJECT')
    return arm


def tube(name, length=1.0, radius=0.05, rings=24, segs=12, caps=True):
    """A closed tube along +Y (rings x segs vertices, quads, two triangle-fan caps): vertices, faces."""
    y = np.linspace(0.0, length, rings)
    a = np.linspace(0.0, 2 * math.pi, segs, endpoint=False)
    verts = np.stack([np.repeat(np.ones(rings), segs) * np.tile(radius * np.cos(a), rings),
                      np.repeat(y, segs), np.tile(radius * np.sin(a), rings)], axis=1)
    faces = [(r * segs + s, r * segs + (s + 1) % segs, (r + 1) * segs + (s + 1) % segs, (r + 1) * segs + s)
             for r in range(rings - 1) for s in range(segs)]
    if caps:
        verts = np.vstack([verts, [[0.0, 0.0, 0.0], [0.0, length, 0.0]]])
        bottom, top = len(verts) - 2, len(verts) - 1
        faces += [(bottom, (s + 1) % segs, s) for s in range(segs)]
        faces += [(top, (rings - 1) * segs + s, (rings - 1) * segs + (s + 1) % segs) for s in range(segs)]
    return verts, faces


def skinned_mesh(name, arm, verts, faces, weights_by_bone):
    """A mesh object skinned to `arm`: an Armature modifier and one vertex group per bone name,
    weights_by_bone = {bone: (vertex indices, weight)}."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    obj.parent = arm
    for bone, (ids, w) in weights_by_bone.items():
        obj.vertex_groups.new(name=bone).add([int(i) for i in ids], w, 'REPLACE')
    mod = obj.modifiers.new("Armature", 'ARMATURE')
    mod.object = arm
    return obj


def tube_character(name="Tube", bones=2, rings=24, segs=12, length=1.0):
    """A chain of `bones` bones along +Y and a closed tube skinned to them ring by ring."""
    new_scene()
    ys = np.linspace(0.0, length, bones + 1)
    arm = make_armature(name + "_rig", [((0, ys[i], 0), (0, ys[i + 1], 0)) for i in range(bones)])
    verts, faces = tube(name, length=length, rings=rings, segs=segs)
    bone_of = np.minimum((verts[:, 1] / length * bones).astype(int), bones - 1)
    names = [b.name for b in arm.data.bones]
    weights = {names[b]: (np.flatnonzero(bone_of == b), 1.0) for b in range(bones)}
    return arm, skinned_mesh(name, arm, verts, faces, weights)


def character_ops(arm, skin):
    """Character Info and Extract with the mesh active and with the armature active: [(status, message)]."""
    results = []
    for active in (skin, arm):
        bpy.context.view_layer.objects.active = active
        results.append(call(bpy.ops.myoskin.character_info))
        results.append(call(bpy.ops.myoskin.extract_muscles))
    return results


def extract_then_bind(arm, skin, expect=None):
    """Extract with the armature active; when it found muscles, Bind, pose, Unbind. Checks the weights are
    restored exactly. Returns the extract's (status, message)."""
    bpy.context.view_layer.objects.active = arm
    status, message = call(bpy.ops.myoskin.extract_muscles)
    if expect:
        assert expect in message, message
    if status == 'FINISHED' and len(arm.myoskin.muscles):
        before = snapshot(arm, skin)
        weights = vertex_groups(skin)
        bound, text = call(bpy.ops.myoskin.bind)
        assert bound == 'FINISHED', text
        arm.pose.bones[0].rotation_mode = 'XYZ'
        arm.pose.bones[-1].rotation_euler = (0.7, 0.0, 0.0)
        bpy.context.view_layer.update()
        assert not module("runtime").last_error(arm), module("runtime").last_error(arm)
        arm.pose.bones[-1].rotation_euler = (0.0, 0.0, 0.0)
        assert call(bpy.ops.myoskin.unbind)[0] == 'FINISHED'
        assert vertex_groups(skin) == weights
        before[arm.name]["bound"] = False
        assert_unchanged(before, arm, skin)
    return status, message


# ------------------------------------------------------------------------------------------------
# Files: truncated and corrupted .glb (batch.py, as users run it, and the core's loader)
# ------------------------------------------------------------------------------------------------

def batch(*args):
    cmd = runner.blender_command("--python-exit-code", "1", "-P", BATCH, "--", *args)
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=dict(os.environ))
    return done.returncode, done.stdout + done.stderr


def good_glb():
    """A valid .glb of the synthetic arm (written by Blender's exporter), made once."""
    path = os.path.join(TMP, "arm.glb")
    if not os.path.exists(path):
        arm, skin = synthetic_arm()
        for o in bpy.context.view_layer.objects:
            o.select_set(o in (arm, skin))
        module("gltf_io").export_gltf(path)
    return path


def damaged_files():
    """(label, path) of damaged copies of a valid .glb: empty, truncated in the header, in the JSON chunk
    and in the binary chunk, the JSON chunk overwritten with garbage, the binary chunk with noise, a chunk
    length far past the end."""
    with open(good_glb(), "rb") as f:
        data = f.read()
    assert data[:4] == b"glTF" and len(data) > 1000, len(data)
    json_length = int.from_bytes(data[12:16], "little")
    rng = np.random.default_rng(15)
    garbage_json = bytearray(data)
    garbage_json[20 + json_length // 3:20 + json_length // 3 + 64] = b"\x00{]\xff" * 16
    noisy_bin = bytearray(data)
    start = 20 + json_length + 8
    noisy_bin[start:] = rng.integers(0, 256, len(data) - start, dtype=np.uint8).tobytes()
    huge_chunk = bytearray(data)
    huge_chunk[12:16] = (0x7FFFFFF0).to_bytes(4, "little")
    cases = {"empty": b"", "truncated_header": data[:10], "truncated_json": data[:20 + json_length // 2],
             "truncated_bin": data[:len(data) - len(data) // 4], "garbage_json": bytes(garbage_json),
             "noisy_bin": bytes(noisy_bin), "huge_chunk_length": bytes(huge_chunk)}
    out = []
    for label, content in cases.items():
        path = os.path.join(TMP, f"{label}.glb")
        with open(path, "wb") as f:
            f.write(content)
        out.append((label, path))
    return out


def test_damaged_glb_files_are_refused_by_the_core():
    files = damaged_files()
    assert len(files) == 7
    refused = 0
    for label, path in files:
        try:
            module("core_loader").core().load_character(path)
        except ValueError as e:
            assert_clear(str(e))
            refused += 1
        # noisy_bin may still load (the noise is only in vertex data): then it must at least be finite
    assert refused >= 6, f"only {refused} of {len(files)} damaged files refused"


def test_damaged_copies_of_a_shared_character_are_refused_by_the_core():
    """The same damage to a real character (../shared, skipped when absent), copied to a temporary folder."""
    with open(runner.shared_file(MUSCULAR), "rb") as f:
        data = f.read()
    assert data[:4] == b"glTF", data[:4]
    core = module("core_loader").core()
    cuts = (len(data) // 3, len(data) - 1000, 30)
    for k, content in enumerate([data[:n] for n in cuts] + [data[:24] + b"\xff" * 200 + data[224:]]):
        path = os.path.join(TMP, f"shared_{k}.glb")
        with open(path, "wb") as f:
            f.write(content)
        try:
            core.load_character(path)
        except ValueError as e:
            assert_clear(str(e))
        else:
            raise AssertionError(f"damaged copy {k} of {MUSCULAR} was loaded")


def test_batch_with_damaged_files_says_error_and_writes_nothing():
    files = damaged_files()
    assert files
    # two of them (each costs a Blender start; the core's loader gets all seven above)
    chosen = [(label, path) for label, path in files if label in ("truncated_bin", "garbage_json")]
    assert len(chosen) == 2
    for label, path in chosen:
        out = os.path.join(TMP, f"{label}_out.blend")
        code, log = batch("--input", path, "extract", "-o", out)
        assert code == 1, (label, code, log[-2000:])
        lines = [ln for ln in log.splitlines() if ln.startswith("myoskin batch: error:")]
        assert len(lines) == 1, (label, log[-3000:])
        assert "Traceback" not in log, (label, log[-3000:])
        # the reason is Blender's glTF importer's own text (e.g. "Bad glTF: json error: ..."), after ours
        assert lines[0].startswith(f"myoskin batch: error: cannot read {path}"), lines[0]
        print(f"  {label}: {lines[0]}")
        assert not os.path.exists(out), label
    # a .blend cut in half (Blender's own reader says why)
    synthetic_arm()
    whole, half = os.path.join(TMP, "whole.blend"), os.path.join(TMP, "half.blend")
    bpy.ops.wm.save_as_mainfile(filepath=whole, compress=False, copy=True)
    with open(whole, "rb") as f:
        data = f.read()
    with open(half, "wb") as f:
        f.write(data[:len(data) // 2])
    code, log = batch("--input", half, "extract", "-o", os.path.join(TMP, "half_out.blend"))
    lines = [ln for ln in log.splitlines() if ln.startswith("myoskin batch: error:")]
    assert code == 1 and len(lines) == 1 and "Traceback" not in log, log[-3000:]
    assert lines[0].startswith(f"myoskin batch: error: cannot read {half}"), lines[0]
    assert not os.path.exists(os.path.join(TMP, "half_out.blend"))
    print(f"  half .blend: {lines[0]}")


# ------------------------------------------------------------------------------------------------
# Meshes: NaN/Inf, no faces, duplicate vertices, non-manifold and open skins, flipped normals,
# one vertex, a million vertices
# ------------------------------------------------------------------------------------------------

def set_coordinates(skin, changes):
    """Write vertex coordinates with foreach_set (RNA clamps single assignments to +-FLT_MAX)."""
    co = np.empty(len(skin.data.vertices) * 3, dtype=np.float32)
    skin.data.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    for (vertex, axis), value in changes.items():
        co[vertex, axis] = value
    skin.data.vertices.foreach_set("co", co.ravel())
    skin.data.update()


def test_nan_and_inf_vertices():
    for bad in (float("nan"), float("inf"), -float("inf")):
        arm, skin = synthetic_arm()
        set_coordinates(skin, {(100, 0): bad, (2000, 2): bad})
        assert not np.isfinite(skin.data.vertices[100].co[0])
        before = snapshot(arm, skin)
        results = character_ops(arm, skin)
        assert len(results) == 4
        for status, message in results:
            assert status == 'CANCELLED', (bad, message)
            assert_clear(message, "NaN or infinite")
        assert_unchanged(before, arm, skin)
    # the largest float32 (what a broken exporter or RNA's clamping leaves): finite, so the core analyses it;
    # a message either way, nothing changed when refused
    arm, skin = synthetic_arm()
    set_coordinates(skin, {(100, 0): np.finfo(np.float32).max, (101, 1): -np.finfo(np.float32).max})
    before = snapshot(arm, skin)
    results = character_ops(arm, skin)
    assert len(results) == 4
    for status, message in results:
        assert_clear(message)
        if status == 'CANCELLED':
            assert_unchanged(before, arm, skin)


def test_mesh_without_faces():
    arm, skin = synthetic_arm()
    bm = bmesh.new()
    bm.from_mesh(skin.data)
    bmesh.ops.delete(bm, geom=list(bm.faces), context='FACES_ONLY')
    bm.to_mesh(skin.data)
    bm.free()
    assert len(skin.data.polygons) == 0 and len(skin.data.vertices) > 0
    before = snapshot(arm, skin)
    results = character_ops(arm, skin)
    assert len(results) == 4
    for status, message in results:
        assert status == 'CANCELLED', message
        assert_clear(message)
        assert "face" in message or "triangle" in message, message
    assert_unchanged(before, arm, skin)


def test_duplicate_vertices_split_skin():
    """Every face on its own vertices (edges split): the weld joins them, extraction works as usual."""
    arm, skin = synthetic_arm()
    bm = bmesh.new()
    bm.from_mesh(skin.data)
    bmesh.ops.split_edges(bm, edges=list(bm.edges))
    bm.to_mesh(skin.data)
    bm.free()
    assert len(skin.data.vertices) > 3 * len(skin.data.polygons) - 10
    status, message = extract_then_bind(arm, skin)
    assert status == 'FINISHED', message
    assert_clear(message, "Extracted")


def test_duplicate_vertices_stacked():
    """A second copy of every vertex, unused by any face (a bad merge): refused or extracted, clearly."""
    arm, skin = synthetic_arm()
    n = len(skin.data.vertices)
    bm = bmesh.new()
    bm.from_mesh(skin.data)
    bmesh.ops.duplicate(bm, geom=list(bm.verts))  # loose copies
    bm.to_mesh(skin.data)
    bm.free()
    assert len(skin.data.vertices) == 2 * n
    before = snapshot(arm, skin)
    status, message = call(bpy.ops.myoskin.character_info)
    assert status == 'FINISHED', message
    status, message = extract_then_bind(arm, skin)
    assert_clear(message)
    if status == 'CANCELLED':
        assert_unchanged(before, arm, skin)


def test_non_manifold_and_open_skins():
    # open: a band of faces removed round the forearm; non-manifold: a fin face on edges of the upper arm
    for kind in ("open", "non_manifold", "open_everywhere"):
        arm, skin = synthetic_arm()
        bm = bmesh.new()
        bm.from_mesh(skin.data)
        bm.faces.ensure_lookup_table()
        if kind == "open":
            centers = np.array([f.calc_center_median()[:] for f in bm.faces])
            axis = int(np.argmax(centers.max(axis=0) - centers.min(axis=0)))  # along the arm
            lo, hi = np.quantile(centers[:, axis], [0.60, 0.62])  # a ring round the forearm
            band = [f for f, c in zip(bm.faces, centers[:, axis]) if lo <= c <= hi]
            assert len(band) > 20, len(band)
            bmesh.ops.delete(bm, geom=band, context='FACES')
        elif kind == "open_everywhere":  # every other face gone: no closed loop anywhere
            bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.index % 2], context='FACES')
        else:
            fins = 0
            for e in list(bm.edges)[::50]:
                v = bm.verts.new(e.verts[0].co + (e.verts[0].normal * 0.01))
                bm.faces.new((e.verts[0], e.verts[1], v))
                fins += 1
            assert fins > 10
        bm.to_mesh(skin.data)
        bm.free()
        status, message = call(bpy.ops.myoskin.character_info)
        assert status == 'FINISHED', message
        assert ("open" if kind.startswith("open") else "non-manifold") in message, message
        before = snapshot(arm, skin)
        status, message = extract_then_bind(arm, skin)
        assert_clear(message)
        if status == 'CANCELLED':
            assert_unchanged(before, arm, skin)


def test_flipped_normals():
    arm, skin = synthetic_arm()
    bm = bmesh.new()
    bm.from_mesh(skin.data)
    bmesh.ops.reverse_faces(bm, faces=list(bm.faces))
    bm.to_mesh(skin.data)
    bm.free()
    status, message = extract_then_bind(arm, skin)
    assert_clear(message)
    assert status == 'FINISHED', message


def test_one_vertex_mesh():
    new_scene()
    arm = make_armature("One_rig", [((0, 0, 0), (0, 1, 0))])
    skin = skinned_mesh("One", arm, [(0.0, 0.5, 0.0)], [], {"b0000": ([0], 1.0)})
    before = snapshot(arm, skin)
    results = character_ops(arm, skin)
    assert len(results) == 4
    for status, message in results:
        assert status == 'CANCELLED', message
        assert_clear(message)
    assert_unchanged(before, arm, skin)
    # a single triangle: has faces, but nothing to analyse
    new_scene()
    arm = make_armature("Tri_rig", [((0, 0, 0), (0, 1, 0))])
    skin = skinned_mesh("Tri", arm, [(0, 0, 0), (0.1, 0.5, 0), (0, 1, 0.1)], [(0, 1, 2)],
                        {"b0000": ([0, 1, 2], 1.0)})
    before = snapshot(arm, skin)
    for status, message in character_ops(arm, skin):
        assert_clear(message)
    assert_unchanged(before, arm, skin)


MILLION = 1_000_000


def test_million_vertex_mesh_is_handled_quickly():
    """1,000,000 vertices (a 1000 x 1000 tube, 2 bones): Character Info and Extract finish or refuse with a
    message in bounded time (measured and printed)."""
    new_scene()
    arm = make_armature("Big_rig", [((0, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 2, 0))])
    rings = segs = 1000
    y = np.repeat(np.linspace(0.0, 2.0, rings), segs)
    a = np.tile(np.linspace(0.0, 2 * math.pi, segs, endpoint=False), rings)
    co = np.stack([0.1 * np.cos(a), y, 0.1 * np.sin(a)], axis=1).astype(np.float32)
    r, s = np.meshgrid(np.arange(rings - 1), np.arange(segs), indexing="ij")
    r, s = r.ravel(), s.ravel()
    quads = np.stack([r * segs + s, r * segs + (s + 1) % segs, (r + 1) * segs + (s + 1) % segs,
                      (r + 1) * segs + s], axis=1).astype(np.int32)
    me = bpy.data.meshes.new("Big")
    me.vertices.add(len(co))
    me.vertices.foreach_set("co", co.ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.ravel())
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    try:
        me.polygons.foreach_set("loop_total", np.full(len(quads), 4, dtype=np.int32))
    except (AttributeError, TypeError, RuntimeError):
        pass
    me.update(calc_edges=True)
    assert len(me.vertices) == MILLION
    skin = bpy.data.objects.new("Big", me)
    bpy.context.scene.collection.objects.link(skin)
    skin.parent = arm
    lower = np.flatnonzero(co[:, 1] < 1.0).tolist()
    upper = np.flatnonzero(co[:, 1] >= 1.0).tolist()
    skin.vertex_groups.new(name="b0000").add(lower, 1.0, 'REPLACE')
    skin.vertex_groups.new(name="b0001").add(upper, 1.0, 'REPLACE')
    skin.modifiers.new("Armature", 'ARMATURE').object = arm
    before = snapshot(arm, skin)
    bpy.context.view_layer.objects.active = arm
    # Extract only (Character Info reads the mesh the same way); ~8 s on an idle 2-core machine with
    # Blender 3.4 (weld 2.8 s, reading the vertex groups 2.5 s, the core 1.4 s)
    start = time.perf_counter()
    status, message = call(bpy.ops.myoskin.extract_muscles)
    seconds = time.perf_counter() - start
    assert_clear(message)
    print(f"  1M vertices: extract_muscles {status} in {seconds:.1f} s: {message[:200]}")
    assert seconds < 60.0, seconds
    if status == 'CANCELLED':
        assert_unchanged(before, arm, skin)


def test_memory_budget_refuses_what_would_not_fit():
    """A farm job's memory cap (MYOSKIN_MEMORY_LIMIT, as the cgroup's memory.max or free memory would be):
    Extract and Bind stop with a message naming the memory needed, nothing changed; without the cap they run."""
    arm, skin = tube_character("Capped")
    before = snapshot(arm, skin)
    bpy.context.view_layer.objects.active = arm
    os.environ["MYOSKIN_MEMORY_LIMIT"] = "1M"
    try:
        status, message = call(bpy.ops.myoskin.extract_muscles)
    finally:
        del os.environ["MYOSKIN_MEMORY_LIMIT"]
    assert status == 'CANCELLED', message
    assert_clear(message, "needs about", "MiB of memory")
    assert_unchanged(before, arm, skin)
    status, message = call(bpy.ops.myoskin.extract_muscles)
    assert "needs about" not in message, message


# ------------------------------------------------------------------------------------------------
# Armatures: one bone, 1,000 bones, zero-length bones, zero and negative (mirrored) scale
# ------------------------------------------------------------------------------------------------

def test_one_bone_armature():
    arm, skin = tube_character("OneBone", bones=1)
    assert len(arm.data.bones) == 1
    before = snapshot(arm, skin)
    results = character_ops(arm, skin)
    assert len(results) == 4
    for status, message in results:
        assert_clear(message)
        if status == 'CANCELLED':
            assert_unchanged(before, arm, skin)


def test_thousand_bone_armature():
    start = time.perf_counter()
    arm, skin = tube_character("Chain", bones=1000, rings=1001, segs=8, length=10.0)
    assert len(arm.data.bones) == 1000 and len(skin.vertex_groups) == 1000
    print(f"  built 1000 bones in {time.perf_counter() - start:.1f} s")
    before = snapshot(arm, skin)
    start = time.perf_counter()
    status, message = extract_then_bind(arm, skin)
    print(f"  1000 bones: extract {status} in {time.perf_counter() - start:.1f} s: {message[:200]}")
    assert_clear(message)
    if status == 'CANCELLED':
        assert_unchanged(before, arm, skin)


def test_arm_with_a_thousand_bones_binds():
    """The synthetic arm with 996 more bones (a chain off the hand, deforming nothing): 1,000 bones through
    Extract, Bind, live update and Unbind."""
    arm, skin = synthetic_arm()
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    parent = arm.data.edit_bones["hand"]
    for i in range(1000 - len(arm.data.edit_bones)):
        eb = arm.data.edit_bones.new(f"extra{i:03d}")
        eb.head = parent.tail
        eb.tail = parent.tail + (parent.tail - parent.head).normalized() * 0.01
        eb.parent = parent
        parent = eb
    bpy.ops.object.mode_set(mode='OBJECT')
    assert len(arm.data.bones) == 1000
    start = time.perf_counter()
    status, message = extract_then_bind(arm, skin)
    print(f"  arm + 996 bones: extract, bind, pose, unbind in {time.perf_counter() - start:.1f} s: {message[:120]}")
    assert status == 'FINISHED', message
    assert_clear(message, "Extracted")


def test_zero_length_and_tiny_bones():
    # Blender itself deletes a zero-length bone when Edit Mode ends; a 10 micrometre bone stays: both handled
    arm, skin = tube_character("Tiny", bones=2)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    eb = arm.data.edit_bones.new("zero")
    eb.head = eb.tail = (0.0, 0.5, 0.0)
    eb = arm.data.edit_bones.new("tiny")
    eb.head, eb.tail = (0.0, 0.5, 0.0), (0.0, 0.5 + 1e-5, 0.0)
    eb.parent = arm.data.edit_bones["b0000"]
    bpy.ops.object.mode_set(mode='OBJECT')
    assert "tiny" in arm.data.bones
    skin.vertex_groups.new(name="tiny").add(list(range(0, 40)), 0.5, 'REPLACE')
    before = snapshot(arm, skin)
    for status, message in character_ops(arm, skin):
        assert_clear(message)
        if status == 'CANCELLED':
            assert_unchanged(before, arm, skin)


def test_zero_and_negative_scale():
    # the armature object scaled to 0: refused with a message; mirrored (-1 on X): extracts as usual
    arm, skin = synthetic_arm()
    arm.scale = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    before = snapshot(arm, skin)
    for status, message in character_ops(arm, skin):
        assert status == 'CANCELLED', message
        assert_clear(message, "zero scale")
    assert_unchanged(before, arm, skin)
    arm, skin = synthetic_arm()
    arm.scale = (-1.0, 1.0, 1.0)
    bpy.context.view_layer.update()
    status, message = extract_then_bind(arm, skin)
    assert status == 'FINISHED', message
    assert_clear(message, "Extracted")


def test_zero_and_negative_pose_scale_during_live_update():
    """A bound rig whose pose bones are scaled to 0 or mirrored (-1) while live update runs: Blender
    keeps running, the error (if any) is stored for the panels, Unbind restores every weight."""
    arm, skin = synthetic_arm()
    weights = vertex_groups(skin)
    assert call(bpy.ops.myoskin.extract_muscles)[0] == 'FINISHED'
    assert call(bpy.ops.myoskin.bind)[0] == 'FINISHED'
    runtime = module("runtime")
    for bone, scale in (("forearm", (0.0, 0.0, 0.0)), ("upper_arm", (-1.0, 1.0, 1.0)),
                        ("forearm", (1.0, -1.0, 1.0)), ("forearm", (1e-30, 1e-30, 1e-30))):
        arm.pose.bones[bone].scale = scale
        bpy.context.view_layer.update()
        bpy.context.scene.frame_set(2)
        message = runtime.last_error(arm)
        if message:
            assert_clear(message)
        points = module("blender_io").evaluated_vertices(skin)
        assert len(points) == len(skin.data.vertices)
        arm.pose.bones[bone].scale = (1.0, 1.0, 1.0)
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = skin
    assert call(bpy.ops.myoskin.unbind)[0] == 'FINISHED'
    assert vertex_groups(skin) == weights


# ------------------------------------------------------------------------------------------------
# Shape keys and modifiers stacked before or after the Armature modifier
# ------------------------------------------------------------------------------------------------

def test_modifier_stacks_and_shape_keys():
    """Shape keys, and Subdivision, Mirror and Corrective Smooth before or after the Armature modifier: Extract,
    Bind, pose, Unbind work and leave the stack (and the shape keys) as they were. Subdivision without its
    limit surface: Blender 3.4 spends ~20 s building the limit surface of this 67k-triangle skin."""
    for stack in (("SUBSURF", "ARMATURE"), ("MIRROR", "ARMATURE", "CORRECTIVE_SMOOTH")):
        arm, skin = synthetic_arm()
        skin.shape_key_add(name="Basis")
        key = skin.shape_key_add(name="Flex")
        key.data[10].co.x += 0.01
        key.value = 0.5
        skin.vertex_groups.new(name="Mask").add(list(range(100)), 1.0, 'REPLACE')  # a group of no bone, last
        skin.modifiers.remove(skin.modifiers["Armature"])
        for kind in stack:  # the stack in this order (no operator: each one evaluates the whole scene)
            mod = skin.modifiers.new(kind.title(), kind)
            if kind == "ARMATURE":
                mod.object, mod.use_vertex_groups, mod.use_bone_envelopes = arm, True, False
            elif kind == "SUBSURF":
                mod.levels, mod.use_limit_surface, mod.quality = 1, False, 1
        assert [m.type for m in skin.modifiers] == list(stack), ([m.type for m in skin.modifiers], stack)
        bpy.context.view_layer.objects.active = skin
        start = time.perf_counter()
        status, message = extract_then_bind(arm, skin)
        print(f"  {' > '.join(stack)}: {status} in {time.perf_counter() - start:.1f} s")
        assert status == 'FINISHED', (stack, message)
        assert_clear(message)
        assert [m.type for m in skin.modifiers] == list(stack), stack


# ------------------------------------------------------------------------------------------------
# Library-linked (read-only) characters
# ------------------------------------------------------------------------------------------------

def test_library_linked_character_is_refused():
    arm, skin = synthetic_arm()
    names = (arm.name, skin.name)
    path = os.path.join(TMP, "library.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    new_scene()
    with bpy.data.libraries.load(path, link=True) as (src, dst):
        dst.objects = [n for n in src.objects if n in names]
    assert len(dst.objects) == 2
    for obj in dst.objects:
        bpy.context.scene.collection.objects.link(obj)
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    assert arm.library is not None and skin.library is not None
    before = snapshot(arm, skin)
    for active in (skin, arm):
        bpy.context.view_layer.objects.active = active
        status, message = call(bpy.ops.myoskin.character_info)
        assert status == 'FINISHED', message  # reading is fine
        for op in (bpy.ops.myoskin.extract_muscles, bpy.ops.myoskin.detect_bone_roles, bpy.ops.myoskin.bind,
                   bpy.ops.myoskin.unbind, bpy.ops.myoskin.bake_action):
            status, message = call(op)
            assert status == 'CANCELLED', (op.idname_py(), message)
            assert_clear(message)
    assert_unchanged(before, arm, skin)
    status, message = call(bpy.ops.myoskin.extract_muscles)
    assert "linked" in message and "library" in message, message


# ------------------------------------------------------------------------------------------------
# Muscle state in the .blend edited by hand into nonsense (Text blocks and ID properties are data:
# parsed with bounded size, never executed)
# ------------------------------------------------------------------------------------------------

def bound_arm():
    """The synthetic arm extracted and bound, its forearm keyed over frames 1-10: (arm, skin, weights
    before the bind)."""
    arm, skin = synthetic_arm()
    weights = vertex_groups(skin)
    assert call(bpy.ops.myoskin.extract_muscles)[0] == 'FINISHED'
    assert call(bpy.ops.myoskin.bind)[0] == 'FINISHED'
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, degrees in ((1, 0.0), (10, 100.0)):
        pb.rotation_euler = (math.radians(degrees), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    return arm, skin, weights


def test_bind_record_edited_into_nonsense():
    arm, skin, weights = bound_arm()
    marker = os.path.join(TMP, "executed")
    record = module("binding").read_bind_record(arm)
    short = dict(record, bone_heads=record["bone_heads"][:-1])
    binding = module("binding")
    cases = {
        "python code": f"__import__('os').makedirs({marker!r})",
        "wrong types": '{"bone_names": 5, "joint_names": [], "muscles": 3}',
        "lists of different lengths": json.dumps(short),
        "nested too deeply": "[" * 200000 + "]" * 200000,
        "too large": json.dumps(dict(record, padding="x" * 4096)),
    }
    runtime = module("runtime")
    scene = bpy.context.scene
    for k, (label, content) in enumerate(cases.items()):
        if not arm.myoskin.bound:
            assert call(bpy.ops.myoskin.bind)[0] == 'FINISHED', label
        arm.myoskin.live = True
        arm.myoskin.bind_text.from_string(content)
        module("live").on_reload()  # what load_post / undo_post do: the cached rig is dropped
        saved_limit = binding.MAX_RECORD_CHARS
        if label == "too large":
            binding.MAX_RECORD_CHARS = len(content) - 1
        try:
            scene.frame_set(3 + k % 5)  # live update meets the damaged record
            message = runtime.last_error(arm)
            assert_clear(message, "bind record")
            assert not arm.myoskin.live, label
            bpy.context.view_layer.objects.active = skin
            status, message = call(bpy.ops.myoskin.bake_action, frame_start=1, frame_end=3)
            assert status == 'CANCELLED', (label, message)
            assert_clear(message, "bind record")
            print(f"  {label}: {message}")
            if k % 2:  # Unbind without the record: every weight back from the backup
                status, message = call(bpy.ops.myoskin.unbind)
                assert status == 'FINISHED', (label, message)
                assert_clear(message)
                assert vertex_groups(skin) == weights, label
                assert not module("rig_io").muscle_bone_names(arm), label
            else:  # Bind again writes a new record; live update works again
                assert call(bpy.ops.myoskin.bind)[0] == 'FINISHED', label
                arm.myoskin.live = True
                scene.frame_set(8)
                assert not runtime.last_error(arm), runtime.last_error(arm)
                runtime.clear_error()
        finally:
            binding.MAX_RECORD_CHARS = saved_limit
    assert not os.path.exists(marker), "the bind record was executed"
    if arm.myoskin.bound:
        assert call(bpy.ops.myoskin.unbind)[0] == 'FINISHED'
    assert vertex_groups(skin) == weights


def test_muscle_data_and_weight_backup_edited_into_nonsense():
    arm, skin, weights = bound_arm()
    state = arm.myoskin
    muscle_io = module("muscle_io")
    bpy.context.view_layer.objects.active = skin
    # a muscle's stored data: garbage, another document, too large; Bind and Refresh say which muscle
    good = state.muscles[0].data
    for label, data in (("garbage", "{{{ not json"), ("not muscles", '{"format": "other"}'),
                        ("code", "__import__('os').system('false')"), ("too large", good + " " * 64)):
        state.muscles[0].data = data
        saved = muscle_io.MAX_DATA_CHARS
        if label == "too large":
            muscle_io.MAX_DATA_CHARS = len(good)
        try:
            for op in (bpy.ops.myoskin.bind, bpy.ops.myoskin.refresh_muscles):
                status, message = call(op)
                assert status == 'CANCELLED', (label, op.idname_py(), message)
                assert_clear(message, state.muscles[0].name)
            print(f"  muscle data {label}: {message}")
        finally:
            muscle_io.MAX_DATA_CHARS = saved
        assert state.bound and module("rig_io").muscle_bone_names(arm), label  # the bound rig is kept
    state.muscles[0].data = good
    # the muscles.json Text is output only: nonsense in it is rewritten by the next edit
    state.muscles_text.from_string("nonsense")
    assert call(bpy.ops.myoskin.refresh_muscles)[0] == 'FINISHED'
    assert json.loads(state.muscles_text.as_string())["format"] == "myoskin.muscles"
    # settings stored as ID properties past their UI ranges
    for key, value in (("joints", 10 ** 9), ("joints", -5), ("bulge", float("nan")), ("bulge", 1e300),
                       ("wrap_radius", float("inf"))):
        saved = state.muscles[1].get(key)
        state.muscles[1][key] = value
        start = time.perf_counter()
        status, message = call(bpy.ops.myoskin.bind)
        assert_clear(message)
        assert time.perf_counter() - start < 20.0, (key, value)
        print(f"  {key} = {value}: {status}: {message}")
        if saved is None:
            del state.muscles[1][key]
        else:
            state.muscles[1][key] = saved
        assert state.bound, (key, value, "a refused Bind keeps the current bind")
    # the weight backup (an ID property on the skin): Unbind refuses and changes nothing
    backup = skin["myoskin_original_weights"].to_dict()
    bones = len(arm.data.bones)
    for label, damaged in (("a string", "nonsense"),
                           ("vertex out of range", {"upper_arm": {"index": 0, "vertices": [10 ** 9], "weights": [1.0]}}),
                           ("missing keys", {"upper_arm": {"vertices": [1]}}),
                           ("lengths differ", {"upper_arm": {"index": 0, "vertices": [1, 2], "weights": [0.5]}})):
        skin["myoskin_original_weights"] = damaged
        before = vertex_groups(skin)
        status, message = call(bpy.ops.myoskin.unbind)
        assert status == 'CANCELLED', (label, message)
        assert_clear(message, "weight backup")
        assert vertex_groups(skin) == before and len(arm.data.bones) == bones and state.bound, label
        print(f"  weight backup {label}: {message}")
    skin["myoskin_original_weights"] = backup
    assert call(bpy.ops.myoskin.unbind)[0] == 'FINISHED'
    assert vertex_groups(skin) == weights


# ------------------------------------------------------------------------------------------------
# Save, reload and undo in the middle of live update and during a bake; F12 render of the animation
# ------------------------------------------------------------------------------------------------

def test_save_and_reload_during_live_update_and_bake():
    arm, skin, weights = bound_arm()
    names = (arm.name, skin.name)
    scene = bpy.context.scene
    saves = {}

    def autosave(scene, depsgraph=None):  # as an autosave or a script would, from a frame change
        key = "bake" if "baking" in saves else "live"
        if scene.frame_current == 5 and key not in saves:
            path = os.path.join(TMP, f"saved_during_{key}.blend")
            bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
            saves[key] = path

    bpy.app.handlers.frame_change_post.append(autosave)
    try:
        for frame in range(1, 9):
            scene.frame_set(frame)
        scene.frame_set(5)
        live_frame5 = module("blender_io").evaluated_vertices(skin)
        saves["baking"] = True
        bpy.context.view_layer.objects.active = skin
        status, message = call(bpy.ops.myoskin.bake_action, frame_start=1, frame_end=8)
        assert status == 'FINISHED', message
    finally:
        bpy.app.handlers.frame_change_post.remove(autosave)
    assert "live" in saves and "bake" in saves, saves
    assert not module("runtime").last_error(arm)
    # the file saved in the middle of playback opens and plays the same skin
    bpy.ops.wm.open_mainfile(filepath=saves["live"])
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    assert arm.myoskin.bound and arm.myoskin.live
    bpy.context.scene.frame_set(1)
    bpy.context.scene.frame_set(5)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - live_frame5).max() < 1e-5
    # reload in the middle of playback (the data replaced as undo replaces it): playback goes on, exact
    for frame in (6, 7):
        bpy.context.scene.frame_set(frame)
    bpy.ops.wm.open_mainfile(filepath=saves["live"])
    module("live").on_reload()
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    bpy.context.scene.frame_set(5)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - live_frame5).max() < 1e-5
    assert not module("runtime").last_error(arm)
    # the file saved during the bake: its state is consistent, Unbind restores every weight
    bpy.ops.wm.open_mainfile(filepath=saves["bake"])
    arm, skin = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
    assert arm.myoskin.bound
    module("binding").read_bind_record(arm)
    bpy.context.view_layer.objects.active = skin
    status, message = call(bpy.ops.myoskin.bake_action, frame_start=1, frame_end=3)
    assert status == 'FINISHED', message
    assert call(bpy.ops.myoskin.unbind)[0] == 'FINISHED'
    assert vertex_groups(skin) == weights


def test_f12_render_of_the_animation_while_live():
    """Render > Render Animation (Cycles, 16 x 16, 1 sample) over frames 1-3 of a bound, live rig: the
    handlers run on the render's frame changes; no error, the scene returns to its frame unchanged."""
    arm, skin, _weights = bound_arm()
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (0.0, -3.0, 0.3)
    camera.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = camera
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.filepath = os.path.join(TMP, "render_")
    scene.render.image_settings.file_format = 'PNG'
    scene.frame_set(2)
    before = module("blender_io").evaluated_vertices(skin)
    assert bpy.ops.render.render(animation=True) == {'FINISHED'}
    written = sorted(f for f in os.listdir(TMP) if f.startswith("render_"))
    assert len(written) == 3, written
    assert scene.frame_current == 2 and arm.myoskin.live and arm.myoskin.bound
    assert not module("runtime").last_error(arm), module("runtime").last_error(arm)
    assert np.abs(module("blender_io").evaluated_vertices(skin) - before).max() < 1e-6


runner.run()
