# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender tier: muscles in the .blend — Extract, the muscle list, Add from a region, locators, wrap
settings, save/reload, and clear errors on bad input.

    BLENDER_USER_SCRIPTS=build/blender_scripts MYOSKIN_SOURCE_DIR=$PWD \
    blender -b --factory-startup --python-exit-code 1 --addons myoskin --python tests/blender/test_muscles.py
"""
import json
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.environ.get("MYOSKIN_SOURCE_DIR", os.path.join(os.path.dirname(
    os.path.abspath(__file__)), "..", "..")), "tests", "blender"))
import blender_test_runner as runner  # noqa: E402
from blender_test_runner import addon_module as module, core, operator_error  # noqa: E402

MUSCULAR = "characters/makehuman_muscular_male/makehuman_muscular_male.glb"
TMP = tempfile.mkdtemp(prefix="myoskin_test_muscles_")


def clear_scene():
    bpy.ops.wm.read_homefile(use_empty=True)


def add_arm(seed=1):
    clear_scene()
    assert bpy.ops.myoskin.add_synthetic_arm(seed=seed) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    return skin.parent, skin


def extracted_arm(seed=1):
    arm, skin = add_arm(seed)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    return arm, skin, arm.myoskin


def mesh_co(obj):
    co = np.empty(3 * len(obj.data.vertices), dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


# ------------------------------------------------------------------------------------------------
# Extract
# ------------------------------------------------------------------------------------------------

def test_extract_on_generated_arm():
    arm, skin, state = extracted_arm()
    before = mesh_co(skin)
    direct, _ = core().extract_muscles(core().make_synthetic_arm(seed=1)[0])
    assert len(state.muscles) == len(direct) >= 4, (len(state.muscles), len(direct))
    _c, truth = core().make_synthetic_arm(seed=1)
    found = module("muscle_io").state_to_core(arm)
    assert core().measure_extraction(found, truth)["matched"] == 6  # as the core tiers (test_extraction, seeds 0-3)
    coll = state.collection
    assert coll is not None and coll.name.startswith("Muscles")
    assert coll in list(bpy.context.scene.collection.children)
    for item, m in zip(state.muscles, direct):
        surface = item.surface
        assert surface is not None and surface.name in coll.objects and surface.parent == arm
        assert surface.parent_type == 'OBJECT'
        # at rest the surface is where the core lofted it (armature at the origin: world = mesh space)
        bpy.context.view_layer.update()
        world = np.array(surface.matrix_world)
        co = mesh_co(surface) @ world[:3, :3].T + world[:3, 3]
        assert np.abs(co - np.asarray(m.surface_vertices)).max() < 1e-5
        for end in ("origin", "insertion"):
            loc = getattr(item, end + "_locator")
            assert loc is not None and loc.parent == arm and loc.parent_type == 'BONE'
            assert loc.parent_bone == getattr(m, end + "_bone") == getattr(item, end + "_bone")
            placed = np.array(loc.matrix_world.translation)
            assert np.abs(placed - np.asarray(getattr(m, end))).max() < 1e-6, (end, placed, getattr(m, end))
        assert item.joints == 4 and abs(item.bulge - 1.0) < 1e-9 and item.enabled
    # the skin is untouched
    assert np.array_equal(mesh_co(skin), before)
    assert [g.name for g in skin.vertex_groups] == [b.name for b in arm.data.bones]
    # the whole muscles.json sits in a Text datablock and parses back
    doc = json.loads(state.muscles_text.as_string())
    assert doc["format"] == "myoskin.muscles" and len(doc["muscles"]) == len(state.muscles)
    assert len(core().muscles_from_json(state.muscles_text.as_string())) == len(state.muscles)


def test_extract_with_the_rig_moved_in_the_world():
    """Muscles live in the armature's space: a moved/rotated rig gives the same muscles, placed with it."""
    arm, skin = add_arm()
    arm.location = (0.4, -1.0, 0.3)
    arm.rotation_euler = (0.2, 0.0, 0.9)
    bpy.context.view_layer.update()
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    state = arm.myoskin
    direct, _ = core().extract_muscles(core().make_synthetic_arm(seed=1)[0])
    assert len(state.muscles) == len(direct)
    to_world = np.array(arm.matrix_world)
    for item, m in zip(state.muscles, direct):
        world = np.array(item.surface.matrix_world)
        co = mesh_co(item.surface) @ world[:3, :3].T + world[:3, 3]
        expected = np.asarray(m.surface_vertices) @ to_world[:3, :3].T + to_world[:3, 3]
        # The locators' float32 world positions can read as moved, and a refreshed muscle is re-lofted without the
        # skin (reattach_muscle without a character: not clamped inside it), so either surface is the core's.
        relofted = np.asarray(core().reattach_muscle(m).surface_vertices) @ to_world[:3, :3].T + to_world[:3, 3]
        assert min(np.abs(co - expected).max(), np.abs(co - relofted).max()) < 1e-5
        placed = np.array(item.origin_locator.matrix_world.translation)
        assert np.abs(placed - (to_world[:3, :3] @ np.asarray(m.origin) + to_world[:3, 3])).max() < 1e-5


