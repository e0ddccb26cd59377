# SPDX-License-Identifier: GPL-3.0-or-later
"""Live update of bound muscles: when the skeleton moves, the muscle-joint bones (and the muscle surfaces)
follow, exactly as the core computes them.

Route (measured by benchmarks/bench_blender_playback.py, README "Live update"):
1. `frame_change_pre` predicts the skeleton's pose at the new frame from the Action's F-curves (plain FK in
   the core, `pose_from_channels`) when nothing else drives the skeleton (no bone constraints, drivers or
   NLA), and writes the joints before Blender evaluates: one evaluation per frame. What the prediction
   needs (predictability, the F-curve indices, the channels without F-curves) is cached in a
   PredictionPlan, so a frame costs the F-curve evaluations, two core calls and three foreach_set.
2. `frame_change_post` + `depsgraph_update_post` read the skeleton's pose from the EVALUATED armature of
   the depsgraph they are given (IK, constraints and drivers applied). When it equals the prediction (to
   1e-6) nothing more happens; otherwise (IK, constraints, hand posing, a stale plan) they drop the plan,
   evaluate the core's MuscleRig, write the joints and tag the armature, and Blender's second evaluation
   pass in the same frame_set / update re-skins with the new joints: exact, no one-frame lag, two
   evaluations. So a cache can only cost time, never a wrong frame.
3. Hand posing (and scripts setting channels): `depsgraph_update_pre` poses the joints from the skeleton's
   channels by the same FK before Blender evaluates (`pose_armature`), so the update skins once.
4. For a skeleton the prediction cannot follow, frame_change_pre switches the bound skins' skinning
   modifiers off for the first pass (`defer_skinning`; Blender 4.3 and later, skins without simulation
   state) and frame_change_post switches them on again: the frame skins once, in the second pass.
The handlers write ORIGINAL data, so every depsgraph (viewport, F12 / Cycles render with
render.use_lock_interface on) sees the same joints.

State: nothing is held between calls but a cache keyed by armature name and the bind record's text (rebuilt
after reload or undo) and, within one frame change, the modifiers its first pass skips (runtime.deferred),
owned by runtime.py (runtime.live_rigs, runtime.deferred) with the re-entrancy guard every handler shares; objects are looked up in bpy.data on every call. A handler that fails reports it through
runtime.report_error (the panels show it). Without the add-on the file opens and shows the joints as last
written (or as baked to the Action).

Layer: runtime. Imports downward only (anim_compat, binding, core_loader, muscle_io, rig_io, runtime).
"""

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import anim_compat, binding, blender_io, core_loader, core_skin, muscle_io, rig_io, runtime

# Frames whose joints were written from the F-curve prediction / from the evaluated pose, and frames whose first
# evaluation pass skipped the skinning (defer_skinning).
stats = {"predicted": 0, "written": 0, "deferred": 0, "posed": 0}


def joints_slide(record):
    """The bind record's MuscleRig joints_slide (the rig's Joints Slide at Bind; a record written before the setting
    existed was bound with sliding joints)."""
    return bool(record.get("joints_slide", True))


def slide_limits(record):
    """The bind record's MuscleRig slide_limits (#J by 2, computed at Bind from the skin weights; a record written
    before them has none: its joints slide unlimited, as they were bound)."""
    return record.get("slide_limits") or []


