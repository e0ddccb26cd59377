"""Anchored skin (issue 17) through the module and the CLI: Newton closest points, constant volume, rest pose exact,
relaxation monotone and a no-op at rest, PC2 baking, bad input as ValueError / one-line CLI errors."""
import json

import numpy as np
import pytest

from conftest import MUSCULAR, run_cli, shared


@pytest.fixture(scope="module")
def arm(core):
    character, _truth = core.make_synthetic_arm(seed=1)
    muscles, _report = core.extract_muscles(character)
    assert len(muscles) > 0
    return character, muscles


def elbow_pose(core, character, degrees):
    names = list(character.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    t = np.radians(degrees) / 2
    q[names.index("forearm")] = [np.cos(t), np.sin(t), 0.0, 0.0]
    return core.pose_from_rotations(character, q)


def test_closest_point_matches_a_dense_search(core):
    rng = np.random.default_rng(3)
    radii = np.array([1.0, 0.05, 0.4])  # 1:20
    th, ph = np.meshgrid(np.linspace(0, np.pi, 721), np.linspace(0, 2 * np.pi, 1441), indexing="ij")
    surface = np.stack([radii[0] * np.sin(th) * np.cos(ph), radii[1] * np.sin(th) * np.sin(ph),
                        radii[2] * np.cos(th)], -1).reshape(-1, 3)
    points = [np.zeros(3), np.array([0.5, 0, 0]), np.array([0, 0, 0.1])] + list(rng.uniform(-1.5, 1.5, (12, 3)) * radii)
    for p in points:
        point, distance, iterations = core.closest_point_on_ellipsoid(radii, p)
        assert iterations <= 20
        assert abs(((np.asarray(point) / radii) ** 2).sum() - 1) < 1e-12
        dense = np.linalg.norm(surface - p, axis=1).min()
        assert distance <= dense + 1e-12            # never worse than any sampled point
        assert dense - distance < 3e-3 * radii.max()  # and the grid's spacing close to it
    with pytest.raises(ValueError, match="radius"):
        core.closest_point_on_ellipsoid([1.0, 0.0, 1.0], [2.0, 0.0, 0.0])


def test_rest_exact_bent_finite_relaxation_monotone(core, arm):
    character, muscles = arm
    skin = core.AnchoredSkin(character, muscles)
    kinds = [c["kind"] for c in skin.components]
    assert kinds.count("muscle_ellipsoid") == len(muscles)
    assert "bone_capsule" in kinds and "joint_sphere" in kinds
    rest = np.asarray(character.vertices)
    size = skin.report["scale"]
    out, energy = skin.evaluate(core.rest_pose(character), trace=True)
    assert np.abs(out - rest).max() <= 1e-6 * size
    bent, energy = skin.evaluate(elbow_pose(core, character, 100), trace=True)
    assert np.isfinite(bent).all()
    assert len(energy) >= 2 and all(b <= a for a, b in zip(energy, energy[1:])) and energy[-1] < energy[0]
    into = np.zeros_like(rest)
    skin.evaluate_into(elbow_pose(core, character, 100), into)
    assert np.array_equal(into, bent)
    assert len(skin.vertex_component) == len(rest)


def test_muscle_volume_constant_and_pc2(core, arm, tmp_path):
    character, muscles = arm
    skin = core.AnchoredSkin(character, muscles, relax_iterations=0)
    rest_parts = skin.posed_components(core.rest_pose(character))
    muscles_rest = [c for c in rest_parts if c["kind"] == "muscle_ellipsoid"]
    assert muscles_rest
    for degrees in (30, 90, 130):
        posed = [c for c in skin.posed_components(elbow_pose(core, character, degrees)) if c["kind"] == "muscle_ellipsoid"]
        assert len(posed) == len(muscles_rest)
        for a, b in zip(muscles_rest, posed):
            assert np.prod(b["radii"]) == pytest.approx(np.prod(a["radii"]), rel=1e-9)
    poses = np.stack([elbow_pose(core, character, d) for d in (0, 45, 90)])
    path = str(tmp_path / "anchored.pc2")
    skin.write_pc2(path, poses, start_frame=1)
    frames = np.asarray(core.read_pc2(path)["frames"])
    assert frames.shape == (3, len(character.vertices), 3)
    assert np.abs(frames[2] - skin.evaluate(poses[2])).max() < 1e-5 * skin.report["scale"]


def test_bad_input(core, arm):
    character, muscles = arm
    skin = core.AnchoredSkin(character, muscles)
    pose = core.rest_pose(character).copy()
    pose[1, 0, 3] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        skin.evaluate(pose)
    with pytest.raises(ValueError, match="not a bone"):
        core.AnchoredSkin(character, muscles, stuffing=[{"kind": "stuffing", "bone": "wing", "radii": [1, 1, 1]}])
    with pytest.raises(ValueError, match="radius"):
        core.AnchoredSkin(character, muscles, stuffing=[{"kind": "stuffing", "bone": "forearm", "radii": [0, 1, 1]}])
    with pytest.raises(ValueError, match="same point|different"):
        core.AnchoredSkin(character, [], stuffing=[{"kind": "muscle_ellipsoid", "origin_bone": "upper_arm",
                                                    "origin": [0.1, 0, 0], "insertion_bone": "forearm",
                                                    "insertion": [0.1, 0, 0], "radius_x": 0.02, "radius_z": 0.02}])
    # An authored stuffing far outside the skin: nothing anchors to it, the output stays finite.
    far = core.AnchoredSkin(character, muscles, stuffing=[{"kind": "stuffing", "bone": "forearm",
                                                           "center": [0, 50, 0], "radii": [0.1, 0.1, 0.1]}])
    assert far.report["vertices_per_component"][-1] == 0
    assert np.isfinite(far.evaluate(elbow_pose(core, character, 120))).all()


def test_cli_method_anchored(core, tmp_path):
    r = run_cli("generate", "arm", "-o", str(tmp_path), "--seed", "1")
    assert r.returncode == 0, r.stderr
    arm = str(tmp_path / "arm.obj")
    muscles = tmp_path / "m.json"
    r = run_cli("extract", arm, "-o", str(muscles), "--no-surfaces")
    assert r.returncode == 0, r.stderr
    pose = tmp_path / "pose.json"
    json.dump({"frames": [{"bones": {}}, {"bones": {"forearm": {"rotation_axis_angle": [90, 1, 0, 0]}}}]}, open(pose, "w"))
    out = tmp_path / "anchored.pc2"
    r = run_cli("deform", arm, "--muscles", str(muscles), "--pose", str(pose), "-o", str(out), "--method", "anchored")
    assert r.returncode == 0, r.stderr
    assert "anchored to" in r.stdout, r.stdout
    frames = np.asarray(core.read_pc2(str(out))["frames"])
    assert frames.shape[0] == 2 and np.isfinite(frames).all()
    r = run_cli("deform", arm, "--pose", str(pose), "-o", str(out), "--method", "blend")
    assert r.returncode == 1 and "--method must be eq3 or anchored" in r.stderr, r.stderr
    r = run_cli("deform", arm, "--pose", str(pose), "-o", str(out), "--method", "anchored", "--preserve-volume")
    assert r.returncode == 1 and "not an option of --method anchored" in r.stderr, r.stderr


def test_makehuman_rest_exact(core):
    character = core.load_character(shared(MUSCULAR), require_weights=True)
    muscles, _ = core.extract_muscles(character)
    skin = core.AnchoredSkin(character, muscles)
    out = skin.evaluate(core.rest_pose(character))
    assert np.abs(out - np.asarray(character.vertices)).max() <= 1e-6 * skin.report["scale"]
