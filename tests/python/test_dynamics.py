"""Secondary motion from Python and the CLI: `myoskin simulate` (jiggle, filter, sculpt, chunks stitched by
state files), _core.simulate, JiggleTrack, temporal_filter and SculptDeltas, and their bad input."""
import json
import os
import sys

import numpy as np
import pytest

from conftest import run_cli

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import skin_quality  # noqa: E402

SWING = [0, 12, 24, 36, 48, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60, 60]


@pytest.fixture(scope="module")
def arm_files(tmp_path_factory):
    """The generated arm, its extracted muscles and a swing of the upper arm that stops dead (24 frames)."""
    d = tmp_path_factory.mktemp("dynamics")
    assert run_cli("generate", "arm", "-o", str(d)).returncode == 0
    r = run_cli("extract", str(d / "arm.obj"), "-o", str(d / "muscles.json"))
    assert r.returncode == 0, r.stderr
    seq = {"start_frame": 1, "frames": [{"bones": {"upper_arm": {"rotation_axis_angle": [a, 0, 0, 1]}}}
                                        for a in SWING]}
    (d / "seq.json").write_text(json.dumps(seq))
    return d


def simulate(d, out, *extra):
    r = run_cli("simulate", str(d / "arm.obj"), "--muscles", str(d / "muscles.json"), "--pose", str(d / "seq.json"),
                "-o", str(out), *extra)
    assert r.returncode == 0, r.stderr
    return r


def swing_poses(core, character):
    names = list(character.bone_names)
    poses = []
    for a in SWING:
        q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
        half = np.radians(a) / 2
        q[names.index("upper_arm")] = [np.cos(half), 0, 0, np.sin(half)]
        poses.append(core.pose_from_rotations(character, q))
    return np.array(poses)


def test_cli_chunks_stitch_to_the_single_bake(core, arm_files):
    d = arm_files
    simulate(d, d / "all.pc2", "--jiggle", "--filter")
    full = core.read_pc2(str(d / "all.pc2"))["frames"]
    assert full.shape[0] == len(SWING)
    simulate(d, d / "a.pc2", "--jiggle", "--filter", "--frames", "1-9", "--state-out", str(d / "s9.json"))
    simulate(d, d / "b.pc2", "--jiggle", "--filter", "--frames", "10-17", "--state-in", str(d / "s9.json"),
             "--state-out", str(d / "s17.json"))
    simulate(d, d / "c.pc2", "--jiggle", "--filter", "--frames", "18-24", "--state-in", str(d / "s17.json"))
    parts = [core.read_pc2(str(d / n)) for n in ("a.pc2", "b.pc2", "c.pc2")]
    assert [p["start_frame"] for p in parts] == [1.0, 10.0, 18.0]
    stitched = np.concatenate([p["frames"] for p in parts])
    assert stitched.shape == full.shape and np.array_equal(stitched, full)
    # The jiggle moves the skin after the stop, and it settles.
    simulate(d, d / "plain.pc2")
    plain = core.read_pc2(str(d / "plain.pc2"))["frames"]
    assert np.array_equal(plain[0], full[0])  # the first frame starts at rest relative to the bones
    moved = np.abs(full - plain).max(axis=(1, 2))
    assert moved[6:10].max() > 1e-3 and moved[-1] < moved[6:10].max()