def test_extract_options_and_limits():
    arm, skin, state = extracted_arm()
    everywhere = len(state.muscles)
    # only where vertices are selected: the forearm's vertex group
    group = skin.vertex_groups["forearm"]
    assert bpy.ops.myoskin.extract_muscles(limit='GROUP', vertex_group="forearm") == {'FINISHED'}
    limited = [m.region for m in state.muscles]
    assert 0 < len(limited) < everywhere and all(r == "forearm" for r in limited), limited
    # selected vertices: select the forearm group in the mesh
    mask = module("blender_io").vertex_group_mask(skin, group.name, 0.5)
    skin.data.vertices.foreach_set("select", mask)
    assert bpy.ops.myoskin.extract_muscles(limit='SELECTED') == {'FINISHED'}
    assert sorted(m.region for m in state.muscles) == sorted(limited)
    # a stricter confidence gives no more muscles
    assert bpy.ops.myoskin.extract_muscles(min_confidence=0.95) == {'FINISHED'}
    assert len(state.muscles) <= everywhere
    # joint wrap 0: every muscle's action line is straight, no wrap display
    assert bpy.ops.myoskin.extract_muscles(joint_wrap=0.0) == {'FINISHED'}
    assert len(state.muscles) > 0
    assert all(item.wrap_type == 'none' and item.wrap_locator is None for item in state.muscles)
    # at most one per region
    assert bpy.ops.myoskin.extract_muscles(max_per_region=1) == {'FINISHED'}
    regions = [m.region for m in state.muscles]
    assert 0 < len(regions) < everywhere and len(set(regions)) == len(regions), regions
    # expert tuning reaches the core (JSON {key: value}); bad JSON or keys: clear errors
    assert bpy.ops.myoskin.extract_muscles(expert='{"filters.minEvidence": 0}') == {'FINISHED'}
    assert len(state.muscles) >= everywhere
    assert bpy.ops.myoskin.extract_muscles(expert='{"filters.minEvidence": 1000, "filters.spindleEnds": 0}') \
        == {'FINISHED'}
    assert len(state.muscles) < everywhere
    assert "not valid JSON" in operator_error(bpy.ops.myoskin.extract_muscles, expert="{min")
    assert "unknown expert extraction option 'nope'" in operator_error(bpy.ops.myoskin.extract_muscles,
                                                                      expert='{"nope": 1}')
    # empty selection / missing group: clear errors
    skin.data.vertices.foreach_set("select", np.zeros(len(skin.data.vertices), dtype=bool))
    assert "No vertices selected" in operator_error(bpy.ops.myoskin.extract_muscles, limit='SELECTED')
    assert "no vertex group 'nope'" in operator_error(bpy.ops.myoskin.extract_muscles, limit='GROUP',
                                                      vertex_group="nope")
    # replacing removes the old objects (no orphans in the Muscles collection)
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    names = {o.name for o in state.collection.objects}
    expected = set()
    for item in state.muscles:
        expected |= {item.surface.name, item.origin_locator.name, item.insertion_locator.name}
        if item.wrap_type != 'none':  # muscles crossing a joint get a joint wrap, shown as a sphere
            expected.add(item.wrap_locator.name)
    assert names == expected, names ^ expected
    assert any(item.wrap_type == 'joint' for item in state.muscles)