class LiveRig:
    """A MuscleRig built from an armature's bind record, plus index arrays into its pose bones."""

    def __init__(self, arm_obj, record, key):
        core = core_loader.core()
        self.key = key
        self.bone_names = record["bone_names"]
        self.joint_names = record["joint_names"]
        self.character = skeleton_character(record)
        muscles = [core.reattach_muscle(m) for m in core.muscles_from_json(record["muscles"])]
        self.rig = core.MuscleRig(self.character, muscles, joints_slide=joints_slide(record),
                                  slide_limits=slide_limits(record))
        if list(self.rig.joint_names) != self.joint_names:
            raise ValueError(f"'{arm_obj.name}': the bind record's joints do not match its muscles: bind again")
        self.surface_names = record.get("surfaces", [])
        skins = record.get("skins") or [record.get("skin")]
        self.skin_names = [n for n in skins if isinstance(n, str)] if isinstance(skins, list) else []
        # The anchored deformer (bind record "deformer": "anchored"): per bound mesh (name, core_skin.MeshFrame,
        # core AnchoredSkin built from the mesh at rest in armature space with its skeleton bones' weights).
        self.anchored = []
        if record.get("deformer") == "anchored":
            for name in record.get("skins") or [record.get("skin")]:
                obj = bpy.data.objects.get(name) if isinstance(name, str) else None
                if obj is None or obj.type != 'MESH':
                    raise ValueError(f"the anchored skin '{name}' is missing: bind again")
                pinned = np.flatnonzero(blender_io.vertex_group_weights(obj, core_skin.PINNED_GROUP) > 0.5)
                anchored = core.AnchoredSkin(blender_io.character_from_blender(obj, arm_obj), muscles,
                                             stuffing=list(record.get("stuffing") or []),
                                             pinned=[int(i) for i in pinned])
                self.anchored.append((name, core_skin.MeshFrame(obj, arm_obj), anchored))
        self.last_pose = None  # the skeleton pose the joints were last written for
        self.last_with_surfaces = False  # whether the muscle surfaces were written with them
        self.last_surface_pose = None  # baked rigs: the pose the muscle surfaces were last written for
        # Speed-ups of the frame_change_pre prediction, dropped whenever a prediction turned out wrong (the
        # post handlers compare it with the evaluated pose, so a stale cache costs a second pass, never
        # a wrong frame): whether the skeleton is predictable (None = check again) and the PredictionPlan.
        self.predictable = None
        self.plan = None
        self.connected = None  # #B bool: connected skeleton bones (channel_pose, the hand-posing prediction)
        self.channels = None  # the skeleton's channels channel_pose last read (float32, flat)
        self.still = False  # the last post handler found the skeleton where the joints were written for (defer_skinning)
        self._pose_bone_keys = None
        self._skeleton_index = None

    def skeleton_indices(self, pose_bones):
        """Pose-bone indices of the bind record's skeleton bones (cached while the armature's bone names
        stay the same); ValueError naming a renamed or deleted bone."""
        keys = tuple(pose_bones.keys())
        if keys != self._pose_bone_keys:
            position = {n: i for i, n in enumerate(keys)}
            missing = [n for n in self.bone_names if n not in position]
            if missing:
                raise ValueError(f"bone '{missing[0]}' was renamed or deleted since the bind: bind again")
            self._skeleton_index = np.array([position[n] for n in self.bone_names], dtype=np.int64)
            self._pose_bone_keys = keys
        return self._skeleton_index

    def forget_prediction(self):
        """A prediction was wrong (or the pose came from elsewhere): check predictability and rebuild the
        plan at the next frame."""
        self.predictable = None
        self.plan = None
        self.connected = None
        self.channels = None


def skeleton_character(record):
    """A core Character carrying only the bind record's skeleton (MuscleRig needs no skin); its mesh is a
    unit tetrahedron placeholder."""
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)
    return core_loader.core().character_from_arrays(
        "skeleton", tetra, faces, record["bone_names"], np.asarray(record["bone_parents"], dtype=np.int32),
        np.asarray(record["bone_heads"], dtype=np.float64), np.asarray(record["bone_tails"], dtype=np.float64),
        np.ascontiguousarray(record["bone_rest"], dtype=np.float64), np.zeros((0, 0), dtype=np.int32),
        np.zeros((0, 0)))


def apply_settings_to_bound(arm_obj):
    """After a muscle setting changed on a bound armature: when the bound joints stay the same (names and
    bind matrices, e.g. a new bulge factor), update the bind record so live update uses the new settings
    at once and return True; otherwise (the rest path or joints changed) return False: bind again."""
    if arm_obj.myoskin.bind_text is None:
        return False
    core = core_loader.core()
    record = binding.read_bind_record(arm_obj)
    try:
        muscles = [core.reattach_muscle(m) for m in muscle_io.state_to_core(arm_obj)]
        rig = core.MuscleRig(skeleton_character(record), muscles, joints_slide=joints_slide(record),
                             slide_limits=slide_limits(record))
    except ValueError:
        return False
    old = live_rig(arm_obj).rig
    if list(rig.joint_names) != record["joint_names"] or \
            np.abs(np.asarray(rig.bind_matrices) - np.asarray(old.bind_matrices)).max() > 1e-9:
        return False
    record["muscles"] = core.muscles_to_json(muscles)
    binding.write_bind_record(arm_obj, record)
    runtime.forget(arm_obj.name)
    update_armature(arm_obj, force=True)
    return True


