"""Muscle joints move continuously as a joint bends: each measured joint swept 0-150 degrees in 0.5-degree steps with
0, 7 and 23 degrees of twist (benchmarks/skin_quality.joint_jumps). A jump is a muscle joint moving over 0.05 limb
radii and 8 times its median step: a joint wrap switching its way round. The two ways round blend by how clearly the
muscle's side names one (paths::jointWrapWays), so a muscle beside a joint or one whose side turns across the bend no
longer jumps between them. Before that blend: makehuman_neutral 21 jumps (up to 1.0 limb radii), the soldier 26 (1.8),
generated biped 26 12 (1.4), makehuman_muscular_male 48 (1.1)."""
import os
import sys

import pytest

from conftest import MUSCULAR, NEUTRAL, shared

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))
import skin_quality  # noqa: E402

SOLDIER = "characters/quaternius_woman_soldier/woman_soldier.glb"

# Sweeps of the core's figures (held-out bodies): the second Python tier leaves them out (conftest.py).
pytestmark = pytest.mark.figures


def jumps(core, character, joints, facing):
    muscles, report = core.extract_muscles(character)
    rig = core.MuscleRig(character, muscles)
    names = list(character.bone_names)
    swept = [bone for _label, bone, *_rest in joints if bone in names]
    # joint_jumps skips a table row whose bone the character lacks: at least one joint that a wrapped muscle spans
    wrapped = [m.name for m in muscles if m.wrap_type == "joint" and m.wrap_bone in swept]
    assert swept and wrapped, "no swept joint has a muscle wrapping it: nothing to measure"
    found = skin_quality.joint_jumps(core, character, rig, joints, report["limb_radius"], facing=facing)
    for label, twist, degrees, joint, move in found:
        print(f"{label} twist {twist}: {joint} jumps {move:.3f} limb radii at {degrees} degrees")
    return found


@pytest.mark.parametrize("relative", [NEUTRAL, SOLDIER])
def test_held_out_characters_muscle_joints_do_not_jump(core, relative):
    character = core.load_character(shared(relative), require_weights=True)
    joints = skin_quality.MAKEHUMAN_JOINTS if relative == NEUTRAL else skin_quality.QUATERNIUS_JOINTS
    assert jumps(core, character, joints, (0.0, 0.0, 1.0)) == []


def test_held_out_generated_biped_muscle_joints_do_not_jump(core):
    character, _truth = core.make_synthetic_body(seed=26)
    assert jumps(core, character, skin_quality.SYNTHETIC_BODY_JOINTS, (0.0, -1.0, 0.0)) == []


def test_makehuman_muscle_joints_move_at_most_a_third_of_a_limb_radius_in_a_step(core):
    """What remains on makehuman_muscular_male: where the plane of a wrap turns at a nearly straight or fully folded
    joint (its outer shin muscle at 74 degrees of plantar flexion, the elbow at 148-150 degrees), up to 0.29 limb
    radii in one step."""
    character = core.load_character(shared(MUSCULAR), require_weights=True)
    found = jumps(core, character, skin_quality.MAKEHUMAN_JOINTS, (0.0, 0.0, 1.0))
    assert max((move for *_rest, move in found), default=0.0) < 0.35