def test_extract_on_makehuman_glb():
    path = runner.shared_file(MUSCULAR)
    clear_scene()
    module("gltf_io").import_gltf(path)
    skin = [o for o in bpy.context.scene.objects if o.type == 'MESH'][0]
    bpy.context.view_layer.objects.active = skin
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    arm = module("blender_io").find_armature(skin)
    state = arm.myoskin
    loaded = core().load_character(path)
    direct, _ = core().extract_muscles(loaded)
    assert len(state.muscles) >= 12, len(state.muscles)  # the core tiers' floor on this body (measured 20)
    assert abs(len(state.muscles) - len(direct)) <= 2, (len(state.muscles), len(direct))
    bones = arm.data.bones
    for item in state.muscles:
        assert item.origin_bone in bones and item.insertion_bone in bones
        assert len(item.surface.data.polygons) > 0
    # mirror of a .L/.R muscle lands on the other side with flipped bone names
    sided = [i for i, m in enumerate(state.muscles) if bpy.utils.flip_name(m.origin_bone) != m.origin_bone]
    assert sided, "the limbs' muscles have sided bones"
    if sided:
        state.active_index = sided[0]
        src = state.muscles[sided[0]]
        # read before mirroring: replacing an existing mirror twin shifts the list under `src`
        src_bone, a = src.origin_bone, np.array(src.origin_locator.location)
        src_name, src_enabled = src.name, src.enabled
        assert bpy.ops.myoskin.mirror_muscle() == {'FINISHED'}
        new = state.muscles[state.active_index]
        assert new.enabled == src_enabled
        assert src_name in [m.name for m in state.muscles]  # the source is kept, only an old mirror is replaced
        assert new.origin_bone == bpy.utils.flip_name(src_bone)
        b = np.array(new.origin_locator.location)
        assert abs(a[0] + b[0]) < 1e-6 and np.abs(a[1:] - b[1:]).max() < 1e-6


# ------------------------------------------------------------------------------------------------
# The muscle list
# ------------------------------------------------------------------------------------------------

def test_list_rename_enable_delete():
    arm, skin, state = extracted_arm()
    n = len(state.muscles)
    item = state.muscles[1]
    surface, origin = item.surface, item.origin_locator
    item.name = "biceps"
    assert surface.name == "biceps" and origin.name == "biceps.origin" and surface["myoskin_muscle"] == "biceps"
    # a clashing name gets a suffix instead of two muscles of one name
    state.muscles[2].name = "biceps"
    assert state.muscles[2].name != "biceps" and state.muscles[2].name.startswith("biceps")
    assert "biceps" in [m["name"] for m in json.loads(state.muscles_text.as_string())["muscles"]]
    # disable: kept in the list and the file, left out of the core's list
    item.enabled = False
    io = module("muscle_io")
    assert len(io.state_to_core(arm)) == n - 1 and len(io.state_to_core(arm, enabled_only=False)) == n
    assert json.loads(state.muscles_text.as_string())["muscles"][1]["enabled"] is False
    # select
    state.active_index = 3
    assert bpy.ops.myoskin.select_muscle() == {'FINISHED'}
    assert state.muscles[3].surface.select_get()
    # delete removes its objects
    state.active_index = 1
    names = [item.surface.name, item.origin_locator.name, item.insertion_locator.name]
    assert bpy.ops.myoskin.remove_muscle() == {'FINISHED'}
    assert len(state.muscles) == n - 1 and "biceps" not in [m.name for m in state.muscles]
    assert not any(name in bpy.data.objects for name in names)
    assert len(json.loads(state.muscles_text.as_string())["muscles"]) == n - 1