def live_rig(arm_obj):
    """The cached LiveRig of a bound armature (rebuilt when its bind record's digest changed, e.g. after a
    new bind, an undo or a reload; the text itself is only read then)."""
    text = arm_obj.myoskin.bind_text
    if text is None:
        raise ValueError(f"'{arm_obj.name}' has no bind record: bind again")
    key = text.get(binding.RECORD_KEY) or text.as_string()
    cached = runtime.live_rigs.get(arm_obj.name)
    if cached is None or cached.key != key:
        cached = LiveRig(arm_obj, binding.read_bind_record(arm_obj), key)
        runtime.live_rigs[arm_obj.name] = cached
    return cached


def evaluated_pose(arm_obj, live, depsgraph=None):
    """#B by 4 by 4 skeleton pose (armature space) from the evaluated armature (constraints and IK applied)."""
    source = arm_obj.evaluated_get(depsgraph) if depsgraph is not None else arm_obj
    return rig_io.pose_bone_matrices(source)[live.skeleton_indices(source.pose.bones)]


def muscles_visible(arm_obj):
    coll = arm_obj.myoskin.collection
    if coll is None or coll.hide_viewport:
        return False
    return any(o.visible_get() for o in coll.objects if o.type == 'MESH')


def update_armature(arm_obj, depsgraph=None, force=False, surfaces=None):
    """Pose one bound armature's muscle joints (and surfaces) from its evaluated skeleton. Returns True
    when it wrote something."""
    live = live_rig(arm_obj)
    pose = evaluated_pose(arm_obj, live, depsgraph)
    surfaces = muscles_visible(arm_obj) if surfaces is None else surfaces
    live.still = not force and up_to_date(live, pose, surfaces)
    if live.still:
        return False
    write_pose(arm_obj, live, pose, surfaces)
    live.forget_prediction()  # the skeleton did not move as predicted (IK, constraints, hand posing)
    stats["written"] += 1
    return True


def write_pose(arm_obj, live, pose, with_surfaces):
    """Evaluate the rig for a skeleton pose (#B by 4 by 4) and write the joint bones (and the surfaces)."""
    result = live.rig.evaluate(pose, with_surfaces=with_surfaces)
    rig_io.write_joint_matrices(arm_obj, live.joint_names, result["joint_matrices"],
                                parent_matrices=(live.bone_names, pose))
    if with_surfaces:
        write_surfaces(arm_obj, live, result["surfaces"])
    if live.anchored:
        write_anchored(live, pose)
    live.last_pose = pose
    live.last_with_surfaces = with_surfaces


def up_to_date(live, pose, surfaces):
    """True when the joints (and, when `surfaces`, the muscle surfaces) were last written for this pose."""
    return same_pose(pose, live.last_pose) and (live.last_with_surfaces or not surfaces)


def write_surfaces(arm_obj, live, surfaces):
    for name, vertices in zip(live.surface_names, surfaces):
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != 'MESH' or len(obj.data.vertices) != len(vertices):
            continue
        obj.data.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
        obj.data.update()


def write_anchored(live, pose):
    """The anchored deformer: evaluate each mesh's AnchoredSkin for a skeleton pose (#B by 4 by 4) and write
    its offsets from rest for the Core Skin modifier (a mesh in Edit Mode or with another vertex count since
    the bind is skipped)."""
    for name, frame, anchored in live.anchored:
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != 'MESH' or obj.mode == 'EDIT' or len(obj.data.vertices) != len(frame.rest):
            continue
        core_skin.write_offsets(obj, frame.offsets(anchored.evaluate(pose)))


def split_bound_armatures(scene):
    """(bound armatures with live update on, bound armatures playing their baked Action), in one pass."""
    live_on, baked = [], []
    for o in scene.objects:
        if o.type == 'ARMATURE':
            state = o.myoskin
            if state.bound:
                (live_on if state.live else baked).append(o)
    return live_on, baked


def update_surfaces(arm_obj, depsgraph=None):
    """Live update off: the baked Action moves the joints natively; the muscle surfaces (mesh objects that
    are not skinned) and anchored skins follow the evaluated skeleton here. Returns True when it wrote."""
    visible = muscles_visible(arm_obj)
    live = live_rig(arm_obj)
    if not visible and not live.anchored:
        return False
    pose = evaluated_pose(arm_obj, live, depsgraph)
    if same_pose(pose, live.last_surface_pose):
        return False
    if visible:
        write_surfaces(arm_obj, live, live.rig.evaluate(pose, with_surfaces=True)["surfaces"])
    if live.anchored:
        write_anchored(live, pose)
    live.last_surface_pose = pose
    return True


