# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: jiggle baked into the muscle joints' Action (issue 16 parts 1, 6, 7).

Asserts: a bake with jiggle keys joints that differ from the plain bake after the elbow stops dead, by an
amount that decays; the baked keys equal the core's JiggleTrack; a farm chunk (keyed over its own range,
simulated from the first frame) gives the same keys as one bake; a muscle's own frequency changes only the
result; bad ranges are refused with a message.
PC2 with dynamics, farms, sculpt deltas and the Dynamics panel: test_dynamics_pc2.py.
"""
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, operator_error  # noqa: E402

STOP, END = 8, 40


def animated_arm():
    """The synthetic arm, extracted, bound, its elbow flexing 0 -> 100 degrees over frames 1-8 and then held."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert len(arm.myoskin.muscles) > 0
    assert bpy.ops.myoskin.bind() == {'FINISHED'}
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    for frame, deg in ((1, 0.0), (STOP, 100.0), (END, 100.0)):
        pb.rotation_euler = (np.radians(deg), 0.0, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    bpy.context.scene.render.fps = 24
    return arm, skin


def joint_heads(arm, frames):
    """#F by #J by 3 posed heads of the muscle joints, as the baked Action plays them (live update off)."""
    names = module("binding").read_bind_record(arm)["joint_names"]
    assert len(names) > 0
    out = []
    for f in frames:
        bpy.context.scene.frame_set(f)
        out.append([tuple(arm.pose.bones[n].head) for n in names])
    return np.array(out)


def test_jiggle_bake_oscillates_after_the_stop_and_decays():
    arm, _skin = animated_arm()
    frames = list(range(1, END + 1))
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=END) == {'FINISHED'}
    plain = joint_heads(arm, frames)
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=END, jiggle=True) == {'FINISHED'}
    assert not arm.myoskin.live
    jiggled = joint_heads(arm, frames)
    diff = np.linalg.norm(jiggled - plain, axis=2).max(axis=1)  # per frame, the largest joint offset
    size = float(np.abs(plain).max())
    early, late = diff[STOP:STOP + 8].max(), diff[-8:].max()
    print(f"jiggle: largest joint offset after the stop {early:.2e} m, last 8 frames {late:.2e} m")
    assert diff[0] <= 1e-6 * size, "at the first frame the spring is at rest"
    assert early > 1e-4 * size, "the muscles must swing on after the elbow stops"
    assert late < 0.5 * early, "the swing must decay with the damping"


def test_jiggle_keys_equal_the_core_track():
    arm, _skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    rig_op = module("operators.rig")
    rig = module("live").live_rig(arm)
    arm.myoskin.live = True  # sample the poses with live update (the keys muted), as the bake did
    track, _poses = rig_op.jiggle_track(bpy.context, arm, rig, 1, 20)
    arm.myoskin.live = False
    bpy.context.scene.frame_set(12)
    want = np.asarray(track.joint_matrices(12))[:, :3, 3]
    got = np.array([tuple(arm.pose.bones[n].matrix.translation) for n in rig.joint_names])
    assert np.abs(got - want).max() <= 1e-5 * max(1.0, float(np.abs(want).max()))


def test_farm_chunk_equals_one_bake():
    arm, _skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=END, jiggle=True) == {'FINISHED'}
    whole = joint_heads(arm, range(21, END + 1))
    arm, _skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=21, frame_end=END, jiggle=True, jiggle_start=1) == {'FINISHED'}
    chunk = joint_heads(arm, range(21, END + 1))
    assert np.abs(whole - chunk).max() == 0.0, "a chunk simulated from the same start must key the same values"


def test_muscle_frequency_override_changes_the_swing():
    arm, _skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24, jiggle=True) == {'FINISHED'}
    default = joint_heads(arm, range(1, 25))
    for item in arm.myoskin.muscles:
        item.jiggle_frequency = 1.5
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24, jiggle=True) == {'FINISHED'}
    slow = joint_heads(arm, range(1, 25))
    assert np.abs(slow - default).max() > 1e-5