def test_cli_chunks_refuse_a_state_baked_with_other_settings(core, arm_files):
    """A state file keeps the bind's and the simulation's settings: a chunk baked otherwise (joints slide, dominance,
    skinning mode, jiggle amount) is refused by the setting's name; the same settings stitch bit for bit; a state
    written before settings were kept is taken as before."""
    d = arm_files
    simulate(d, d / "k1.pc2", "--jiggle", "--joints-slide", "off", "--frames", "1-9", "--state-out", str(d / "k9.json"))
    state = json.loads((d / "k9.json").read_text())
    assert state["settings"]["bind.joints_slide"] == "off" and state["settings"]["bind.skinning"] == "linear"
    tail = ["--jiggle", "--frames", "10-24", "--state-in", str(d / "k9.json")]
    for extra, message in [([], "with bind.joints_slide off, this run has on"),
                           (["--joints-slide", "off", "--dominance", "0.7"], "with bind.dominance"),
                           (["--joints-slide", "off", "--preserve-volume"],
                            "with bind.skinning linear, this run has preserve volume, pivot scale"),
                           (["--joints-slide", "off", "--jiggle-amount", "0.5"], "with simulation.jiggle")]:
        r = run_cli("simulate", str(d / "arm.obj"), "--muscles", str(d / "muscles.json"), "--pose", str(d / "seq.json"),
                    "-o", str(d / "k_bad.pc2"), *tail, *extra)
        assert r.returncode == 1 and message in r.stderr and r.stderr.count("\n") == 1, (extra, r.stderr)
    simulate(d, d / "k2.pc2", *tail, "--joints-slide", "off")
    simulate(d, d / "k_all.pc2", "--jiggle", "--joints-slide", "off")
    stitched = np.concatenate([core.read_pc2(str(d / n))["frames"] for n in ("k1.pc2", "k2.pc2")])
    assert np.array_equal(stitched, core.read_pc2(str(d / "k_all.pc2"))["frames"])
    del state["settings"]
    (d / "k9_old.json").write_text(json.dumps(state))
    simulate(d, d / "k_old.pc2", "--jiggle", "--frames", "10-24", "--state-in", str(d / "k9_old.json"))


def test_cli_bad_input(core, arm_files):
    d = arm_files
    for extra, message in [(["--jiggle", "--frames", "5-2"], "comes before"),
                           (["--frames", "1-99"], "outside the sequence"),
                           (["--jiggle", "--fps", "0"], "--fps must be > 0"),
                           (["--jigle"], "unknown option '--jigle'"),
                           (["--jiggle", "--jiggle-damping", "-1"], "dampingRatio must be >= 0"),
                           (["--jiggle", "--frames", "12-13", "--state-in", str(d / "seq.json")], "simulation_state")]:
        r = run_cli("simulate", str(d / "arm.obj"), "--muscles", str(d / "muscles.json"), "--pose",
                    str(d / "seq.json"), "-o", str(d / "bad.pc2"), *extra)
        assert r.returncode == 1 and message in r.stderr and r.stderr.count("\n") == 1, (extra, r.stderr)
    r = run_cli("simulate", str(d / "arm.obj"), "--pose", str(d / "seq.json"), "-o", str(d / "x.pc2"), "--jiggle")
    assert r.returncode == 1 and "--jiggle needs --muscles" in r.stderr
    r = run_cli("simulate", str(d / "arm.obj"), "--pose", str(d / "seq.json"), "-o", str(d / "x.pc2"), "--skin-solve")
    assert r.returncode == 1 and "--skin-solve needs --muscles" in r.stderr


def test_skin_solve_in_the_simulation_cli_and_python(core, arm_files):
    """simulate --skin-solve: rest frames stay the skin, bent frames are solved (skin outside the posed muscles
    where it was outside at rest), chunks still stitch, and Python's simulate(skin_solve=...) gives the same."""
    d = arm_files
    simulate(d, d / "solved.pc2", "--jiggle", "--skin-solve")
    simulate(d, d / "jiggled.pc2", "--jiggle")
    solved = core.read_pc2(str(d / "solved.pc2"))["frames"]
    jiggled = core.read_pc2(str(d / "jiggled.pc2"))["frames"]
    character = core.load_character(str(d / "arm.obj"))
    size = np.ptp(character.vertices, axis=0).max()
    assert np.abs(solved[0] - character.vertices).max() <= 1e-6 * size, "the rest frame is the skin"
    moved = np.abs(solved - jiggled).max(axis=(1, 2))
    assert moved[6:].max() > 1e-5 * size, "the solve must act on the swung arm"
    assert moved.max() < 0.05 * size
    simulate(d, d / "s_a.pc2", "--jiggle", "--skin-solve", "--frames", "1-12", "--state-out", str(d / "ss12.json"))
    simulate(d, d / "s_b.pc2", "--jiggle", "--skin-solve", "--frames", "13-24", "--state-in", str(d / "ss12.json"))
    stitched = np.concatenate([core.read_pc2(str(d / n))["frames"] for n in ("s_a.pc2", "s_b.pc2")])
    assert np.array_equal(stitched, solved)
    rig, joints, weights = skin_quality.bound_rig(core, character, core.read_muscles(str(d / "muscles.json")))
    skinner = core.Skinner(character.vertices, joints, weights, character.num_bones + len(rig.joint_names))
    goal_weights = core.default_goal_weights(joints, weights, character.num_bones)
    frames = core.simulate(character, skinner, swing_poses(core, character), rig, 24.0, 1, jiggle=True,
                           skin_solve=goal_weights)
    assert frames.shape == solved.shape and np.abs(frames - solved).max() < 1e-6 * size


