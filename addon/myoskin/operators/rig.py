# SPDX-License-Identifier: GPL-3.0-or-later
"""Rig operators: Bind / Unbind the muscles to the character's armature, Bake the muscle joints to an Action,
export glTF with the helper bones, bake the skin to a PC2 cache through the core.
Small: call the rig service (binding), convert data (blender_io, rig_io), call the core, report."""
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty, StringProperty

from .. import (binding, blender_io, core_loader, core_skin, correctives, dynamics, gltf_io, live, muscle_io,
               rig_io, runtime)
from .muscles import _MuscleOperator, resolve_extracted, resolve_rig
from ..state import rig_state


class MYOSKIN_OT_bind(_MuscleOperator, bpy.types.Operator):
    """Bind the enabled muscles: muscle joints become deform bones of the armature (own bone layer),
    their weights vertex groups blended with the skeleton's (binds again when already bound)"""
    bl_idname = "myoskin.bind"
    bl_label = "Bind"

    def run(self, context):
        skins, arm, state = resolve_extracted(context)
        if state.bound:  # the muscles must be usable before the current bind is taken down
            muscles = muscle_io.state_to_core(arm)
            if not muscles:
                raise ValueError(f"Every muscle of '{arm.name}' is disabled: enable at least one to bind")
            core = core_loader.core()
            muscles = [core.reattach_muscle(m) for m in muscles]
            try:  # the bound skeleton, from the bind record (a damaged record is rewritten by the new bind)
                skeleton = live.live_rig(arm).character
            except Exception:
                skeleton = None
            if skeleton is not None:
                # the rig's own checks (ends, wraps, joints)
                core.MuscleRig(skeleton, muscles, joints_slide=bool(state.joints_slide))
            for skin in binding.bound_skins(arm):
                binding.check_backup(skin)
            if state.deformer == 'ANCHORED':
                core_skin.stuffing_of(arm)  # the artist's stuffing Empties are usable
        wm = context.window_manager
        wm.progress_begin(0, 2)
        try:
            if state.bound:
                binding.unbind(arm)
            wm.progress_update(1)
            joints = binding.bind(context, skins, arm)
            live.update_armature(arm, force=True)
            runtime.clear_error(arm)
        finally:
            wm.progress_end()
        return (f"Bound {sum(1 for m in state.muscles if m.enabled)} muscles ({joints} joints) to {arm.name}"
                + (f" and its {len(skins)} meshes ({', '.join(o.name for o in skins)})" if len(skins) > 1 else ""))


class MYOSKIN_OT_unbind(_MuscleOperator, bpy.types.Operator):
    """Remove the muscle joints and restore the skin's original weights exactly"""
    bl_idname = "myoskin.unbind"
    bl_label = "Unbind"

    def run(self, context):
        _skins, arm = resolve_rig(context.active_object)
        if not rig_state(arm).bound:
            raise ValueError(f"'{arm.name}' is not bound")
        skins = binding.bound_skins(arm)
        problem = binding.unbind(arm)
        runtime.clear_error(arm)
        message = f"Unbound {arm.name}: original weights of {', '.join(o.name for o in skins)} restored"
        if problem:  # the weights came back from each mesh's backup; Armature modifiers Bind added may remain
            return 'WARNING', f"{message}; {problem}: check the meshes' Armature modifiers"
        return message


class MYOSKIN_OT_add_stuffing(_MuscleOperator, bpy.types.Operator):
    """Add a stuffing ellipsoid for the Anchored Skin deformer: an Empty on the bone (move, turn and scale it;
    Bind again to use it)"""
    bl_idname = "myoskin.add_stuffing"
    bl_label = "Add Stuffing"

    bone: StringProperty(name="Bone", description="The bone that carries it (default: the active bone)")

    def run(self, context):
        _skins, arm = resolve_rig(context.active_object)
        name = self.bone or (arm.data.bones.active.name if arm.data.bones.active else "")
        if not name:
            raise ValueError(f"Give a bone of '{arm.name}' (or make one active)")
        empty = core_skin.add_stuffing(context, arm, name)
        return f"Added stuffing '{empty.name}' on '{name}': shape it, then Bind with the Anchored Skin deformer"