# ------------------------------------------------------------------------------------------------
# Prediction of the skeleton's pose from F-curves (frame_change_pre)
# ------------------------------------------------------------------------------------------------

PREDICT_TOLERANCE = 1e-6  # predicted vs evaluated pose matrices, relative to the rig's size (float32 data)


def same_pose(pose, previous):
    """True when two #B by 4 by 4 poses agree within PREDICT_TOLERANCE x max(1 m, the largest translation)."""
    if previous is None:
        return False
    scale = max(1.0, float(np.abs(previous[:, :3, 3]).max()))
    return float(np.abs(pose - previous).max()) <= PREDICT_TOLERANCE * scale


def _predictable(arm_obj, live):
    """True when the skeleton's pose is its F-curves' plain FK: no constraints on any bone, no drivers, no
    NLA strips, every bone inheriting rotation and scale fully with local location."""
    anim = arm_obj.animation_data
    if anim is not None and (len(anim.drivers) or any(len(t.strips) for t in anim.nla_tracks)):
        return False
    for pb in arm_obj.pose.bones:
        if any(not c.mute and c.influence > 0.0 for c in pb.constraints):
            return False
    for bone in arm_obj.data.bones:
        if not bone.use_inherit_rotation or bone.inherit_scale != 'FULL' or not bone.use_local_location:
            return False
    return True


CHANNELS = {"location": 3, "rotation_quaternion": 4, "rotation_euler": 3, "rotation_axis_angle": 4, "scale": 3}
ROTATION_MODES = {'AXIS_ANGLE': -1, 'QUATERNION': 0, 'XYZ': 1, 'XZY': 2, 'YXZ': 3, 'YZX': 4, 'ZXY': 5, 'ZYX': 6}
ROTATION_CHANNEL = {'QUATERNION': "rotation_quaternion", 'AXIS_ANGLE': "rotation_axis_angle"}  # else Euler


CHANNEL_WIDTHS = (("location", 3), ("scale", 3), ("rotation_euler", 3), ("rotation_quaternion", 4),
                  ("rotation_axis_angle", 4))


def read_channels(pose_bones, index):
    """{channel: #B by width float32} of the skeleton bones (`index` into pose_bones), one foreach_get each."""
    n, read = len(pose_bones), {}
    for prop, width in CHANNEL_WIDTHS:
        flat = np.empty(n * width, dtype=np.float32)
        pose_bones.foreach_get(prop, flat)
        read[prop] = flat.reshape(n, width)[index]
    return read


def skeleton_channels(pose_bones, index, read, connected):
    """What pose_from_channels takes, from read_channels' arrays: (#B by 3 location, 0 for a bone connected to its
    parent (Blender ignores it), rotation mode names, #B by 4 rotation of each bone's mode, #B by 3 scale).
    The modes are read bone by bone: foreach_get of the enum returns garbage on Blender 3.4."""
    names = [pb.rotation_mode for pb in pose_bones]
    modes = [names[int(k)] for k in index]
    location = np.where(np.asarray(connected)[:, None], 0.0, read["location"].astype(np.float64))
    rotation = np.zeros((len(index), 4))
    for i, mode in enumerate(modes):
        prop = ROTATION_CHANNEL.get(mode, "rotation_euler")
        rotation[i, :CHANNELS[prop]] = read[prop][i]
    return location, modes, rotation, read["scale"].astype(np.float64)