def test_python_simulate_equals_the_cli_and_sculpt(core, arm_files):
    d = arm_files
    character = core.load_character(str(d / "arm.obj"))
    rig, joints, weights = skin_quality.bound_rig(core, character, core.read_muscles(str(d / "muscles.json")))
    skinner = core.Skinner(character.vertices, joints, weights, character.num_bones + len(rig.joint_names))
    poses = swing_poses(core, character)
    frames = core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, filter=True)
    simulate(d, d / "py.pc2", "--jiggle", "--filter")
    cli = core.read_pc2(str(d / "py.pc2"))["frames"]
    size = np.ptp(character.vertices, axis=0).max()
    assert frames.shape == cli.shape and np.abs(frames - cli).max() < 1e-6 * size
    # Sculpt: frame 8 gives the sculpt, later frames carry the detail.
    sculpt = np.array(frames[7], dtype=np.float64)
    sculpt[:, 2] += 0.003 * np.exp(-((sculpt[:, 1] - sculpt[:, 1].mean()) / 0.05) ** 2)
    out = core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, filter=True, sculpt=sculpt,
                        sculpt_frame=8)
    assert np.abs(out[7] - sculpt).max() < 1e-6 * size
    assert np.abs(out[20] - frames[20]).max() > 1e-3
    # A chunk with its state from Python too.
    state = d / "py_state.json"
    core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, filter=True, frames=(1, 11), state_out=str(state))
    tail = core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, filter=True, frames=(12, 24),
                         state_in=str(state))
    assert np.array_equal(tail, frames[11:])