class MYOSKIN_OT_clear_error(bpy.types.Operator):
    """Dismiss the error a handler or property callback reported for this armature (shown in the panels)"""
    bl_idname = "myoskin.clear_error"
    bl_label = "Dismiss Error"
    bl_options = {'REGISTER', 'INTERNAL'}

    armature: StringProperty(name="Armature", description="The armature whose error to dismiss (empty: all)")

    def execute(self, context):
        runtime.clear_error(self.armature or None)
        return {'FINISHED'}


def require_bound(context):
    _skins, arm, state = resolve_extracted(context)
    if not state.bound:
        raise ValueError(f"'{arm.name}' is not bound: Bind first")
    return binding.bound_skins(arm), arm, state


class MYOSKIN_OT_bake_action(_MuscleOperator, bpy.types.Operator):
    """Key the muscle joints' pose on every frame of a range into the armature's Action (plays without the
    add-on, exports to glTF)"""
    bl_idname = "myoskin.bake_action"
    bl_label = "Bake Muscle Action"

    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=120)
    jiggle: BoolProperty(name="Jiggle", default=False,
                         description="Simulate the muscles' jiggle from the start frame (the rig's Jiggle settings)")
    jiggle_start: IntProperty(name="Simulation Start", default=-1000000,
                              description="Jiggle: the frame the simulation starts from at rest (below Start: a farm "
                                          "chunk of a longer bake, keyed from Start but simulated from here, so "
                                          "chunks agree with one bake; default: Start)")
    state_in: StringProperty(name="State In", subtype='FILE_PATH', default="",
                             description="Jiggle, a farm chunk: the simulation state file the chunk before wrote "
                                         "(State Out; Bake PC2's works too), so the jiggle continues from it instead "
                                         "of replaying the frames before Start")
    state_out: StringProperty(name="State Out", subtype='FILE_PATH', default="",
                              description="Jiggle: write the simulation state of frame End - 1 for the next chunk's "
                                          "State In (the format Bake PC2 writes)")

    def run(self, context):
        _skins, arm, state = require_bound(context)
        if self.frame_end < self.frame_start:
            raise ValueError(f"Frame range {self.frame_start}-{self.frame_end} is empty")
        scene = context.scene
        names = binding.read_bind_record(arm)["joint_names"]
        missing = [n for n in names if n not in arm.pose.bones]
        if missing:
            raise ValueError(f"Muscle bone '{missing[0]}' is missing (deleted or renamed?): bind again")
        live.live_rig(arm).skeleton_indices(arm.pose.bones)  # ValueError naming a renamed skeleton bone
        if arm.animation_data is None:
            arm.animation_data_create()
        if arm.animation_data.action is None:
            arm.animation_data.action = bpy.data.actions.new(f"{arm.name}Action")
        state.live = True  # mutes the joints' earlier baked keys, so they cannot override the live values
        wm = context.window_manager
        wm.progress_begin(self.frame_start, self.frame_end)
        current = scene.frame_current
        rig = live.live_rig(arm)
        try:
            sim_start = self.frame_start if self.jiggle_start == -1000000 else self.jiggle_start
            state_in = bpy.path.abspath(self.state_in) if self.state_in else ""
            state_out = bpy.path.abspath(self.state_out) if self.state_out else ""
            if (state_in or state_out) and not self.jiggle:
                raise ValueError("State In / State Out carry the jiggle's state: turn Jiggle on")
            sampled_from = None
            if state_in:
                state_frame, state_start = dynamics.state_file_frames(state_in)
                if self.jiggle_start == -1000000:
                    sim_start = state_start
                if state_frame > self.frame_start:
                    raise ValueError(f"The simulation state {state_in} is of frame {state_frame}, after Start "
                                     f"{self.frame_start}: give the state the chunk before this one wrote")
                sampled_from = max(sim_start, state_frame)
            if state_out:
                dynamics.check_state_target(state_out)
            if sim_start > self.frame_start:
                raise ValueError(f"Simulation Start {sim_start} is after Start {self.frame_start}")
            track = jiggle_track(context, arm, rig, sim_start, self.frame_end, sampled_from) if self.jiggle else None
            if state_in:  # the frames before the state are never evaluated: the state carries them
                track[0].restore_state(state_in)
            for frame in range(self.frame_start, self.frame_end + 1):
                k = frame - sim_start
                scene.frame_set(frame)
                if track is None:
                    live.update_armature(arm, context.evaluated_depsgraph_get(), force=True)
                else:  # the jiggled joints, posed against the skeleton pose the track was sampled with
                    rig_io.write_joint_matrices(arm, rig.joint_names, track[0].joint_matrices(frame),
                                                parent_matrices=(rig.bone_names, track[1][k]))
                for n in names:
                    pb = arm.pose.bones[n]
                    pb.rotation_mode = 'QUATERNION'
                    for path in ("location", "rotation_quaternion", "scale"):
                        pb.keyframe_insert(path, frame=frame, group=n)
                wm.progress_update(frame)
            if state_out:
                track[0].write_state(state_out, max(sim_start, self.frame_end - 1))
        finally:
            wm.progress_end()
        state.live = False  # the baked Action plays now (also without the add-on); Live Update mutes it again
        scene.frame_set(current)
        return (f"Baked {len(names)} muscle joints{' with jiggle' if self.jiggle else ''} over frames "
                f"{self.frame_start}-{self.frame_end} (live update off: the Action plays; turn it on after editing "
                f"the animation)")


