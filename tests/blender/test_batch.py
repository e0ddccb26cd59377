# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: the batch entry point addon/myoskin/batch.py, run as users run it (its own Blender process):
.blend in and .glb in, extract + bind + bake + PC2 + glTF, out.blend that plays the baked state; clear errors.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_batch.py
"""
import os
import re
import subprocess
import sys
import tempfile

import addon_utils
import bpy
import numpy as np

SOURCE = os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(SOURCE, "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module  # noqa: E402

BATCH = os.path.join(SOURCE, "addon", "myoskin", "batch.py")
MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
SOLDIER = "characters/quaternius_woman_soldier/woman_soldier.glb"  # 4 skinned meshes, armature scale 100
TMP = tempfile.mkdtemp(prefix="myoskin_test_batch_")


def batch(*args, blend=None):
    """Run the batch script in a fresh Blender; returns (exit code, stdout + stderr)."""
    cmd = runner.blender_command(*([blend] if blend else []), "--python-exit-code", "1", "-P", BATCH, "--", *args)
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=dict(os.environ))
    return done.returncode, done.stdout + done.stderr


def arm_blend(path):
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
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


def test_batch_volume_blend_on_by_default_and_off_on_request():
    """--bind writes the volume blend (the share group and the second Armature modifier) unless --volume-blend off;
    the muscle joints slide unless --joints-slide off (the setting and the bind record's rig)."""
    src = os.path.join(TMP, "arm_vb.blend")
    skin_name, arm_name = arm_blend(src)
    for flag, expected in ((None, True), ("off", False)):
        out = os.path.join(TMP, f"vb_{flag}.blend")
        code, log = batch("extract", "--bind", *(["--volume-blend", flag, "--joints-slide", flag] if flag else []),
                          "-o", out, blend=src)
        assert code == 0, log
        bpy.ops.wm.open_mainfile(filepath=out)
        skin, arm = bpy.data.objects[skin_name], bpy.data.objects[arm_name]
        binding = module("binding")
        assert (binding.volume_blend_modifier(skin, arm) is not None) == expected, flag
        assert (binding.VOLUME_BLEND_GROUP in skin.vertex_groups) == expected, flag
        assert binding.armature_modifier(skin, arm).use_deform_preserve_volume != expected, flag
        assert arm.myoskin.joints_slide == binding.read_bind_record(arm)["joints_slide"] == expected, flag
        assert module("live").live_rig(arm).rig.joints_slide == expected, flag


def cli_command():
    """The myoskin CLI of this build, or Skip naming what is missing."""
    exe = os.path.join(os.environ.get("MYOSKIN_BUILD_DIR", os.path.join(SOURCE, "build")), "bin", "myoskin")
    if not os.path.isfile(exe):
        runner.skip(f"needs the CLI {exe} (set MYOSKIN_BUILD_DIR to a build with bin/myoskin)")
    return exe


def cli_and_batch_muscles(relative, bind):
    """batch.py (extract, and --bind when `bind`) and `myoskin extract` on the same .glb: (armature, the add-on's
    muscles by name with their points taken from the armature's space to the scene and from Blender's Z-up to
    glTF's Y-up, the CLI's muscles by name, the CLI's limb radius)."""
    import json
    import re
    path = runner.shared_file(relative)
    stem = os.path.splitext(os.path.basename(path))[0]
    out, cli_json = os.path.join(TMP, stem + ".blend"), os.path.join(TMP, stem + ".muscles.json")
    code, log = batch("--input", path, "extract", *(["--bind"] if bind else []), "-o", out)
    assert code == 0, log
    done = subprocess.run([cli_command(), "extract", path, "-o", cli_json], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    radius = float(re.search(r"limb radius ([0-9.eE+-]+)", done.stdout).group(1))
    bpy.ops.wm.open_mainfile(filepath=out)
    arms = [o for o in bpy.data.objects if o.type == 'ARMATURE']
    assert len(arms) == 1, [o.name for o in arms]
    arm = arms[0]
    to_world = np.array(arm.matrix_world)

    def gltf_space(points):  # armature space -> the scene -> glTF axes (x, z, -y)
        w = np.asarray(points, dtype=np.float64) @ to_world[:3, :3].T + to_world[:3, 3]
        return np.stack([w[:, 0], w[:, 2], -w[:, 1]], axis=1)

    ours = {}
    for item in arm.myoskin.muscles:
        m = json.loads(item.data)["muscles"][0]
        ours[item.name] = {"centers": gltf_space([s["center"] for s in m["sections"]]),
                           "root_curve": gltf_space(m["root_curve"])}
    with open(cli_json) as f:
        theirs = {m["name"]: {"centers": np.array([s["center"] for s in m["sections"]], dtype=np.float64),
                              "root_curve": np.array(m["root_curve"], dtype=np.float64)}
                  for m in json.load(f)["muscles"]}
    return arm, ours, theirs, radius


def assert_same_muscles(label, ours, theirs, radius, tolerance=0.01, same_places=False):
    """The same muscle names, and per muscle as many sections and root-curve points. Positions (issue 13 asks 1 %
    of the limb radius): the muscles more than `tolerance` apart are printed, and with `same_places` asserted."""
    assert len(ours) == len(theirs), f"{label}: add-on {len(ours)} muscles, CLI {len(theirs)}"
    assert set(ours) == set(theirs), (f"{label}: only in the add-on {sorted(set(ours) - set(theirs))}, "
                                      f"only in the CLI {sorted(set(theirs) - set(ours))}")
    worst, over = {}, {}
    for name in sorted(theirs):
        for key in ("centers", "root_curve"):
            a, b = ours[name][key], theirs[name][key]
            assert a.shape == b.shape, f"{label} {name}: {key} {a.shape} in the add-on, {b.shape} in the CLI"
            error = float(np.linalg.norm(a - b, axis=1).max()) if len(a) else 0.0
            worst[key] = max(worst.get(key, 0.0), error)
            if error > tolerance * radius:
                over[f"{name} {key}"] = round(error / radius, 4)
    print(f"  {label}: add-on and CLI {len(ours)} muscles each; sections within {worst.get('centers', 0):.2e}, "
          f"root curves within {worst.get('root_curve', 0):.2e} (limb radius {radius:.4g}); more than "
          f"{tolerance:.0%} of it apart: {over}")
    assert not (same_places and over), f"{label}: more than {tolerance:.0%} of the limb radius apart: {over}"


def test_batch_glb_input_and_the_cli_give_the_same_muscles():
    """batch.py on the .glb and `myoskin extract` on the same file: the same muscles (names, count), every
    section centre and root-curve point in the same place (the add-on's armature space taken to the scene, then
    from Blender's Z-up to glTF's Y-up) within 1 % of the limb radius (issue 13). Extraction takes bone tails from
    the joints (tailsFromJoints), so how Blender's importer or the CLI's loader guessed tails does not matter for
    which muscles are found. The pectorals were 3.4-7.2 % of the limb radius apart until a clipped (shoulder)
    profile's base support faded over a margin of its tolerance (the importer's float32 re-posing, a 8e-6 scale
    along the height, put one vertex across the tolerance and sent one section's base refits another way)."""
    arm, ours, theirs, radius = cli_and_batch_muscles(MUSCULAR, bind=True)
    assert arm.myoskin.bound and len(arm.myoskin.muscles) >= 12  # the core tiers' floor on this body (measured 20)
    limbs = [n for n in theirs if not n.startswith("spine")]
    assert len(limbs) >= 10, f"the CLI found only {limbs} on the limbs and shoulders"
    assert_same_muscles("makehuman_muscular_male", ours, theirs, radius, same_places=True)


def test_batch_and_the_cli_agree_on_other_characters():
    """As above (extract only) on makehuman_neutral, the Godot base mesh and woman_soldier (four meshes,
    armature x100, whose bones Blender's importer makes 100 times too long): every section and root-curve point
    within 1 % of the limb radius. The neutral body's calves end on the ankle itself, equally near the shin and the
    foot; Blender's importer left the shin's tail 1.2e-7 m off the foot's head, which gave the end to the shin and
    carried it over the ankle, 0.57 limb radii from the CLI's, until tails within round-off of their joint were set
    to it (tailsFromJoints)."""
    for relative in ("characters/makehuman_neutral/makehuman_neutral.glb",
                     "characters/godot_male_base_mesh_lowpoly/male_base_mesh.glb", SOLDIER):
        _arm, ours, theirs, radius = cli_and_batch_muscles(relative, bind=False)
        assert theirs, f"{relative}: the CLI found no muscles"
        assert_same_muscles(os.path.basename(relative), ours, theirs, radius, same_places=True)


def test_batch_character_in_four_meshes():
    """woman_soldier.glb: four skinned meshes (Body, Feet, Head, Legs) on an armature scaled x100. Batch
    extracts from all of them as one surface, binds and bakes every mesh; at rest each mesh is unchanged."""
    path = runner.shared_file(SOLDIER)
    out, pc2 = os.path.join(TMP, "soldier.blend"), os.path.join(TMP, "soldier.pc2")
    code, log = batch("--input", path, "extract", "--bind", "--bake", "1-3", "--pc2", pc2, "-o", out)
    assert code == 0, log
    assert "4 mesh(es)" in log, log
    bpy.ops.wm.open_mainfile(filepath=out)
    arm = [o for o in bpy.data.objects if o.type == 'ARMATURE'][0]
    state = arm.myoskin
    meshes = [s.object for s in state.skins]
    assert len(meshes) == 4 and state.bound and len(state.muscles) >= 1, (meshes, len(state.muscles))
    import json
    record = json.loads(state.bind_text.as_string())
    assert record["skins"] == [m.name for m in meshes]
    joints = set(record["joint_names"])
    muscled = {m.name: sum(1 for v in m.data.vertices for g in v.groups
                           if m.vertex_groups[g.group].name in joints and g.weight > 0.0) for m in meshes}
    assert sum(muscled.values()) > 0, muscled
    for m in meshes:
        assert "myoskin_original_weights" in m and any(g.name in joints for g in m.vertex_groups), m.name
        assert os.path.isfile(module("operators.rig").pc2_paths(pc2, meshes)[meshes.index(m)]), m.name
    # at rest, with live update evaluating the muscle joints from the skeleton, every mesh is unchanged
    if arm.animation_data is not None:
        arm.animation_data.action = None
    for pb in arm.pose.bones:
        pb.location, pb.scale = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
        pb.rotation_quaternion, pb.rotation_euler = (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    state.live = True
    module("live").update_armature(arm, force=True)
    bpy.context.view_layer.update()
    io = module("blender_io")

    def world(m, points):
        mw = np.array(m.matrix_world)
        return points @ mw[:3, :3].T + mw[:3, 3]

    # (the character's size, all meshes in world space: the tolerance is 1e-6 of it; with Preserve Volume,
    # Blender's float32 dual quaternions move a piece by ~5 float32 ulps of its coordinates)
    size = float(np.ptp(np.concatenate([world(m, io.mesh_vertices(m.data)) for m in meshes]), axis=0).max())
    for m in meshes:
        rest = world(m, io.mesh_vertices(m.data))
        err = float(np.abs(world(m, io.evaluated_vertices(m)) - rest).max())
        assert err < 1e-6 * size, f"{m.name}: rest pose moved by {err:.3g} (character size {size:.3g}) after bind"
    print(f"  woman_soldier: {len(state.muscles)} muscles, vertices with muscle weights per mesh {muscled}")
    # the log names the skin parts left out of the analysis (the head's eyes, hair, helmet) by their mesh
    left_out = [line for line in log.splitlines() if "] left out " in line]
    assert left_out and all("'Soldier_Head'" in line for line in left_out), log
    assert any("rigid part" in line and "(bound to 'Head')" in line for line in left_out), left_out
    # --object picks one mesh
    code, log = batch("--input", path, "--object", meshes[0].name, "extract")
    assert code == 0 and f"(1 mesh(es): {meshes[0].name})" in log, log


def test_batch_roles():
    """--roles ROLES.json (the CLI's format) sets the bone role overrides: upper_arm ignored gives no muscle
    there and the override is saved; every bone ignored: exit 1 naming why nothing could be analysed; a role
    file naming a bone that is not there or an unknown role: exit 1, clear message."""
    import json
    src, out = os.path.join(TMP, "roles_arm.blend"), os.path.join(TMP, "roles_out.blend")
    arm_blend(src)
    roles = os.path.join(TMP, "roles.json")
    with open(roles, "w") as f:
        json.dump({"upper_arm": "ignore"}, f)
    code, log = batch("extract", "--roles", roles, "-o", out, blend=src)
    assert code == 0 and "bone roles: 1 override(s)" in log, log
    bpy.ops.wm.open_mainfile(filepath=out)
    arm = [o for o in bpy.data.objects if o.type == 'ARMATURE'][0]
    found = [m.region for m in arm.myoskin.muscles]
    assert "forearm" in found and "upper_arm" not in found, found
    assert module("state").role_overrides(arm) == {"upper_arm": "ignore"}
    with open(roles, "w") as f:
        json.dump({b: "ignore" for b in ("clavicle", "upper_arm", "forearm", "hand")}, f)
    code, log = batch("extract", "--roles", roles, "-o", out + "2", blend=src)
    assert code == 1 and "myoskin batch: error: nothing could be analysed: no limb chain recognised" in log, log
    assert "Traceback" not in log and not os.path.exists(out + "2"), log
    with open(roles, "w") as f:
        json.dump({"humerus": "limb", "forearm": "arm"}, f)
    code, log = batch("extract", "--roles", roles, blend=src)
    assert code == 1 and "has no bone 'humerus'" in log and "Traceback" not in log, log


def test_batch_extraction_options():
    """The user-facing flags and the expert tuning (--options FILE.json, then --expert KEY=VALUE) reach extraction;
    a bad key or value: exit 1, clear message."""
    import json
    src = os.path.join(TMP, "options_arm.blend")
    arm_blend(src)
    code, log = batch("extract", "--max-per-region", "1", "--expert", "filters.minEvidence=1000", "--expert",
                      "filters.spindleEnds=0", blend=src)
    assert code == 0 and "found no muscles" in log, log
    options = os.path.join(TMP, "expert.json")
    with open(options, "w") as f:
        json.dump({"filters.minEvidence": 1000, "filters.spindleEnds": 0}, f)
    code, log = batch("extract", "--options", options, "--expert", "filters.minEvidence=6.6", blend=src)
    assert code == 0 and "found no muscles" not in log and "extracted " in log, log
    # A reference limb radius half the arm's: the body is analysed at twice the size the defaults are stated for, and
    # the log says so (the operator's message too: a WARNING).
    code, log = batch("extract", "--expert", "scale.referenceLimbRadius=0.02", blend=src)
    assert code == 0 and re.search(r"note: limb radius .* times the 0\.02 m .*scale\.continuous", log), log
    assert re.search(r"^Warning: Extracted \d+ muscles .*; note: limb radius", log, re.M), log  # the operator
    code, log = batch("extract", "--expert", "scale.referenceLimbRadius=0.02", "--expert", "scale.continuous=1",
                      blend=src)
    assert code == 0 and "note:" not in log and "found no muscles" not in log, log
    assert int(re.search(r"extracted (\d+) muscles", log).group(1)) > 0, log
    for bad, message in ((["--expert", "nope=1"], "unknown expert extraction option 'nope'"),
                         (["--expert", "filters.minEvidence"], "--expert needs KEY=VALUE"),
                         (["--joint-wrap", "-1"], "--joint-wrap and --max-per-region must be >= 0")):
        code, log = batch("extract", *bad, blend=src)
        assert code == 1 and message in log and "Traceback" not in log, (bad, log)


def test_batch_errors():
    code, log = batch("--input", os.path.join(TMP, "missing.glb"), "extract")
    assert code == 1 and "myoskin batch: error: no such file" in log, log
    code, log = batch("extract")  # empty scene: no skinned mesh
    assert code == 1 and "0 skinned meshes" in log, log
    two = os.path.join(TMP, "two.blend")  # two characters: say which
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.myoskin.add_synthetic_arm(seed=1, **runner.LIGHT_ARM) == {'FINISHED'}
    assert bpy.ops.myoskin.add_synthetic_arm(seed=2, **runner.LIGHT_ARM) == {'FINISHED'}
    bpy.ops.wm.save_as_mainfile(filepath=two)
    code, log = batch("extract", "-o", os.path.join(TMP, "two_out.blend"), blend=two)
    assert code == 1 and "2 armatures deform meshes" in log and "pick one with --object" in log, log
    assert not os.path.exists(os.path.join(TMP, "two_out.blend"))
    src = os.path.join(TMP, "arm2.blend")
    arm_blend(src)
    code, log = batch("--bake", "1-5", blend=src)  # nothing extracted
    assert code == 1 and "run Extract Muscles first" in log, log
    code, log = batch("extract", "--bind", "--bake", "9-3", blend=src)
    assert code == 1 and "is empty" in log, log
    code, log = batch("extract", "--joints-slide", "off", blend=src)  # a bind setting without --bind
    assert code == 1 and "--joints-slide needs --bind" in log, log
    code, log = batch("extract", "--bind", "--deformer", "anchored", "--joints-slide", "off", blend=src)
    assert code == 1 and "--joints-slide is for the muscle joints deformer" in log, log
    unwritable = os.path.join(TMP, "no_such_folder", "out.blend")
    code, log = batch("extract", "-o", unwritable, blend=src)
    assert code == 1 and f"myoskin batch: error: cannot save {unwritable}" in log and "Traceback" not in log, log
    code, log = batch("extract", "--pc2", os.path.join(TMP, "no_such_folder", "x.pc2"), "--bake", "1-2",
                      "--bind", blend=src)
    assert code == 1 and "myoskin batch: error:" in log and "Traceback" not in log, log


runner.run()