def test_pc2_with_skin_solve_is_the_core_solve_and_rest_is_exact():
    arm, skin = animated_arm()
    tmp = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"myoskin_dyn_{os.getpid()}")
    os.makedirs(tmp, exist_ok=True)
    plain_path, solved_path = os.path.join(tmp, "plain.pc2"), os.path.join(tmp, "solved.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=plain_path, frame_start=1, frame_end=STOP) == {'FINISHED'}
    assert bpy.ops.myoskin.bake_pc2(filepath=solved_path, frame_start=1, frame_end=STOP, skin_solve=True) == {'FINISHED'}
    core = module("core_loader").core()
    plain, solved = core.read_pc2(plain_path)["frames"], core.read_pc2(solved_path)["frames"]
    rest = module("blender_io").mesh_vertices(skin.data)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    assert np.abs(solved[0] - rest).max() <= 1e-6 * size, "at rest the solve returns the skin"
    moved = np.abs(solved[-1] - plain[-1]).max()
    print(f"skin solve at 100 deg: moves the skin up to {moved / size:.2e} of the size from the plain skin")
    assert 0.0 < moved < 0.1 * size
    # The same frame solved by the core directly (the bake's inputs: the mesh's combined weights).
    live, rig_io = module("live"), module("rig_io")
    rig = live.live_rig(arm)
    joints, weights = rig_io.read_combined_weights(skin, rig.bone_names + rig.joint_names)
    solver = core.SkinSolver(module("blender_io").character_from_blender(skin, arm), rig.rig,
                             core.default_goal_weights(joints, weights, len(rig.bone_names)))
    bpy.context.scene.frame_set(STOP)
    pose = live.evaluated_pose(arm, rig, bpy.context.evaluated_depsgraph_get())
    goal = np.asarray(plain[-1], dtype=np.float64)  # the skinned frame (mesh space = armature space here)
    want = np.asarray(solver.solve(goal, rig.rig, pose))
    assert np.abs(want - solved[-1]).max() <= 1e-5 * size


def test_pc2_with_jiggle_plays_what_the_jiggled_action_plays():
    arm, skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"myoskin_jiggle_{os.getpid()}.pc2")
    assert bpy.ops.myoskin.bake_pc2(filepath=path, frame_start=1, frame_end=20, jiggle=True) == {'FINISHED'}
    frames = module("core_loader").core().read_pc2(path)["frames"]
    assert frames.shape[0] == 20
    rest = module("blender_io").mesh_vertices(skin.data)
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    for frame in (5, 12, 19):
        bpy.context.scene.frame_set(frame)
        bpy.context.view_layer.update()
        err = np.abs(module("blender_io").evaluated_vertices(skin) - frames[frame - 1]).max()
        assert err <= 1e-5 * size, f"frame {frame}: the PC2 is {err / size:.2e} of the size off the baked Action"


def test_painted_group_scales_the_jiggle():
    arm, skin = animated_arm()
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24) == {'FINISHED'}
    plain = joint_heads(arm, range(1, 25))
    group = skin.vertex_groups.new(name=module("operators.rig").JIGGLE_GROUP)
    group.add(list(range(len(skin.data.vertices))), 0.0, 'REPLACE')  # painted 0 everywhere: no jiggle
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24, jiggle=True) == {'FINISHED'}
    assert np.abs(joint_heads(arm, range(1, 25)) - plain).max() <= 1e-6
    group.add(list(range(len(skin.data.vertices))), 1.0, 'REPLACE')  # 1 everywhere: the default jiggle
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24, jiggle=True) == {'FINISHED'}
    painted = joint_heads(arm, range(1, 25))
    skin.vertex_groups.remove(group)
    assert bpy.ops.myoskin.bake_action(frame_start=1, frame_end=24, jiggle=True) == {'FINISHED'}
    default = joint_heads(arm, range(1, 25))
    assert np.abs(painted - plain).max() > 1e-5
    assert np.abs(painted - default).max() <= 1e-6


def test_bad_ranges_are_refused():
    animated_arm()
    msg = operator_error(bpy.ops.myoskin.bake_action, frame_start=10, frame_end=20, jiggle=True, jiggle_start=15)
    assert "Simulation Start" in msg, msg
    msg = operator_error(bpy.ops.myoskin.bake_action, frame_start=20, frame_end=10, jiggle=True)
    assert "empty" in msg, msg


if __name__ == "__main__":
    runner.run(globals())