def jiggle_params(state, rig, track):
    """#M by 3 (mass, stiffness, damping) of the rig's muscles: the track's defaults (by muscle size) with each
    muscle's own Jiggle Frequency / Damping where set; None when no muscle overrides them."""
    items = {m.name: m for m in state.muscles}
    params = np.array(track.params, dtype=np.float64)
    changed = False
    for i, muscle in enumerate(rig.rig.muscles):
        item = items.get(muscle.name)
        if item is None:
            continue
        mass, stiffness, damping = params[i]
        ratio = damping / (2.0 * np.sqrt(stiffness * mass))
        if item.jiggle_frequency > 0.0:
            stiffness, changed = mass * (2.0 * np.pi * item.jiggle_frequency) ** 2, True
        if item.jiggle_damping >= 0.0:
            ratio, changed = item.jiggle_damping, True
        params[i] = (mass, stiffness, 2.0 * ratio * np.sqrt(stiffness * mass))
    return params if changed else None


JIGGLE_GROUP = dynamics.JIGGLE_GROUP  # a vertex group painted on a skin: where its muscles may jiggle (0..1)


def jiggle_influence(skins, rig, default):
    """#J influences of the muscle joints: the default (fading toward the tendons) times, when a skin has the
    vertex group JIGGLE_GROUP, the group's mean over the skin each joint moves (weighted by the joint's
    weight; a vertex outside the group counts 0). None when no skin has the group."""
    names = rig.bone_names + rig.joint_names
    painted = [s for s in skins if JIGGLE_GROUP in s.vertex_groups]
    if not painted:
        return None
    num_bones = len(rig.bone_names)
    total = np.zeros(len(rig.joint_names))
    hit = np.zeros(len(rig.joint_names))
    for skin in painted:
        joints, weights = rig_io.read_combined_weights(skin, names)
        group = blender_io.vertex_group_weights(skin, JIGGLE_GROUP)  # #V, 0 outside the group
        mask = joints >= num_bones
        j = joints[mask] - num_bones
        w = weights[mask]
        g = np.broadcast_to(group[:, None], joints.shape)[mask]
        np.add.at(total, j, w)
        np.add.at(hit, j, w * g)
    scale = np.divide(hit, total, out=np.ones_like(total), where=total > 0)
    return np.asarray(default, dtype=np.float64) * scale