def test_jiggle_track_filter_and_sculpt_deltas(core, arm_files):
    d = arm_files
    character = core.load_character(str(d / "arm.obj"))
    rig = core.MuscleRig(character, core.read_muscles(str(d / "muscles.json")))
    poses = swing_poses(core, character)
    track = core.JiggleTrack(character, rig, poses, 24.0)
    nm = len(rig.muscle_names) if hasattr(rig, "muscle_names") else track.params.shape[0]
    assert track.params.shape == (nm, 3) and nm > 0 and len(track.influence) == len(rig.joint_names)
    assert np.array_equal(track.offsets(1), np.zeros((nm, 3)))
    rest = rig.evaluate(poses[0], with_surfaces=False)["joint_matrices"]
    assert np.array_equal(track.joint_matrices(1), rest)
    moved = track.joint_matrices(8) - rig.evaluate(poses[7], with_surfaces=False)["joint_matrices"]
    assert np.abs(moved[:, :3, 3]).max() > 1e-4 and np.abs(moved[:, :3, :3]).max() < 1e-12
    with pytest.raises(ValueError, match="mass must be > 0"):
        core.JiggleTrack(character, rig, poses, 24.0, params=np.tile([0.0, 1.0, 0.1], (nm, 1)))
    with pytest.raises(ValueError, match="stiffness must be > 0"):
        core.JiggleTrack(character, rig, poses, 24.0, params=np.tile([1.0, -1.0, 0.1], (nm, 1)))
    bad = poses.copy()
    bad[3, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        core.JiggleTrack(character, rig, bad, 24.0)
    # Filter: a spike on one frame shrinks by 90 % or more; the rest of the cache is untouched.
    edge = core.mean_edge_length(character.vertices, character.triangles)
    cache = np.repeat(np.asarray(character.vertices, dtype=np.float32)[None], 5, axis=0)
    cache[2, 100] += np.float32(10 * edge)
    filtered, pulled = core.temporal_filter(cache, edge)
    assert pulled == 1 and np.linalg.norm(filtered[2, 100] - character.vertices[100]) < 0.1 * 10 * edge
    assert np.array_equal(np.delete(filtered, 100, axis=1), np.delete(cache, 100, axis=1))
    # Sculpt deltas turn with the surface.
    v = np.asarray(character.vertices)
    sculpt = v + 0.002 * np.sin(v * 40)
    deltas = core.SculptDeltas(v, character.triangles, sculpt)
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert np.abs(deltas.apply(v @ rot.T) - sculpt @ rot.T).max() < 1e-6 * np.ptp(v, axis=0).max()
    with pytest.raises(ValueError, match="vertices"):
        core.SculptDeltas(v, character.triangles, sculpt[:10])


def test_simulate_vertex_influence_shape_offsets_stored_sculpt_and_track_states(core, arm_files, tmp_path):
    """The add-on's PC2 inputs: a per-vertex jiggle map (0: plain skinning, 1: the full jiggle), per-frame shape
    offsets (= skinning the offset mesh), sculpt deltas from stored local deltas (= the sculpt at its frame), and a
    JiggleTrack chunk continued from a state file (= one track)."""
    d = arm_files
    character = core.load_character(str(d / "arm.obj"))
    rig = core.MuscleRig(character, core.read_muscles(str(d / "muscles.json")))
    joints, weights = core.hybrid_weights(character, rig)
    count = character.num_bones + len(rig.joint_names)
    skinner = core.Skinner(character.vertices, joints, weights, count)
    poses = swing_poses(core, character)
    v = np.asarray(character.vertices)
    size = np.ptp(v, axis=0).max()
    plain = core.simulate(character, skinner, poses, rig, 24.0, 1)
    full = core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True)
    zero = np.arange(len(v)) % 3 == 0
    w = np.where(zero, 0.0, 1.0)
    mixed = core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, jiggle_vertex_influence=w)
    assert np.abs(full - plain)[:, ~zero].max() > 1e-4 * size
    assert np.array_equal(mixed[:, zero], plain[:, zero])
    assert np.abs(mixed[:, ~zero] - full[:, ~zero]).max() <= 1e-6 * size
    with pytest.raises(ValueError, match="outside 0..1"):
        core.simulate(character, skinner, poses, rig, 24.0, 1, jiggle=True, jiggle_vertex_influence=w * 2)
    # Shape offsets on frame 10: skinning the offset mesh.
    offset = (0.01 * size * np.sin(v * 30)).astype(np.float32)
    offsets = np.zeros((len(poses), len(v), 3), dtype=np.float32)
    offsets[9] = offset
    keyed = core.simulate(character, skinner, poses, rig, 24.0, 1, shape_offsets=offsets)
    again = core.Skinner(v + offset, joints, weights, count)
    want = core.simulate(character, again, poses, rig, 24.0, 1)
    assert np.abs(keyed[9] - want[9]).max() <= 1e-6 * size and np.abs(keyed[9] - plain[9]).max() > 1e-3 * size
    assert np.array_equal(keyed[10], plain[10])
    with pytest.raises(ValueError, match="shape_offsets"):
        core.simulate(character, skinner, poses, rig, 24.0, 1, shape_offsets=offsets[:5])
    # Stored sculpt deltas (local deltas + frame flags) give the sculpt at their frame.
    sculpt = np.array(plain[7], dtype=np.float64) + 0.002 * size * np.sin(np.array(plain[7]) * 40)
    captured = core.SculptDeltas(np.array(plain[7], dtype=np.float64), character.triangles, sculpt)
    stored = core.SculptDeltas.from_local(character.triangles, captured.local_deltas, captured.framed)
    assert captured.framed.dtype == bool and captured.framed.all()
    flags = np.arange(len(v)) % 3 == 0  # mixed flags read back as stored
    assert np.array_equal(core.SculptDeltas.from_local(character.triangles, captured.local_deltas, flags).framed, flags)
    out = core.simulate(character, skinner, poses, rig, 24.0, 1, sculpt_deltas=stored)
    assert np.abs(out[7] - sculpt).max() <= 1e-6 * size
    with pytest.raises(ValueError, match="framed"):
        core.SculptDeltas.from_local(character.triangles, captured.local_deltas, captured.framed[:3])
    # A JiggleTrack chunk from a state file: the frames after it equal one track's.
    one = core.JiggleTrack(character, rig, poses, 24.0)
    state = tmp_path / "track.json"
    one.write_state(str(state), 11)
    assert json.loads(state.read_text())["frame"] == 11
    chunk = core.JiggleTrack(character, rig, poses, 24.0)
    assert chunk.restore_state(str(state)) == 11
    for frame in (12, 17, 24):
        assert np.array_equal(chunk.joint_matrices(frame), one.joint_matrices(frame))
    other = core.JiggleTrack(character, rig, poses, 30.0)
    with pytest.raises(ValueError, match="fps"):
        other.restore_state(str(state))
