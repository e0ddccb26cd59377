# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: bone roles in the add-on (issue 13, items 3 and 4) — Extract works whatever the bone names,
role overrides stored on the armature (Detect / Reset, the Bone Roles panel, save + reload, renamed bones),
and Extract says why when nothing could be analysed.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_roles.py
"""
import json
import os
import sys
import tempfile

import bpy

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, operator_error  # noqa: E402
from fake_layout import draw_panel  # noqa: E402  (UILayout stand-in)

TMP = tempfile.mkdtemp(prefix="myoskin_test_roles_")


def add_arm(seed=1):
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=seed) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    return skin.parent, skin


def regions(state):
    return sorted(m.region for m in state.muscles)


def panel_text(panel):
    return " ".join(t for k, t in draw_panel(panel).log if k == "label")


def test_default_bone_names_get_the_same_muscles():
    """Every bone renamed to Blender's defaults (Bone, Bone.001, ...): the roles come from the bone tree, and
    Extract finds the muscles it finds with the anatomical names."""
    arm, skin = add_arm()
    direct, _ = core().extract_muscles(core().make_synthetic_arm(seed=1)[0])
    original = [b.name for b in arm.data.bones]
    for i, bone in enumerate(list(arm.data.bones)):
        bone.name = "Bone" if i == 0 else f"Bone.{i:03d}"
    renamed = dict(zip(original, (b.name for b in arm.data.bones)))
    assert [g.name for g in skin.vertex_groups] == list(renamed.values())  # Blender renames the groups too
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    state = arm.myoskin
    assert len(state.muscles) == len(direct) >= 4, (len(state.muscles), len(direct))
    assert regions(state) == sorted(renamed[m.region] for m in direct), (regions(state), [m.region for m in direct])
    # Extract recorded the detected roles: the panel lists the limb chain with a role per bone
    # (the tree alone tells the clavicle and the hand from the upper arm and forearm: the same roles as the names)
    named = core().bone_roles(core().make_synthetic_arm(seed=1)[0])
    assert named == {"clavicle": "shoulder", "upper_arm": "limb", "forearm": "limb", "hand": "ignore"}, named
    assert [(i.name, i.detected, i.role) for i in state.bone_roles] == [(renamed[b], named[b], named[b]) for b in original]
    log = draw_panel(bpy.types.MYOSKIN_PT_bone_roles).log
    labels = " ".join(t for k, t in log if k == "label")
    assert "Limb: Bone.001 .. Bone.002" in labels and "0 override(s)" in labels, labels
    assert log.count(("prop", "role")) == 3, log  # the shoulder and the two limb bones; the hand is under Ignored
    assert ("operator", "myoskin.detect_bone_roles") in log and ("operator", "myoskin.reset_bone_roles") in log


def test_override_ignore_removes_muscles_and_survives_reload():
    arm, skin = add_arm()
    state = arm.myoskin
    assert bpy.ops.myoskin.detect_bone_roles() == {'FINISHED'}
    roles = {i.name: i.role for i in state.bone_roles}
    assert roles["upper_arm"] == "limb" and roles["forearm"] == "limb", roles
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    before = regions(state)
    assert "upper_arm" in before and "forearm" in before, before
    state.bone_roles["upper_arm"].role = 'ignore'
    assert module("state").role_overrides(arm) == {"upper_arm": "ignore"}
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    after = regions(state)
    # no muscle on the ignored bone (its planes are gone); the forearm's are the same
    assert "upper_arm" not in after and after.count("forearm") == before.count("forearm") > 0, (before, after)
    assert "1 override(s)" in panel_text(bpy.types.MYOSKIN_PT_bone_roles)
    # stored in the .blend: save, reload, the override is there and Extract uses it
    path, arm_name = os.path.join(TMP, "override.blend"), arm.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    arm = bpy.data.objects[arm_name]
    state = arm.myoskin
    assert module("state").role_overrides(arm) == {"upper_arm": "ignore"}
    assert state.bone_roles["upper_arm"].detected == "limb"
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    assert regions(state) == after
    # a renamed bone: a clear error naming it, then Detect drops the stale override and Extract works
    arm.data.bones["upper_arm"].name = "humerus"
    text = operator_error(bpy.ops.myoskin.extract_muscles)
    assert "'upper_arm'" in text and "renamed or deleted" in text, text
    assert "upper_arm" in panel_text(bpy.types.MYOSKIN_PT_bone_roles)  # the panel says it too
    assert regions(state) == after  # nothing changed
    assert bpy.ops.myoskin.detect_bone_roles() == {'FINISHED'}
    assert module("state").role_overrides(arm) == {}
    assert state.bone_roles["humerus"].role == "limb"
    # Reset clears overrides
    state.bone_roles["forearm"].role = 'ignore'
    assert bpy.ops.myoskin.reset_bone_roles() == {'FINISHED'}
    assert module("state").role_overrides(arm) == {} and state.bone_roles["forearm"].role == "limb"


def test_all_bones_ignored_says_why_and_changes_nothing():
    arm, skin = add_arm()
    state = arm.myoskin
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    muscles = [m.name for m in state.muscles]
    assert muscles
    text_before = state.muscles_text.as_string()
    objects_before = sorted(o.name for o in bpy.data.objects)
    detected_before = [(i.name, i.detected) for i in state.bone_roles]
    assert len(detected_before) == len(arm.data.bones)
    active = sum(1 for i in state.bone_roles if i.detected != 'ignore')
    assert active >= 2, detected_before
    for item in state.bone_roles:
        item.role = 'ignore'
    text = operator_error(bpy.ops.myoskin.extract_muscles)
    assert "Nothing could be analysed: no limb chain recognised" in text, text
    assert "Reset" in text, text  # the user's overrides did it: say how to undo them
    assert [m.name for m in state.muscles] == muscles
    assert state.muscles_text.as_string() == text_before
    assert sorted(o.name for o in bpy.data.objects) == objects_before
    assert [(i.name, i.detected) for i in state.bone_roles] == detected_before
    assert all(i.role == 'ignore' for i in state.bone_roles)
    # the panel draws with no chain and lists the ignored bones
    log = draw_panel(bpy.types.MYOSKIN_PT_bone_roles).log
    assert ("label", f"0 chain(s), {active} override(s)") in log, log
    assert ("prop", "show_ignored") in log and ("template_list", "MYOSKIN_UL_bone_roles") not in log
    bpy.context.scene.myoskin_ui.show_ignored = True
    assert ("template_list", "MYOSKIN_UL_bone_roles") in draw_panel(bpy.types.MYOSKIN_PT_bone_roles).log


def test_smooth_arm_warns_no_significant_relief():
    """Sections analysed but nothing stands out: a WARNING naming the cause (not an error: the extraction ran)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, muscle_scale=0.0) == {'FINISHED'}
    arm = bpy.context.view_layer.objects.active.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    done = module("operators.muscles").last_extraction[arm.name]
    assert done["analysed"] and done["muscles"] == len(arm.myoskin.muscles) == 0, done
    assert done["diagnosis"].startswith("no significant relief"), done
    assert done["message"].startswith("Found no muscles on SyntheticArm: no significant relief"), done


def test_left_out_parts_are_named_per_mesh():
    """A rigid prop bound to one bone (a helmet-like cube in its own mesh) is left out of the analysis, and
    the INFO message names the mesh it came from through the weld map."""
    arm, skin = add_arm()
    bpy.ops.mesh.primitive_cube_add(size=0.02, location=(0.0, 0.0, 0.0))
    prop = bpy.context.active_object
    prop.name = "Prop"
    prop.parent = arm
    prop.modifiers.new("Armature", 'ARMATURE').object = arm
    group = prop.vertex_groups.new(name="hand")
    group.add(list(range(len(prop.data.vertices))), 1.0, 'REPLACE')
    bpy.context.view_layer.objects.active = arm
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    done = module("operators.muscles").last_extraction[arm.name]
    assert len(done["left_out"]) == 1, done
    assert "part of 'Prop'" in done["left_out"][0] and "'hand'" in done["left_out"][0], done
    assert "left out " + done["left_out"][0] in done["message"], done
    assert len(arm.myoskin.muscles) >= 4


runner.run()