def jiggle_settings(context, arm, rig, skins, poses, per_vertex=False):
    """The rig's jiggle settings as JiggleTrack / simulate keywords: frequency, damping ratio, amount, the
    per-muscle overrides (params) and the joints' influence: the default (fading toward the tendons), scaled by
    the painted JIGGLE_GROUP per joint for the Action (per_vertex False), or the default alone when the group is
    applied per vertex (the PC2 route: dynamics.vertex_influence)."""
    state = rig_state(arm)
    settings = dict(frequency=state.jiggle_frequency, damping_ratio=state.jiggle_damping, amount=state.jiggle_amount)
    scene = context.scene
    defaults = core_loader.core().JiggleTrack(rig.character, rig.rig, poses[:1], scene.render.fps / scene.render.fps_base,
                                              1.0, **settings)
    settings["params"] = jiggle_params(state, rig, defaults)
    settings["influence"] = None if per_vertex else jiggle_influence(skins, rig, defaults.influence)
    return settings


def sampled_poses(context, arm, rig, start, end):
    """#F by #B by 4 by 4: the evaluated skeleton (IK and constraints included) of every frame start..end."""
    return sampled_frames(context, arm, rig, start, end)[0]


def sampled_frames(context, arm, rig, start, end, keyed=(), mixes=None):
    """(#F by #B by 4 by 4 evaluated skeleton poses of frames start..end, {mesh name: #F lists of the shape key
    values Blender uses on that frame} for the meshes `keyed` with their dynamics.ShapeKeyMix in `mixes`)."""
    poses, values = [], {s.name: [] for s in keyed}
    for frame in range(start, end + 1):
        context.scene.frame_set(frame)
        depsgraph = context.evaluated_depsgraph_get()
        poses.append(live.evaluated_pose(arm, rig, depsgraph))
        for skin in keyed:
            values[skin.name].append(mixes[skin.name].values(skin, depsgraph))
    return np.ascontiguousarray(poses, dtype=np.float64), values


def jiggle_track(context, arm, rig, start, end, sampled_from=None):
    """(core JiggleTrack over frames start..end, #F by #B by 4 by 4 skeleton poses it was sampled from) at the
    scene's frame rate with the rig's Jiggle settings. Deterministic: the same frames give the same track, so
    separate bakes of a range agree. sampled_from: a chunk that restores a state of that frame samples the
    skeleton from there on only (the first sampled pose stands in for the frames before, never evaluated)."""
    scene = context.scene
    sampled_from = start if sampled_from is None else max(start, sampled_from)
    poses = sampled_poses(context, arm, rig, sampled_from, end)
    poses = np.ascontiguousarray(np.concatenate([np.repeat(poses[:1], sampled_from - start, axis=0), poses]))
    settings = jiggle_settings(context, arm, rig, binding.bound_skins(arm), poses)
    track = core_loader.core().JiggleTrack(rig.character, rig.rig, poses, scene.render.fps / scene.render.fps_base,
                                           float(start), **settings)
    return track, poses


class MYOSKIN_OT_export_gltf(_MuscleOperator, bpy.types.Operator):
    """Export the skin and its armature, muscle-joint helper bones included, to glTF (with the Actions)"""
    bl_idname = "myoskin.export_gltf"
    bl_label = "Export glTF"
    bl_options = {'REGISTER'}
    edits_character = False

    filepath: StringProperty(name="File", subtype='FILE_PATH', default="//character.glb")

    def run(self, context):
        skins, arm = resolve_rig(context.active_object)
        path = bpy.path.abspath(self.filepath)
        if not path or path.endswith(os.sep):
            raise ValueError("Give a file name for the glTF export")
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        for obj in context.view_layer.objects:
            obj.select_set(obj == arm or obj in skins)
        with correctives.weights_baked_for_export(context, skins, arm):  # morph weights animation in every exporter
            gltf_io.export_gltf(path)
        return (f"Exported {', '.join(o.name for o in skins)} + {arm.name} ({len(arm.data.bones)} bones) "
                f"to {path}")