def test_mirror_muscle_on_arm():
    arm, skin, state = extracted_arm()
    state.active_index = 0
    src = state.muscles[0]
    src_core = module("muscle_io").item_to_core(arm, src)
    assert bpy.ops.myoskin.mirror_muscle() == {'FINISHED'}
    new = state.muscles[len(state.muscles) - 1]
    assert new.name == src.name + ".mirror"  # the arm's bones have no side suffix
    m = module("muscle_io").item_to_core(arm, new)
    a, b = np.asarray(src_core.root_curve), np.asarray(m.root_curve)
    assert np.abs(a * [-1, 1, 1] - b).max() < 1e-6  # locators are float32
    v = mesh_co(new.surface)
    assert abs(v[:, 0].mean() + mesh_co(src.surface)[:, 0].mean()) < 1e-4
    # mirroring again replaces the mirror instead of piling up copies
    state.active_index = 0
    n = len(state.muscles)
    assert bpy.ops.myoskin.mirror_muscle() == {'FINISHED'} and len(state.muscles) == n


def test_add_muscle_from_faces_and_group():
    arm, skin, state = extracted_arm()
    # mark the skin region over the first extracted muscle's belly
    io = module("muscle_io")
    target = io.item_to_core(arm, state.muscles[0])
    centers = np.asarray(target.section_centers)
    co = mesh_co(skin)
    d = np.linalg.norm(co[:, None, :] - centers[None, ::2, :], axis=2).min(axis=1)
    region = d < 1.6 * float(np.asarray(target.section_a).max())
    n = len(state.muscles)
    bpy.ops.myoskin.remove_muscle(index=0)
    faces = np.empty(len(skin.data.polygons) * 3, dtype=np.int32)
    skin.data.polygons.foreach_get("vertices", faces)
    sel = region[faces.reshape(-1, 3)].all(axis=1)
    skin.data.polygons.foreach_set("select", sel)
    assert bpy.ops.myoskin.add_muscle_from_region(source='FACES') == {'FINISHED'}
    assert len(state.muscles) == n
    added = io.item_to_core(arm, state.muscles[len(state.muscles) - 1])
    gap = np.linalg.norm(np.asarray(added.section_centers)[:, None] - centers[None], axis=2).min(axis=1)
    assert np.median(gap) < 0.5 * float(np.asarray(target.section_a).mean()), gap
    # the same through a vertex group
    group = skin.vertex_groups.new(name="mark")
    group.add(np.flatnonzero(region).tolist(), 1.0, 'REPLACE')
    assert bpy.ops.myoskin.add_muscle_from_region(source='GROUP', vertex_group="mark") == {'FINISHED'}
    assert len(state.muscles) == n + 1
    # in Edit Mode, as an artist marks faces: the selection is read from the edit mesh
    bpy.context.view_layer.objects.active = skin
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='DESELECT')
    bpy.ops.object.mode_set(mode='OBJECT')
    skin.data.polygons.foreach_set("select", sel)
    bpy.ops.object.mode_set(mode='EDIT')
    assert bpy.ops.myoskin.add_muscle_from_region(source='FACES') == {'FINISHED'}
    bpy.ops.object.mode_set(mode='OBJECT')
    assert len(state.muscles) == n + 2
    # nothing marked: clear errors
    skin.data.polygons.foreach_set("select", np.zeros(len(skin.data.polygons), dtype=bool))
    assert "No faces selected" in operator_error(bpy.ops.myoskin.add_muscle_from_region, source='FACES')
    empty = skin.vertex_groups.new(name="empty")
    assert "is empty" in operator_error(bpy.ops.myoskin.add_muscle_from_region, source='GROUP',
                                        vertex_group=empty.name)