class PredictionPlan:
    """What predicted_pose needs, read once: the skeleton bones' channels as they are now (location, scale,
    the rotation of each bone's mode as one #B by 4 array; the location of a bone connected to its parent
    is 0, Blender ignores it), the bones' rotation modes, and per animated channel the index of its F-curve
    in the Action and where its value goes. Per frame only the F-curves are evaluated. Validated by the
    Action's identity and its F-curve count; anything else that changes (a channel edited by hand, a curve
    muted, a rotation mode, the curve order) makes the prediction differ from the evaluated pose, and the
    post handlers then drop the plan."""

    def __init__(self, arm_obj, live, anim):
        from bpy.utils import escape_identifier
        pose_bones = arm_obj.pose.bones
        index = live.skeleton_indices(pose_bones)
        fcurves = anim_compat.object_fcurves(anim)
        self.action = anim_compat.action_key(anim)
        self.fcurve_count = len(fcurves)
        bones = [pose_bones[int(k)] for k in index]
        self.location, modes, self.rotation, self.scale = skeleton_channels(
            pose_bones, index, read_channels(pose_bones, index), [pb.bone.use_connect for pb in bones])
        self.modes = [ROTATION_MODES[m] for m in modes]  # the core's (Blender's) codes
        rotation = [ROTATION_CHANNEL.get(m, "rotation_euler") for m in modes]
        target = {"location": self.location, "scale": self.scale}
        paths = {}
        for i, (pb, prop) in enumerate(zip(bones, rotation)):
            path = f'pose.bones["{escape_identifier(pb.name)}"].'
            if not pb.bone.use_connect:
                paths[path + "location"] = (i, "location")
            paths[path + "scale"] = (i, "scale")
            paths[path + prop] = (i, prop)
        self.curves = []  # (F-curve index in the Action, target array, bone position, component)
        for c, fc in enumerate(fcurves):
            hit = paths.get(fc.data_path)
            if hit is not None and not fc.mute and 0 <= fc.array_index < CHANNELS[hit[1]]:
                self.curves.append((c, target.get(hit[1], self.rotation), hit[0], fc.array_index))

    def valid_for(self, anim):
        return (self.action == anim_compat.action_key(anim)
                and self.fcurve_count == len(anim_compat.object_fcurves(anim)))


def predicted_pose(arm_obj, live, frame):
    """#B by 4 by 4 skeleton pose at `frame` by FK from the Action's F-curves, or None when something else
    (constraints, IK, drivers, NLA) may drive the skeleton. Channels without an F-curve keep their values
    (as read into the PredictionPlan); the FK runs in the core (pose_from_channels)."""
    if live.predictable is None:
        live.predictable = _predictable(arm_obj, live)
        live.plan = None
    if not live.predictable:
        return None
    anim = arm_obj.animation_data
    plan = live.plan
    if plan is None or not plan.valid_for(anim):
        plan = live.plan = PredictionPlan(arm_obj, live, anim)
    if plan.curves:
        fcurves = anim_compat.object_fcurves(anim)
        for c, values, i, k in plan.curves:
            values[i, k] = fcurves[c].evaluate(frame)
    return core_loader.core().pose_from_channels(live.character, plan.location, plan.modes, plan.rotation,
                                                 plan.scale)


def channel_pose(arm_obj, live):
    """#B by 4 by 4 skeleton pose by FK from the pose bones' channels as they are now (what Blender evaluates
    when nothing but the channels poses the skeleton), or None when the skeleton's channels are those of the
    last call (`live.channels`): five foreach_get, then the rotation modes and one core call. Which bones are
    connected (Blender ignores their location) is read once (`live.connected`; edited bones make the prediction
    differ from the evaluated pose, and the post handlers then drop it with the plan)."""
    pose_bones = arm_obj.pose.bones
    index = live.skeleton_indices(pose_bones)
    read = read_channels(pose_bones, index)
    raw = np.concatenate([read[prop].ravel() for prop, _w in CHANNEL_WIDTHS])
    if live.channels is not None and np.array_equal(raw, live.channels):
        return None
    live.channels = raw
    if live.connected is None:
        live.connected = np.array([pose_bones[int(k)].bone.use_connect for k in index])
    location, modes, rotation, scale = skeleton_channels(pose_bones, index, read, live.connected)
    return core_loader.core().pose_from_channels(live.character, location, [ROTATION_MODES[m] for m in modes],
                                                 rotation, scale)


def pose_armature(arm_obj):
    """depsgraph_update_pre: write the joints for the pose the skeleton's channels give (hand posing, a script
    setting channels), so the evaluation that follows skins once. Only for a skeleton the channels alone pose
    (no constraints, drivers or NLA) and the joints deformer (not the anchored one), and only when its channels
    changed since the last call and the joints were not written for that pose already. Returns True when it
    wrote."""
    live = live_rig(arm_obj)
    if live.anchored:  # its offsets written here were not those Blender evaluated (0.13 mm off): post writes them
        return False
    if live.predictable is None:
        live.predictable = _predictable(arm_obj, live)
        live.plan = None
    if not live.predictable:
        return False
    pose = channel_pose(arm_obj, live)
    if pose is None:
        return False
    surfaces = muscles_visible(arm_obj)
    if up_to_date(live, pose, surfaces):
        return False
    write_pose(arm_obj, live, pose, surfaces)
    stats["posed"] += 1
    return True