def pc2_paths(path, skins):
    """The PC2 file of each mesh: `path` itself for one mesh; for several, one file per mesh beside it,
    named <path without .pc2>_<mesh name>.pc2 (the name made file-safe)."""
    if len(skins) == 1:
        return [path]
    root, ext = os.path.splitext(path)
    return [f"{root}_{bpy.path.clean_name(o.name)}{ext or '.pc2'}" for o in skins]


class MYOSKIN_OT_bake_pc2(_MuscleOperator, bpy.types.Operator):
    """Bake the skin over a frame range to a PC2 point cache computed by the core (Equation 3 with the
    muscle joints, or dual quaternions where the Armature modifier preserves volume), for a Mesh Cache modifier or other tools; a character of several meshes gets one file
    per mesh, <file>_<mesh>.pc2"""
    bl_idname = "myoskin.bake_pc2"
    bl_label = "Bake PC2"
    bl_options = {'REGISTER'}
    edits_character = False

    filepath: StringProperty(name="File", subtype='FILE_PATH', default="//skin.pc2")
    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=120)
    add_modifier: BoolProperty(name="Add Mesh Cache Modifier", default=False)
    skin_solve: BoolProperty(name="Skin Solve", default=False,
                             description="Per frame, relax the skinned skin with edge springs toward a per-vertex goal "
                                         "and push it out of the posed muscles, so it slides over them (Gray & "
                                         "Hutchinson; muscle-joint skins only)")
    jiggle: BoolProperty(name="Jiggle", default=False,
                         description="Simulate the muscles' jiggle from the first frame (the rig's Jiggle settings, as "
                                     "Bake Muscle Action keys it)")
    temporal_filter: BoolProperty(name="Temporal Filter", default=False,
                                  description="With Skin Solve: pull back what the solve adds where it jitters from "
                                              "frame to frame (each vertex against the line through its neighbouring "
                                              "frames; smooth motion passes unchanged)")
    simulation_start: IntProperty(name="Simulation Start", default=-1000000,
                                  description="Jiggle: the frame the simulation starts from at rest (below Start: a "
                                              "farm chunk of a longer bake; default: Start)")
    state_in: StringProperty(name="State In", subtype='FILE_PATH', default="",
                             description="A farm chunk: the simulation state file the chunk before this one wrote "
                                         "(State Out), so the jiggle continues from it instead of replaying")
    state_out: StringProperty(name="State Out", subtype='FILE_PATH', default="",
                              description="Write the simulation state at the end of this bake, for the next chunk's "
                                          "State In (the chunks then stitch bit for bit to one bake)")
    mute_armature: BoolProperty(name="Mute Armature Modifier", default=True,
                                description="With Add Mesh Cache Modifier: switch the mesh's Armature modifier off "
                                            "(the cache replaces its result, so it would only cost time); Unbind "
                                            "switches it back on and removes the cache modifiers")

    def run(self, context):
        skins, arm, state = require_bound(context)
        if self.frame_end < self.frame_start:
            raise ValueError(f"Frame range {self.frame_start}-{self.frame_end} is empty")
        path = bpy.path.abspath(self.filepath)
        paths = pc2_paths(path, skins)
        state_in = bpy.path.abspath(self.state_in) if self.state_in else ""
        state_out = bpy.path.abspath(self.state_out) if self.state_out else ""
        if state_out:
            dynamics.check_state_target(state_out)
        sim_start = None if self.simulation_start == -1000000 else self.simulation_start
        if sim_start is None and state_in:  # a chunk: the simulation the state file belongs to
            sim_start = dynamics.state_file_frames(state_in)[1]
        frames = bake_skin_frames(context, skins, arm, self.frame_start, self.frame_end, self.skin_solve,
                                  self.jiggle, self.temporal_filter, sim_start=sim_start, state_in=state_in,
                                  state_out=state_out)
        os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
        for skin, mesh_path, mesh_frames in zip(skins, paths, frames):
            core_loader.core().write_pc2(mesh_path, mesh_frames, float(self.frame_start), 1.0)
            if self.add_modifier:
                mod = skin.modifiers.new(binding.PC2_MODIFIER, 'MESH_CACHE')
                mod.cache_format, mod.filepath = 'PC2', mesh_path
                # Frame time mode reads sample (scene frame - frame_start): sample 0 is frame_start
                mod.time_mode, mod.play_mode, mod.frame_start = 'FRAME', 'SCENE', float(self.frame_start)
                if self.mute_armature:
                    binding.mute_armature_for_cache(skin, arm)
        count = self.frame_end - self.frame_start + 1
        if len(skins) == 1:
            return f"Baked {count} frames of {skins[0].name} to {path}"
        return f"Baked {count} frames of {len(skins)} meshes to " + ", ".join(paths)