def test_add_muscle_from_region_without_a_bump_adds_nothing():
    """On an arm whose bellies are a fifth of the default, extraction keeps some as closed spindles (their shape is
    their evidence) without a forced region; a marked region with no bump still says so instead of adding one of
    those."""
    clear_scene()
    assert bpy.ops.myoskin.add_synthetic_arm(seed=0, muscle_scale=0.2) == {'FINISHED'}
    skin = bpy.context.view_layer.objects.active
    arm = skin.parent
    assert bpy.ops.myoskin.extract_muscles() == {'FINISHED'}
    state = arm.myoskin
    n = len(state.muscles)
    assert n > 0  # faint bellies found as spindles: what a forced region must not pick up
    io = module("muscle_io")
    centres = np.concatenate([np.asarray(io.item_to_core(arm, m).section_centers) for m in state.muscles])
    co = mesh_co(skin)
    # the end slab of the arm (5 % of its length) farther from every extracted muscle: the hand's end, no belly
    axis = int(np.argmax(co.max(axis=0) - co.min(axis=0)))
    lo, hi = co[:, axis].min(), co[:, axis].max()
    slabs = [co[:, axis] < lo + 0.05 * (hi - lo), co[:, axis] > hi - 0.05 * (hi - lo)]
    far = [np.linalg.norm(co[s][:, None] - centres[None], axis=2).min() for s in slabs]
    region = slabs[int(np.argmax(far))]
    faces = np.empty(len(skin.data.polygons) * 3, dtype=np.int32)
    skin.data.polygons.foreach_get("vertices", faces)
    sel = region[faces.reshape(-1, 3)].all(axis=1)
    assert sel.any()
    skin.data.polygons.foreach_set("select", sel)
    assert "No bump found" in operator_error(bpy.ops.myoskin.add_muscle_from_region, source='FACES')
    assert len(state.muscles) == n


# ------------------------------------------------------------------------------------------------
# Locators and wrap settings
# ------------------------------------------------------------------------------------------------