def predict_armature(arm_obj, frame):
    """frame_change_pre: write the joints for the predicted pose (True when it could predict; nothing is
    written when the pose equals the one the joints were last written for)."""
    live = live_rig(arm_obj)
    pose = predicted_pose(arm_obj, live, frame)
    if pose is None:
        return False
    surfaces = muscles_visible(arm_obj)
    if not up_to_date(live, pose, surfaces):
        write_pose(arm_obj, live, pose, surfaces)
    stats["predicted"] += 1
    return True


# ------------------------------------------------------------------------------------------------
# Deferred skinning (skeletons the prediction cannot follow: IK, constraints, drivers, NLA)
# ------------------------------------------------------------------------------------------------

# Modifiers whose step keeps state from frame to frame (or feeds another object's): such a skin must be posed
# in every evaluation, so it is never deferred. A Geometry Nodes modifier other than the Core Skin may hold a
# simulation zone, so it counts too.
STATEFUL_MODIFIERS = frozenset({'CLOTH', 'SOFT_BODY', 'COLLISION', 'DYNAMIC_PAINT', 'PARTICLE_SYSTEM', 'FLUID',
                                'SURFACE', 'EXPLODE', 'NODES'})
# Simulations on other objects that may read the skin (a garment's cloth over a Surface Deform, particles, a
# Geometry Nodes simulation zone reading it through Object Info): while the scene has one, nothing is deferred.
SIMULATION_MODIFIERS = frozenset({'CLOTH', 'SOFT_BODY', 'DYNAMIC_PAINT', 'PARTICLE_SYSTEM', 'FLUID', 'EXPLODE'})
# Where switching the modifiers off for the first pass pays (bench_blender_playback's 2-pass case, 50k-vertex arm,
# ms per frame two passes -> deferred): 4.3 4.13 -> 2.96, 4.5 4.26 -> 3.03, 5.2 3.73 -> 2.73; on 3.4 it cost time
# (12.15 -> 16.03), so 3.x keeps skinning in both passes. 4.2 was not measured.
DEFER_SKINNING = bpy.app.version >= (4, 3, 0)


def _has_simulation_zone(tree, seen):
    """True when a node tree (or a group inside it) holds a Geometry Nodes simulation zone."""
    if tree is None or tree.as_pointer() in seen:
        return False
    seen.add(tree.as_pointer())
    for node in tree.nodes:
        if node.bl_idname == "GeometryNodeSimulationOutput":
            return True
        if getattr(node, "node_tree", None) is not None and _has_simulation_zone(node.node_tree, seen):
            return True
    return False


def scene_simulates(scene):
    """True when something in the scene steps a simulation from frame to frame (SIMULATION_MODIFIERS, a
    Geometry Nodes simulation zone, an enabled rigid body world): its step could read a skin."""
    world = scene.rigidbody_world
    if world is not None and world.enabled:
        return True
    seen = set()
    for obj in scene.objects:
        for mod in obj.modifiers:
            if mod.type in SIMULATION_MODIFIERS:
                return True
            if mod.type == 'NODES' and _has_simulation_zone(mod.node_group, seen):
                return True
    return False


def skinning_modifiers(arm_obj, live):
    """The enabled modifiers that skin a live rig's bound meshes (its Armature modifiers, the anchored deformer's
    Core Skin), or [] when one of those meshes carries simulation state (STATEFUL_MODIFIERS, a rigid body)."""
    found = []
    for name in live.skin_names:
        skin = bpy.data.objects.get(name)
        if skin is None or skin.type != 'MESH':
            continue
        if skin.rigid_body is not None:
            return []
        anim = skin.animation_data  # a modifier switch keyed or driven by the user is left alone
        if anim is not None and any(fc.data_path.startswith("modifiers[")
                                    for fc in list(anim_compat.object_fcurves(anim)) + list(anim.drivers)):
            return []
        core_mod = core_skin.modifier(skin)
        for mod in skin.modifiers:
            if mod.type in STATEFUL_MODIFIERS and mod != core_mod:
                return []
        found += [m for m in binding.armature_modifiers(skin, arm_obj) + [core_mod]
                  if m is not None and m.show_viewport]
    return found


