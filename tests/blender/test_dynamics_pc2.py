# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: Bake PC2 with secondary motion (issue 16 parts 1, 5, 6, 7).

Asserts: two batch.py chunk processes stitched by state files give the bytes of one bake (jiggle; jiggle + skin
solve + temporal filter), and a state too late for a chunk is refused with the reason; the painted jiggle map acts
per vertex (0: the plain skin, 1: the full jiggle, to 1e-6 of the size); sculpt deltas captured from a shape key
give the sculpt at their frame (1e-6 of the size) and turn with the forearm on a frame bent 100 degrees; the
Dynamics panel draws the rig's and the active muscle's jiggle settings, the map, skin solve, filter, sculpt and
the bakes, and the Bake panel no longer does.
"""
import json
import os
import subprocess
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, operator_error  # noqa: E402
from test_dynamics import STOP, animated_arm, joint_heads  # noqa: E402  (the synthetic arm, elbow flexing then held)

TMP = tempfile.mkdtemp(prefix="myoskin_test_dynamics_pc2_")
BATCH = os.path.join(runner.SOURCE_DIR, "addon", "myoskin", "batch.py")


def pc2_frames(path):
    return np.asarray(module("core_loader").core().read_pc2(path)["frames"])


def batch(*args, blend):
    """batch.py in a fresh Blender on `blend`; returns its log (asserting it exited 0)."""
    cmd = runner.blender_command(blend, "--python-exit-code", "1", "-P", BATCH, "--", *args)
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=dict(os.environ))
    log = done.stdout + done.stderr
    assert done.returncode == 0, log
    return log


def test_farm_chunks_with_state_files_stitch_to_one_bake():
    arm, skin = animated_arm()
    skin_name, arm_name = skin.name, arm.name
    blend, chunk_blend = os.path.join(TMP, "farm.blend"), os.path.join(TMP, "farm_chunk2.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    for extra in ((), ("--skin-solve", "--filter")):
        name = "solve" if extra else "jiggle"
        whole = os.path.join(TMP, f"{name}_whole.pc2")
        solve = bool(extra)
        assert bpy.ops.myoskin.bake_pc2(filepath=whole, frame_start=1, frame_end=20, jiggle=True, skin_solve=solve,
                                        temporal_filter=solve) == {'FINISHED'}
        parts = [os.path.join(TMP, f"{name}_{k}.pc2") for k in (1, 2)]
        state = os.path.join(TMP, f"{name}_state.json")
        batch("--bake", "1-10", "--jiggle", "--pc2", parts[0], "--state-out", state, *extra, blend=blend)
        with open(state, encoding="utf-8") as f:
            saved = json.load(f)
        assert saved["frame"] == 9 and saved["start_frame"] == 1 and "jiggle" in saved, saved
        # the second chunk reads and rewrites one state file (as a farm's chain does); its jiggled Action is saved
        tail = ("-o", chunk_blend) if not extra else ()
        log = batch("--bake", "11-20", "--jiggle", "--pc2", parts[1], "--state-in", state, "--state-out", state,
                    *extra, *tail, blend=blend)
        assert "wrote" in log, log
        with open(state, encoding="utf-8") as f:
            assert json.load(f)["frame"] == 19
        one, first, second = pc2_frames(whole), pc2_frames(parts[0]), pc2_frames(parts[1])
        assert one.shape[0] == 20 and first.shape[0] == 10 and second.shape[0] == 10
        assert one.dtype == np.float32 and first.dtype == np.float32
        stitched = np.concatenate([first, second])
        assert stitched.tobytes() == one.tobytes(), f"{name}: the chunks differ from one bake by " \
            f"{np.abs(stitched - one).max():.3g}"
        assert np.abs(one[14] - one[0]).max() > 0.01 * runner.size_of(bpy.data.objects[skin_name])
        print(f"farm ({name}): 2 chunk processes (1-10, 11-20 from the state of frame 9) = one bake, bit for bit")
    # A chunk whose state is too late for it is refused with the reason.
    late = os.path.join(TMP, "late_state.json")
    assert bpy.ops.myoskin.bake_pc2(filepath=os.path.join(TMP, "late.pc2"), frame_start=1, frame_end=20, jiggle=True,
                                    state_out=late) == {'FINISHED'}
    msg = operator_error(bpy.ops.myoskin.bake_pc2, filepath=os.path.join(TMP, "bad.pc2"), frame_start=13,
                         frame_end=24, jiggle=True, state_in=late)
    assert "needs the state of frame 11 or earlier" in msg, msg
    # The jiggled Action of the second chunk (its own state file beside the PC2's) keys what one bake keys.
    assert os.path.isfile(os.path.join(TMP, "jiggle_state.action.json"))
    arm = bpy.data.objects[arm_name]
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    whole = joint_heads(arm, range(11, 21))
    bpy.ops.wm.open_mainfile(filepath=chunk_blend)
    chunk = joint_heads(bpy.data.objects[arm_name], range(11, 21))
    assert np.abs(whole - chunk).max() == 0.0, "the chunk's Action must key what one bake keys"
    print("farm: the second chunk's jiggled Action keys (from the state file) = one bake's, bit for bit")


def test_painted_jiggle_map_acts_per_vertex_on_the_pc2():
    arm, skin = animated_arm()
    size = runner.size_of(skin)
    paths = {k: os.path.join(TMP, f"map_{k}.pc2") for k in ("plain", "full", "painted")}
    assert bpy.ops.myoskin.bake_pc2(filepath=paths["plain"], frame_start=1, frame_end=20) == {'FINISHED'}
    assert bpy.ops.myoskin.bake_pc2(filepath=paths["full"], frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.add_jiggle_map() == {'FINISHED'}
    group = skin.vertex_groups[module("dynamics").JIGGLE_GROUP]
    count = len(skin.data.vertices)
    zero = np.arange(count) % 2 == 0
    group.add([int(v) for v in np.flatnonzero(zero)], 0.0, 'REPLACE')  # painted 0 on every other vertex
    assert bpy.ops.myoskin.bake_pc2(filepath=paths["painted"], frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    plain, full, painted = (pc2_frames(paths[k]) for k in ("plain", "full", "painted"))
    jiggle = np.linalg.norm(full - plain, axis=2)
    assert jiggle[:, ~zero].max() > 1e-4 * size, "the jiggle must move the skin"
    off_zero = float(np.abs(painted[:, zero] - plain[:, zero]).max()) / size
    off_one = float(np.abs(painted[:, ~zero] - full[:, ~zero]).max()) / size
    print(f"jiggle map: jiggle up to {jiggle.max() / size:.2e} of the size; painted 0 off the plain skin by "
          f"{off_zero:.1e}, painted 1 off the full jiggle by {off_one:.1e}")
    assert off_zero <= 1e-6 and off_one <= 1e-6


def forearm_frame(arm, skin):
    """(rotation of the forearm bone at the current frame from rest; the forearm's axis; its hinge axis (the
    bone's local X, which the animation turns about)), mesh space."""
    to_arm = module("blender_io").mesh_to_armature_matrix(skin, arm)
    bone = arm.pose.bones["forearm"]
    rest = np.array(bone.bone.matrix_local)
    turn = (np.array(bone.matrix) @ np.linalg.inv(rest))[:3, :3]
    m = np.linalg.inv(to_arm[:3, :3])
    axis, hinge = m @ rest[:3, 1], m @ rest[:3, 0]
    return m @ turn @ to_arm[:3, :3], axis / np.linalg.norm(axis), hinge / np.linalg.norm(hinge)


def test_sculpt_deltas_give_the_sculpt_and_turn_with_the_surface():
    arm, skin = animated_arm()
    size = runner.size_of(skin)
    bio = module("blender_io")
    rest = bio.mesh_vertices(skin.data)
    bpy.context.scene.frame_set(1)
    _turn, axis, hinge = forearm_frame(arm, skin)
    head = np.array(skin.matrix_world.inverted() @ (arm.matrix_world @ arm.pose.bones["forearm"].bone.head_local))
    length = arm.pose.bones["forearm"].bone.length
    t = (rest - head) @ axis / length
    region = (t > 0.75) & (t < 0.95)  # near the wrist, far from the elbow
    assert region.sum() > 10
    direction = np.cross(hinge, axis)  # across the elbow's hinge: turns with it
    direction /= np.linalg.norm(direction)
    offset = np.zeros_like(rest)
    offset[region] = 0.01 * size * direction
    skin.shape_key_add(name="Basis")
    key = skin.shape_key_add(name="detail")
    key.data.foreach_set("co", (rest + offset).astype(np.float32).ravel())
    bpy.context.view_layer.objects.active = skin
    bpy.context.scene.myoskin_ui.frame_start, bpy.context.scene.myoskin_ui.frame_end = 1, STOP
    assert bpy.ops.myoskin.capture_sculpt(source_key="detail") == {'FINISHED'}
    assert skin.data.shape_keys.key_blocks["detail"].value == 0.0
    info = module("dynamics").sculpt_info(skin)
    assert info["frame"] == 1 and info["vertices"] == len(rest)
    path, bare = os.path.join(TMP, "sculpt.pc2"), os.path.join(TMP, "bare.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=STOP) == {'FINISHED'}
    sculpted = pc2_frames(path)
    err = float(np.abs(sculpted[0] - (rest + offset)).max()) / size
    print(f"sculpt deltas: at the sculpt frame the PC2 is {err:.1e} of the size off the sculpt")
    assert err <= 1e-6
    assert bpy.ops.myoskin.remove_sculpt() == {'FINISHED'}
    assert module("dynamics").sculpt_info(skin) is None
    assert bpy.ops.myoskin.bake_pc2(filepath=bare, frame_start=1, frame_end=STOP) == {'FINISHED'}
    plain = pc2_frames(bare)
    bpy.context.scene.frame_set(STOP)
    turn = forearm_frame(arm, skin)[0]
    want = offset[region] @ turn.T  # the detail turned with the forearm
    got = (sculpted[-1] - plain[-1])[region]
    off = float(np.linalg.norm(got - want, axis=1).max()) / (0.01 * size)
    unturned = float(np.linalg.norm(offset[region] - want, axis=1).min()) / (0.01 * size)
    print(f"sculpt deltas: on the frame bent 100 deg the detail is {off:.3f} of its size off the turned detail "
          f"(unturned it would be {unturned:.2f} off)")
    assert unturned > 1.0
    assert off < 0.05


def test_dynamics_panel_draws_settings_and_bakes():
    arm, skin = animated_arm()
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from fake_layout import draw_panel
    bpy.context.view_layer.objects.active = skin
    arm.myoskin.jiggle = True
    log = draw_panel(bpy.types.MYOSKIN_PT_dynamics).log
    for entry in (("prop", "jiggle"), ("prop", "jiggle_frequency"), ("prop", "jiggle_damping"),
                  ("prop", "jiggle_amount"), ("prop", "skin_solve"), ("prop", "temporal_filter"),
                  ("operator", "myoskin.add_jiggle_map"), ("operator", "myoskin.capture_sculpt"),
                  ("operator", "myoskin.bake_action"), ("operator", "myoskin.bake_pc2")):
        assert entry in log, (entry, log)
    text = " ".join(t for k, t in log if k == "label")
    assert arm.myoskin.muscles[arm.myoskin.active_index].name in text and "batch.py" in text, text
    assert bpy.ops.myoskin.add_jiggle_map() == {'FINISHED'}
    log = draw_panel(bpy.types.MYOSKIN_PT_dynamics).log
    assert ("operator", "myoskin.add_jiggle_map") not in log
    assert any(k == "label" and "myoskin_jiggle" in t for k, t in log), log
    bake = draw_panel(bpy.types.MYOSKIN_PT_bake).log
    assert ("prop", "jiggle") not in bake and ("prop", "skin_solve") not in bake, bake


if __name__ == "__main__":
    runner.run(globals())
