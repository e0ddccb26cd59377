"""Secondary motion from Python and the CLI: `myoskin simulate` (jiggle, filter, sculpt, chunks stitched by
state files), _core.simulate, JiggleTrack, temporal_filter and SculptDeltas, and their bad input."""
import json

import numpy as np
import pytest

from conftest import run_cli

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


def test_cli_bad_input(core, arm_files):
    d = arm_files
    for extra, message in [(["--skin-solve"], "not available in this build"),
                           (["--jiggle", "--frames", "5-2"], "comes before"),
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


def test_python_simulate_equals_the_cli_and_sculpt(core, arm_files):
    d = arm_files
    character = core.load_character(str(d / "arm.obj"))
    rig = core.MuscleRig(character, core.read_muscles(str(d / "muscles.json")))
    joints, weights = core.hybrid_weights(character, rig)
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