def bake_skin_frames(context, skins, arm, start, end, skin_solve=False, jiggle=False, temporal_filter=False,
                     sim_start=None, state_in="", state_out="", sculpt=True):
    """Per mesh of `skins`, #frames by #V by 3 float32 skin positions (mesh object space) of frames start..end
    computed by the core: the anchored skin, or Equation 3 (the skinner in the mode Blender skins the mesh with)
    on the mesh's shape key mix of each frame (correctives included, as Blender evaluates it), through the core's
    simulation when any of jiggle (the rig's Jiggle settings; the painted JIGGLE_GROUP scales it per vertex),
    skin_solve (the skin solved against the posed muscles), temporal_filter, stored sculpt deltas (`sculpt`) or a
    state file is on. sim_start: the frame the simulation starts from (default: start; a farm chunk of a longer
    bake starts later); state_in: the state file a chunk ending before `start` wrote (the jiggle continues from
    it, frames before it are not sampled); state_out: where to write the state for the next chunk. The skeleton
    is sampled once per frame for all meshes."""
    core = core_loader.core()
    rig = live.live_rig(arm)
    names = rig.bone_names + rig.joint_names
    anchored = {name: (frame, deformer) for name, frame, deformer in rig.anchored}
    scene = context.scene
    sim_start = start if sim_start is None else sim_start
    if sim_start > start:
        raise ValueError(f"Simulation Start {sim_start} is after Start {start}")
    sampled_from = sim_start  # without a state a chunk replays from the simulation's start
    if state_in:
        state_frame, state_start = dynamics.state_file_frames(state_in)
        if state_start != sim_start:
            raise ValueError(f"The simulation state {state_in} is of a simulation from frame {state_start}, this bake "
                             f"simulates from frame {sim_start}: give the same Simulation Start")
        sampled_from = max(sim_start, min(start, state_frame))  # the core checks it is early enough for the chunk
    meshes = [s for s in skins if s.name not in anchored]
    mixes = {s.name: dynamics.ShapeKeyMix(s) for s in meshes}
    keyed = [s for s in meshes if mixes[s.name].names]
    # The temporal filter of the last two frames sees the two frames after the range (as in a longer bake), so a
    # chunk's frames do not depend on where the chunk ends.
    sample_end = end + 2 if temporal_filter and skin_solve else end
    current = scene.frame_current
    try:
        sampled, values = sampled_frames(context, arm, rig, sampled_from, sample_end, keyed, mixes)
    finally:
        scene.frame_set(current)
    # Frames before the restored state are never evaluated by the core: the first sampled pose stands in for them.
    poses = np.concatenate([np.repeat(sampled[:1], sampled_from - sim_start, axis=0), sampled])
    first = start - sim_start  # index of `start` in poses
    settings = jiggle_settings(context, arm, rig, skins, poses, per_vertex=True) if jiggle else {}
    rest_bones_inv = np.linalg.inv(np.asarray(rig.character.bone_rest))
    bind_inv = np.linalg.inv(np.asarray(rig.rig.bind_matrices))
    out = []
    for skin in skins:
        deltas = dynamics.stored_sculpt(skin) if sculpt else None
        if skin.name in anchored:  # the anchored deformer: the core's AnchoredSkin of this mesh, per pose
            frame, deformer = anchored[skin.name]
            posed = np.array([deformer.evaluate(pose) for pose in poses[first:]])
            if deltas is not None:
                posed = np.array([deltas.apply(p) for p in posed])
            to_mesh = frame.to_mesh
        else:
            joints, weights = rig_io.read_combined_weights(skin, names)
            to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
            to_mesh = np.linalg.inv(to_arm)
            rest = blender_io.mesh_vertices(skin.data) @ to_arm[:3, :3].T + to_arm[:3, 3]
            # The mode Blender skins this mesh with (its Armature modifier's Preserve Volume), so the PC2 equals
            # Blender's skin; the transforms and rest matrices are in armature space, as the modifier's.
            skinner = binding.skinner_for(skin, arm, rig, rest, joints, weights)
            offsets = None
            if skin in keyed:  # the shape key mix of each frame, armature space (zeros: none that frame)
                offsets = np.zeros((len(poses), len(rest), 3), dtype=np.float32)
                mix = mixes[skin.name]
                for k, frame_values in enumerate(values[skin.name]):
                    d = mix.offsets(frame_values)
                    if d is not None:
                        offsets[sampled_from - sim_start + k] = d @ to_arm[:3, :3].T
            influence = dynamics.vertex_influence(skin) if jiggle else None
            simulated = (jiggle or skin_solve or temporal_filter or state_in or state_out or deltas is not None
                         or offsets is not None)
            if simulated:
                goal_weights = core.default_goal_weights(joints, weights, len(rig.bone_names)) if skin_solve else None
                posed = core.simulate(
                    blender_io.character_from_blender(skin, arm), skinner, poses, rig.rig,
                    scene.render.fps / scene.render.fps_base, sim_start, jiggle=jiggle, filter=temporal_filter,
                    skin_solve=goal_weights, jiggle_frequency=settings.get("frequency", 5.0),
                    jiggle_damping=settings.get("damping_ratio", 0.3), jiggle_amount=settings.get("amount", 1.0),
                    jiggle_params=settings.get("params"), jiggle_influence=settings.get("influence"),
                    jiggle_vertex_influence=influence, shape_offsets=offsets, sculpt_deltas=deltas,
                    frames=(start, end), state_in=state_in or None, state_out=state_out or None)
            else:
                posed = np.empty((end - start + 1, len(rest), 3), dtype=np.float32)
                for k, pose in enumerate(poses[first:]):
                    joint_matrices = rig.rig.evaluate(pose)["joint_matrices"]
                    posed[k] = skinner.deform(np.concatenate([pose @ rest_bones_inv, joint_matrices @ bind_inv]))
        posed = np.asarray(posed, dtype=np.float64)
        out.append((posed @ to_mesh[:3, :3].T + to_mesh[:3, 3]).astype(np.float32))
    return out


classes = (MYOSKIN_OT_bind, MYOSKIN_OT_unbind, MYOSKIN_OT_add_stuffing, MYOSKIN_OT_bake_action, MYOSKIN_OT_export_gltf,
           MYOSKIN_OT_bake_pc2, MYOSKIN_OT_clear_error)
