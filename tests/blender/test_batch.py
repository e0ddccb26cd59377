# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: the batch entry point addon/myoskin/batch.py, run as users run it (its own Blender process):
.blend in and .glb in, extract + bind + bake + PC2 + glTF, out.blend that plays the baked state; clear errors.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_batch.py
"""
import os
import subprocess
import sys
import tempfile

import addon_utils
import bpy
import numpy as np

SOURCE = os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "tests", "blender"))
import blender_test_runner as runner  # noqa: E402

BATCH = os.path.join(SOURCE, "addon", "myoskin", "batch.py")
MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TMP = tempfile.mkdtemp(prefix="myoskin_test_batch_")


def batch(*args, blend=None):
    """Run the batch script in a fresh Blender; returns (exit code, stdout + stderr)."""
    cmd = runner.blender_command(*([blend] if blend else []), "--python-exit-code", "1", "-P", BATCH, "--", *args)
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=dict(os.environ))
    return done.returncode, done.stdout + done.stderr


def arm_blend(path):
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    pb = skin.parent.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in ((1, 0.0), (6, 110.0)):
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return skin.name, skin.parent.name


def test_batch_blend_extract_bind_bake():
    src, out = os.path.join(TMP, "arm.blend"), os.path.join(TMP, "out.blend")
    pc2, glb = os.path.join(TMP, "skin.pc2"), os.path.join(TMP, "out.glb")
    skin_name, arm_name = arm_blend(src)
    code, log = batch("extract", "--bind", "--bake", "1-6", "--pc2", pc2, "--gltf", glb, "-o", out, blend=src)
    assert code == 0, log
    assert "extracted" in log and "bound" in log and "baked" in log, log
    assert os.path.isfile(pc2) and os.path.isfile(glb) and os.path.isfile(out)
    # the glTF carries the helper bones as skin joints and their baked animation
    import json
    import struct
    with open(glb, "rb") as f:
        data = f.read()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    joint_nodes = {doc["nodes"][j]["name"] for j in doc["skins"][0]["joints"]}
    muscle_joints = {n for n in joint_nodes if ".j" in n}
    assert muscle_joints, joint_nodes
    animated = {doc["nodes"][c["target"]["node"]]["name"] for a in doc.get("animations", []) for c in a["channels"]
                if c["target"].get("node") is not None and c["target"]["path"] == "scale"}
    assert muscle_joints <= animated, muscle_joints - animated
    # the result plays the baked muscles with the add-on disabled
    addon_utils.disable(runner.ADDON, default_set=True)
    try:
        bpy.ops.wm.open_mainfile(filepath=out)
        skin = bpy.data.objects[skin_name]
        assert any(b.get("myoskin_joint") for b in bpy.data.objects[arm_name].data.bones)
        scene = bpy.context.scene
        positions = []
        for frame in range(1, 7):
            scene.frame_set(frame)
            ev = skin.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
            co = np.empty(3 * len(ev.vertices), dtype=np.float32)
            ev.vertices.foreach_get("co", co)
            positions.append(co.reshape(-1, 3))
    finally:
        addon_utils.enable(runner.ADDON, default_set=True)
    frames = runner.core().read_pc2(pc2)["frames"]
    err = max(float(np.abs(frames[k] - positions[k]).max()) for k in range(6))
    assert err < 1e-5, f"baked playback without the add-on differs from the core's PC2 by {err:.3g} m"
    assert np.abs(positions[5] - positions[0]).max() > 0.05


def test_batch_glb_input():
    path = runner.shared_file(MUSCULAR)
    out = os.path.join(TMP, "mh.blend")
    code, log = batch("--input", path, "extract", "--bind", "-o", out)
    assert code == 0, log
    bpy.ops.wm.open_mainfile(filepath=out)
    arms = [o for o in bpy.data.objects if o.type == 'ARMATURE']
    assert len(arms) == 1 and arms[0].myoskin.bound and len(arms[0].myoskin.muscles) >= 5


def test_batch_errors():
    code, log = batch("--input", os.path.join(TMP, "missing.glb"), "extract")
    assert code == 1 and "myoskin batch: error: no such file" in log, log
    code, log = batch("extract")  # empty scene: no skinned mesh
    assert code == 1 and "0 skinned meshes" in log, log
    src = os.path.join(TMP, "arm2.blend")
    arm_blend(src)
    code, log = batch("--bake", "1-5", blend=src)  # nothing extracted
    assert code == 1 and "run Extract Muscles first" in log, log
    code, log = batch("extract", "--bind", "--bake", "9-3", blend=src)
    assert code == 1 and "is empty" in log, log
    unwritable = os.path.join(TMP, "no_such_folder", "out.blend")
    code, log = batch("extract", "-o", unwritable, blend=src)
    assert code == 1 and f"myoskin batch: error: cannot save {unwritable}" in log and "Traceback" not in log, log
    code, log = batch("extract", "--pc2", os.path.join(TMP, "no_such_folder", "x.pc2"), "--bake", "1-2",
                      "--bind", blend=src)
    assert code == 1 and "myoskin batch: error:" in log and "Traceback" not in log, log


runner.run()