def _rendering():
    is_job_running = getattr(bpy.app, "is_job_running", None)
    return bool(is_job_running and is_job_running('RENDER'))


def defer_skinning(arm_obj, live, simulating):
    """frame_change_pre of a skeleton that only its evaluation poses (no prediction): the joints are known only
    after this evaluation, so the first pass would skin with the last frame's joints and frame_change_post's
    joint update would skin again. Switch the skinning modifiers off for the first pass instead
    (runtime.deferred; restore_deferred switches them on in frame_change_post, and Blender's second pass skins
    once, with the right joints). Not while the scene simulates (`simulating`, scene_simulates), not during a
    render (its depsgraph skins with show_render: the switch would only add a pass), and not after a frame in
    which the skeleton did not move (`live.still`: the skin needed no evaluation then, a switch would force one)."""
    if not DEFER_SKINNING or simulating or live.still or _rendering():
        return
    modifiers = skinning_modifiers(arm_obj, live)
    for mod in modifiers:
        mod.show_viewport = False
        runtime.deferred.append((mod.id_data.name, mod.name))
    stats["deferred"] += bool(modifiers)


def restore_deferred():
    """Switch the modifiers defer_skinning switched off back on (the second pass then skins their meshes); one
    that cannot be switched on is reported, the others still are."""
    deferred, runtime.deferred = runtime.deferred, []
    for obj_name, mod_name in deferred:
        try:
            obj = bpy.data.objects.get(obj_name)
            mod = obj.modifiers.get(mod_name) if obj is not None else None
            if mod is not None:
                mod.show_viewport = True
        except Exception as e:  # noqa: BLE001  (a handler must never raise into Blender)
            print(f"Myoskin: could not switch '{mod_name}' of '{obj_name}' back on: {e}")


@persistent
def on_save_pre(*_args):
    """save_pre: never save a skin with its modifiers switched off for a first pass."""
    if runtime.deferred:
        restore_deferred()


def stop_live(arm_obj, error):
    """A handler failed: say why (runtime.report_error: the panels show it) and turn live update off through
    the property, so its update callback unmutes the baked joint keys and the baked Action plays (the ID
    property is the fallback)."""
    runtime.report_error(arm_obj, f"live update of '{arm_obj.name}' stopped: {error}")
    try:
        arm_obj.myoskin.live = False
    except Exception:  # noqa: BLE001
        arm_obj.myoskin["live"] = False


@persistent
def on_frame_change_pre(scene, depsgraph=None):
    """frame_change_pre: write the joints for the predicted pose; remember the bound armatures found
    (runtime.frame_armatures) for the frame_change_post of the same frame change."""
    runtime.frame_armatures = None
    if runtime.busy() or not core_loader.available():
        return
    armatures, baked = split_bound_armatures(scene)
    runtime.frame_armatures = (scene.as_pointer(), scene.frame_current_final, [a.name for a in armatures],
                               [a.name for a in baked])
    if not armatures:
        return
    with runtime.guard():
        restore_deferred()  # left over from a frame change whose frame_change_post did not run
        simulating = None
        for arm in armatures:
            try:
                predicted = predict_armature(arm, scene.frame_current_final)
            except Exception as e:  # noqa: BLE001  (a handler must never raise into Blender)
                stop_live(arm, e)
                continue
            if predicted:
                continue
            try:  # a failure here only costs the second skinning pass
                if simulating is None:
                    simulating = scene_simulates(scene)
                defer_skinning(arm, live_rig(arm), simulating)
            except Exception as e:  # noqa: BLE001
                restore_deferred()
                runtime.report_error(arm, f"'{arm.name}': skinning once per frame failed, skinning twice: {e}")


@persistent
def on_frame_change_post(scene, depsgraph=None):
    """frame_change_post: on_update for the armatures the frame_change_pre of this frame change found."""
    found, runtime.frame_armatures = runtime.frame_armatures, None
    if runtime.deferred:
        with runtime.guard():
            restore_deferred()
    if found is not None and found[0] == scene.as_pointer() and found[1] == scene.frame_current_final:
        objects = bpy.data.objects
        lists = tuple([o for o in (objects.get(n) for n in names) if o is not None] for names in found[2:])
        update_all(scene, depsgraph, *lists)
    else:
        on_update(scene, depsgraph)


