"""The per-frame skin solve from Python (_core.SkinSolver): rest pose exact, a bent frame pushes the skin out of the
muscles and slides it (no vertex deeper in a muscle than at rest), the pose argument equals evaluating the rig first,
and bad input raises ValueError."""
import numpy as np
import pytest


@pytest.fixture(scope="module")
def setup(core):
    character, _truth = core.make_synthetic_arm(seed=1)
    muscles, _report = core.extract_muscles(character)
    assert len(muscles) > 0
    rig = core.MuscleRig(character, muscles)
    joints, weights = core.hybrid_weights(character, rig)
    nb = character.num_bones
    skinner = core.Skinner(character.vertices, joints, weights, nb + rig.num_joints)
    lbs = core.Skinner(character.vertices, character.weight_joints, character.weight_values, nb)
    goal_weights = core.default_goal_weights(joints, weights, nb)
    solver = core.SkinSolver(character, rig, goal_weights)
    size = float(np.linalg.norm(np.ptp(np.asarray(character.vertices), axis=0)))
    return dict(c=character, rig=rig, skinner=skinner, lbs=lbs, solver=solver, size=size, nb=nb,
                goal_weights=goal_weights)


def bend(core, character, degrees, bone="forearm", axis=(1, 0, 0)):
    names = list(character.bone_names)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    half = np.radians(degrees) / 2
    q[names.index(bone)] = [np.cos(half), *(np.sin(half) * np.asarray(axis, dtype=float))]
    return core.pose_from_rotations(character, q)


def test_goal_weights_are_low_over_the_muscles_and_one_elsewhere(core, setup):
    g = np.asarray(setup["goal_weights"])
    assert g.shape == (len(setup["c"].vertices),)
    # slide 0.95 from a muscle share of 0.25: skin over a belly gets 0.05, skin the bones alone move 1
    assert abs(g.min() - 0.05) < 1e-12 and g.max() == 1.0
    assert (g < 0.5).sum() > 100, "no skin lies over a muscle"
    g2 = core.default_goal_weights(*core.hybrid_weights(setup["c"], setup["rig"]), setup["nb"], slide=0.5)
    assert abs(g2.min() - 0.5) < 1e-12
    report = setup["solver"].report
    assert report["regions"] >= 1 and report["sliding_vertices"] == int((g < 1).sum())
    assert report["mean_edge_length"] > 0


def test_rest_pose_is_exact_and_a_bent_frame_keeps_the_skin_out_of_the_muscles(core, setup):
    c, rig, solver, size = setup["c"], setup["rig"], setup["solver"], setup["size"]
    rest = core.rest_pose(c)
    t = core.skinning_transforms(c, rest, rig, rig.evaluate(rest)["joint_matrices"])
    out = solver.solve(setup["skinner"].deform(t), rig, rest)
    assert out.shape == (len(c.vertices), 3)
    assert np.abs(out - c.vertices).max() <= 1e-6 * size
    pose = bend(core, c, 110)
    goal = setup["lbs"].deform(core.skeleton_transforms(c, pose))  # plain LBS: the muscles poke out of it
    out = solver.solve(goal, rig, pose)
    allowed = np.asarray(solver.rest_depth) + 1e-6 * size
    depth_goal = -np.minimum(solver.signed_distance(goal), 0)
    depth_out = -np.minimum(solver.signed_distance(out), 0)
    assert (depth_goal > allowed).sum() > 0, "the goal never entered a muscle: nothing to test"
    assert (depth_out > allowed).sum() == 0
    moved = np.linalg.norm(out - goal, axis=1)
    assert moved.max() > 1e-3 * size
    # Without a pose the rig's last evaluation is used: the same frame gives the same skin.
    again = solver.solve(goal, rig)
    assert np.array_equal(again, out)


def test_bad_input_raises_value_error(core, setup):
    c, rig, solver = setup["c"], setup["rig"], setup["solver"]
    g = np.asarray(setup["goal_weights"])
    with pytest.raises(ValueError, match="goal weights"):
        core.SkinSolver(c, rig, g[:10])
    bad = g.copy()
    bad[3] = 2.0
    with pytest.raises(ValueError, match="goal weight of vertex 3"):
        core.SkinSolver(c, rig, bad)
    with pytest.raises(ValueError, match="iterations"):
        core.SkinSolver(c, rig, g, iterations=-1)
    goal = np.array(c.vertices, dtype=float)
    goal[5, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        solver.solve(goal, rig, core.rest_pose(c))
    with pytest.raises(ValueError):
        solver.solve(goal[:, :2], rig)
    pose = np.array(core.rest_pose(c))
    pose[1, 0, 3] = np.nan
    with pytest.raises(ValueError):
        solver.solve(np.asarray(c.vertices), rig, pose)
    with pytest.raises(ValueError):
        core.default_goal_weights(np.zeros((3, 2), np.int32), np.ones((3, 2)), 1, slide=1.5)