def test_moving_a_locator_updates_the_muscle():
    arm, skin, state = extracted_arm()
    item = state.muscles[0]
    io = module("muscle_io")
    before_curve = np.asarray(io.item_to_core(arm, item).root_curve)
    before_surface = mesh_co(item.surface)
    others = [mesh_co(m.surface) for m in list(state.muscles)[1:]]
    item.insertion_locator.location.z += 0.02
    bpy.context.view_layer.update()  # the depsgraph handler re-attaches right away
    m = io.item_to_core(arm, item)
    curve, surface = np.asarray(m.root_curve), mesh_co(item.surface)
    assert np.abs(curve[-1] - np.array(item.insertion_locator.location)).max() < 1e-9
    assert abs(curve[-1][2] - before_curve[-1][2] - 0.02) < 1e-6
    assert np.abs(curve[0] - before_curve[0]).max() < 1e-6  # the origin stayed (locators are float32)
    assert np.abs(surface - before_surface).max() > 0.01
    # the pole vertex of the insertion cap is the insertion
    assert np.linalg.norm(surface - np.array(item.insertion_locator.location), axis=1).min() < 1e-6
    assert others
    for m2, co in zip(list(state.muscles)[1:], others):
        assert np.array_equal(mesh_co(m2.surface), co)  # the other muscles did not change
    stored = json.loads(state.muscles_text.as_string())["muscles"][0]
    assert abs(stored["insertion"]["position"][2] - curve[-1][2]) < 1e-9
    # posing the armature moves the locator in the world but not its rest position: no re-attach
    pb = arm.pose.bones["forearm"]
    pb.rotation_mode = 'XYZ'
    pb.rotation_euler = (1.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    assert np.array_equal(mesh_co(item.surface), surface)


def test_locator_moved_into_the_joint_sphere_shrinks_it():
    arm, skin, state = extracted_arm()
    item = next(m for m in state.muscles if m.wrap_type == 'joint')
    centre = np.array(arm.data.bones[item.wrap_bone].head_local)
    radius = item.wrap_radius
    # drag the insertion to half the radius from the joint centre: the sphere shrinks to fit, no error
    item.insertion_locator.location = centre + np.array([0.5 * radius, 0.0, 0.0])
    bpy.context.view_layer.update()
    assert abs(item.wrap_radius - 0.4 * radius) < 1e-6, (item.wrap_radius, radius)
    assert abs(item.wrap_locator.empty_display_size - item.wrap_radius) < 1e-6
    character = module("blender_io").character_from_blender(skin, arm)
    core().MuscleRig(character, [module("muscle_io").item_to_core(arm, item)])  # a valid rig


def test_snap_locator_to_nearest_bone():
    arm, skin, state = extracted_arm()
    state.active_index = 0
    item = state.muscles[0]
    loc = item.origin_locator
    loc.location = np.array(arm.data.bones["forearm"].head_local) + np.array([0.03, 0.0, 0.0])
    bpy.context.view_layer.update()
    assert bpy.ops.myoskin.snap_locator(end='origin') == {'FINISHED'}
    bone = arm.data.bones[item.origin_bone]
    p = np.array(loc.location)
    a, b = np.array(bone.head_local), np.array(bone.tail_local)
    t = np.dot(p - a, b - a) / np.dot(b - a, b - a)
    assert -1e-9 <= t <= 1 + 1e-9 and np.linalg.norm(a + t * (b - a) - p) < 1e-6
    assert loc.parent_bone == item.origin_bone
    assert np.abs(np.asarray(module("muscle_io").item_to_core(arm, item).root_curve)[0] - p).max() < 1e-9


def test_wrap_settings_and_display():
    arm, skin, state = extracted_arm()
    item = state.muscles[0]
    item.wrap_type = 'joint'
    item.wrap_bone = "forearm"
    item.wrap_radius = 0.04
    display = item.wrap_locator
    assert display is not None and display.empty_display_type == 'SPHERE'
    assert abs(display.empty_display_size - 0.04) < 1e-7
    bpy.context.view_layer.update()
    assert np.abs(np.array(display.matrix_world.translation) -
                  np.array(arm.data.bones["forearm"].head_local)).max() < 1e-6
    m = module("muscle_io").item_to_core(arm, item)
    assert (m.wrap_type, m.wrap_bone, abs(m.wrap_radius - 0.04) < 1e-9) == ('joint', 'forearm', True)
    item.wrap_type = 'bone'
    item.wrap_bone = "upper_arm"
    bpy.context.view_layer.update()
    bone_y = np.array(arm.data.bones["upper_arm"].matrix_local)[:3, 1]
    cone_y = lambda: np.array(item.wrap_locator.matrix_world)[:3, 1]  # noqa: E731
    assert item.wrap_locator.empty_display_type == 'CONE' and np.dot(cone_y(), bone_y) > 0.99
    item.wrap_side = '-1'
    bpy.context.view_layer.update()
    assert np.dot(cone_y(), bone_y) < -0.99  # the display shows the side
    m = module("muscle_io").item_to_core(arm, item)
    assert (m.wrap_type, m.wrap_bone, m.wrap_side) == ('bone', 'upper_arm', -1)
    item.bulge, item.joints = 2.5, 6
    m = module("muscle_io").item_to_core(arm, item)
    assert abs(m.bulge - 2.5) < 1e-9 and m.joints == 6
    stored = json.loads(state.muscles_text.as_string())["muscles"][0]
    assert stored["wrap"]["type"] == "bone" and stored["joints"] == 6
    item.wrap_type = 'none'
    assert item.wrap_locator is None and not bpy.data.objects.get(item.name + ".wrap")


# ------------------------------------------------------------------------------------------------
# Save / reload
# ------------------------------------------------------------------------------------------------

def test_save_reload_keeps_muscle_state():
    arm, skin, state = extracted_arm()
    item = state.muscles[0]
    item.name = "renamed"
    item.bulge = 1.7
    item.enabled = False
    item.wrap_type, item.wrap_bone, item.wrap_radius = 'joint', "forearm", 0.05
    item.origin_locator.location.x += 0.005
    bpy.context.view_layer.update()
    io = module("muscle_io")
    before = [(m.name, np.asarray(m.root_curve).copy(), m.bulge, m.wrap_type) for m in
              io.state_to_core(arm, enabled_only=False)]
    surfaces = [mesh_co(m.surface) for m in state.muscles]
    text = state.muscles_text.as_string()
    path = os.path.join(TMP, "muscles.blend")
    arm_name = arm.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    arm = bpy.data.objects[arm_name]
    state = arm.myoskin
    assert state.muscles_text.as_string() == text
    after = io.state_to_core(arm, enabled_only=False)
    assert [m.name for m in after] == [b[0] for b in before]
    for (name, curve, bulge, wrap), m in zip(before, after):
        assert np.array_equal(np.asarray(m.root_curve), curve) and m.bulge == bulge and m.wrap_type == wrap
    assert not state.muscles[0].enabled and state.muscles[0].wrap_locator is not None
    for m, co in zip(state.muscles, surfaces):
        assert np.array_equal(mesh_co(m.surface), co)
    # the handler works after reload (it looks everything up by name)
    state.muscles[1].insertion_locator.location.z -= 0.01
    bpy.context.view_layer.update()
    assert not np.array_equal(mesh_co(state.muscles[1].surface), surfaces[1])


def test_file_opens_without_the_addon():
    """ID properties and the muscles.json Text need no registered classes."""
    arm, skin, state = extracted_arm()
    n = len(state.muscles)
    arm_name = arm.name
    path = os.path.join(TMP, "noaddon.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    import addon_utils
    addon_utils.disable(runner.ADDON, default_set=True)
    try:
        bpy.ops.wm.open_mainfile(filepath=path)
        arm = bpy.data.objects[arm_name]
        # Blender 5.0+ keeps bpy.props data apart from the user's custom properties
        raw = (arm.bl_system_properties_get() if hasattr(arm, "bl_system_properties_get") else arm)["myoskin"]
        assert len(raw["muscles"]) == n
        text = bpy.data.texts[f"{arm.name}.muscles.json"].as_string()
        assert len(json.loads(text)["muscles"]) == n
        assert len(bpy.data.collections["Muscles"].objects) >= n
    finally:
        addon_utils.enable(runner.ADDON, default_set=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert len(bpy.data.objects[arm_name].myoskin.muscles) == n


# ------------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------------

def test_bad_input_messages():
    clear_scene()
    bpy.context.view_layer.objects.active = None
    assert "No active object" in operator_error(bpy.ops.myoskin.extract_muscles)
    mesh = bpy.data.objects.new("lonely", bpy.data.meshes.new("lonely"))
    bpy.context.scene.collection.objects.link(mesh)
    bpy.context.view_layer.objects.active = mesh
    assert "has no armature" in operator_error(bpy.ops.myoskin.extract_muscles)
    # skinned by an armature, but no vertex group of a deform bone
    arm, skin = add_arm()
    for g in list(skin.vertex_groups):
        skin.vertex_groups.remove(g)
    assert "is not skinned" in operator_error(bpy.ops.myoskin.extract_muscles)
    # nothing extracted
    arm, skin = add_arm()
    for op in (bpy.ops.myoskin.remove_muscle, bpy.ops.myoskin.mirror_muscle, bpy.ops.myoskin.select_muscle,
               bpy.ops.myoskin.refresh_muscles):
        assert "run Extract Muscles first" in operator_error(op), op


def test_deleted_muscle_object_and_renamed_bone():
    arm, skin, state = extracted_arm()
    item = state.muscles[0]
    bpy.data.objects.remove(item.surface)
    bpy.data.objects.remove(item.origin_locator)
    state.active_index = 0
    assert "has no surface object" in operator_error(bpy.ops.myoskin.select_muscle)
    assert bpy.ops.myoskin.refresh_muscles() == {'FINISHED'}  # rebuilds both
    assert item.surface is not None and item.origin_locator is not None and len(item.surface.data.vertices)
    # a renamed bone: clear message naming the muscle and the bone
    old = item.insertion_bone
    arm.data.bones[old].name = "renamed_bone"
    text = operator_error(bpy.ops.myoskin.refresh_muscles)
    assert f"'{old}' is not in armature" in text and item.name in text, text
    arm.data.bones["renamed_bone"].name = old
    assert bpy.ops.myoskin.refresh_muscles() == {'FINISHED'}


def test_property_callback_error_is_shown_in_the_panel():
    """A property update callback that fails does not raise into the UI: its message is stored for the
    armature (runtime.last_error), drawn by the sidebar with a Dismiss button, and dismissed by it."""
    arm, skin, state = extracted_arm()
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from fake_layout import draw_panel
    runtime, io = module("runtime"), module("muscle_io")
    assert runtime.last_error(arm) == ""
    assert ("operator", "myoskin.clear_error") not in draw_panel(bpy.types.MYOSKIN_PT_main).log
    real = io.update_wrap_display

    def broken(arm_obj, item):
        raise RuntimeError("wrap display exploded")
    io.update_wrap_display = broken
    try:
        state.muscles[0].bulge = 2.0  # the update callback runs (and fails) here
    finally:
        io.update_wrap_display = real
    assert state.muscles[0].bulge == 2.0
    message = runtime.last_error(arm.name)
    assert message == f"could not apply the change to '{state.muscles[0].name}': wrap display exploded", message
    layout = draw_panel(bpy.types.MYOSKIN_PT_main)
    assert " ".join(message.split()) in " ".join(layout.text().split()), layout.text()
    assert ("operator", "myoskin.clear_error") in layout.log
    assert bpy.ops.myoskin.clear_error(armature=arm.name) == {'FINISHED'}
    assert runtime.last_error(arm) == ""
    assert ("operator", "myoskin.clear_error") not in draw_panel(bpy.types.MYOSKIN_PT_main).log
    state.muscles[0].bulge = 1.5  # works again: no new error
    assert runtime.last_error(arm) == ""


def test_panels_draw_with_muscles():
    arm, skin, state = extracted_arm()
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from fake_layout import draw_panel
    for name in ("MYOSKIN_PT_extract", "MYOSKIN_PT_edit", "MYOSKIN_PT_bind", "MYOSKIN_PT_bake",
                 "MYOSKIN_PT_skin_muscles"):
        log = draw_panel(getattr(bpy.types, name)).log
        assert log, name
    edit = draw_panel(bpy.types.MYOSKIN_PT_edit).log
    assert ("template_list", "MYOSKIN_UL_muscles") in edit
    assert ("operator", "myoskin.add_muscle_from_region") in edit and ("prop", "wrap_type") in edit
    assert ("operator", "myoskin.extract_muscles") in draw_panel(bpy.types.MYOSKIN_PT_extract).log
    assert ("operator", "myoskin.bind") in draw_panel(bpy.types.MYOSKIN_PT_bind).log
    assert ("operator", "myoskin.bake_action") in draw_panel(bpy.types.MYOSKIN_PT_bake).log
    text = " ".join(t for k, t in draw_panel(bpy.types.MYOSKIN_PT_skin_muscles).log if k == "label")
    assert f"{len(state.muscles)} muscles" in text, text


runner.run()