@persistent
def on_update_pre(scene, depsgraph=None):
    """depsgraph_update_pre: write the joints for the skeleton's channels before Blender evaluates (pose_armature),
    so hand posing skins once; the post handler still checks the evaluated pose."""
    if runtime.busy() or not core_loader.available():
        return
    armatures, _baked = split_bound_armatures(scene)
    if not armatures:
        return
    with runtime.guard():
        for arm in armatures:
            try:
                pose_armature(arm)
            except Exception as e:  # noqa: BLE001  (a handler must never raise into Blender)
                stop_live(arm, e)


@persistent
def on_update(scene, depsgraph=None):
    """depsgraph_update_post (and frame_change_post): re-pose every bound armature whose skeleton moved."""
    if runtime.deferred and not runtime.busy():
        with runtime.guard():
            restore_deferred()
    if not runtime.busy() and core_loader.available():
        update_all(scene, depsgraph, *split_bound_armatures(scene))


def update_all(scene, depsgraph, armatures, baked):
    """The post handlers' work: live armatures re-posed from the evaluated skeleton when it moved other
    than predicted, baked ones get their muscle surfaces."""
    if runtime.busy() or not core_loader.available() or not (armatures or baked):
        return
    with runtime.guard():
        for arm in armatures:
            try:
                update_armature(arm, depsgraph)
            except Exception as e:  # noqa: BLE001  (a handler must never raise into Blender)
                stop_live(arm, e)
        for arm in baked:
            try:
                update_surfaces(arm, depsgraph)
            except Exception as e:  # noqa: BLE001
                runtime.report_error(arm, f"muscle surfaces of '{arm.name}' not updated: {e}")


def set_baked_muted(arm_obj, muted):
    """Mute (live on) or unmute (live off: the baked Action plays) the muscle joints' F-curves."""
    fcurves = anim_compat.object_fcurves(arm_obj.animation_data)
    if not fcurves:
        return 0
    prefixes = tuple(f'pose.bones["{n}"].' for n in rig_io.muscle_bone_names(arm_obj))
    count = 0
    for fc in fcurves:
        if fc.data_path.startswith(prefixes):
            fc.mute = muted
            count += 1
    return count


def on_live_changed(arm_obj, state):
    """The Live Update property changed (dispatched from state.py): mute or unmute the baked joint keys; a
    bound rig turned live again rebuilds its cached rig."""
    set_baked_muted(arm_obj, state.live)
    if state.live and state.bound:
        runtime.forget(arm_obj.name)


@persistent
def on_reload(*_args):
    """load_post / undo_post / redo_post: the data were replaced, so cached rigs and poses are stale (and the
    modifiers a first pass switched off, if any, belong to data that are gone)."""
    runtime.forget()
    runtime.deferred = []
    rig_io.forget_structures()


@persistent
def on_load(*_args):
    """load_post: another file, so the errors reported for the armatures of the last one are gone too. A rig
    bound before Preserve Volume became the default (the setting never stored) keeps the mode its Armature
    modifiers were bound with. A volume blend's share group written by a Blender that reads it the other way (3.x /
    4.x and later) is rewritten for this one."""
    runtime.clear_error()
    for obj in bpy.data.objects:
        try:
            if obj.type != 'ARMATURE' or obj.library is not None:
                continue
            state = obj.myoskin
            if not state.bound:
                continue
            skins = binding.bound_skins(obj)
            for skin in skins:
                if skin.library is None:
                    binding.ensure_share_convention(skin)
            if state.is_property_set("preserve_volume"):
                continue
            if skins:
                state.preserve_volume = binding.preserve_volume_of(skins[0], obj)
        except Exception as e:  # a damaged rig must not stop the file from loading
            print(f"myoskin: {obj.name}: {e}")


def _handlers():
    h = bpy.app.handlers
    return ((h.frame_change_pre, on_frame_change_pre), (h.frame_change_post, on_frame_change_post),
            (h.depsgraph_update_pre, on_update_pre), (h.depsgraph_update_post, on_update),
            (h.load_post, on_reload), (h.load_post, on_load),
            (h.undo_post, on_reload), (h.redo_post, on_reload), (h.save_pre, on_save_pre))


def register():
    for handlers, fn in _handlers():
        if fn not in handlers:
            handlers.append(fn)


def unregister():
    for handlers, fn in _handlers():
        if fn in handlers:
            handlers.remove(fn)
    restore_deferred()
    runtime.forget()
