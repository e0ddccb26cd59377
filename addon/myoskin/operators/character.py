# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators that create or inspect characters. Small: convert data, call the core, report."""
import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty

from .. import blender_io, core_loader


def character_summary(character):
    """Counts and topology of a core Character as a dict (what character_info reports)."""
    topology = character.topology()
    return {
        "name": character.name,
        "vertices": int(character.num_vertices),
        "triangles": int(character.num_triangles),
        "bones": int(character.num_bones),
        "influences": int(character.weight_joints.shape[1]) if character.has_weights else 0,
        "volume": float(character.volume()),
        **{k: (bool(v) if isinstance(v, bool) else int(v)) for k, v in topology.items()},
    }


def format_summary(s):
    shape = "closed" if s["closed"] else f"open ({s['boundary_edges']} boundary edges)"
    manifold = "manifold" if s["manifold"] else f"non-manifold ({s['non_manifold_edges']} edges)"
    return (f"{s['name']}: {s['vertices']:,} vertices, {s['triangles']:,} triangles, {s['bones']} bones, "
            f"up to {s['influences']} influences; {shape}, {manifold}, {s['components']} component(s), "
            f"volume {s['volume'] * 1000:.3f} L")


class MYOSKIN_OT_add_synthetic_arm(bpy.types.Operator):
    """Add the procedural muscular right arm (armature, skin, vertex groups, Armature modifier)"""
    bl_idname = "myoskin.add_synthetic_arm"
    bl_label = "Add Synthetic Arm"
    bl_options = {'REGISTER', 'UNDO'}

    seed: IntProperty(name="Seed", description="Varies muscle sizes and placement (0 = the canonical arm)",
                      default=1, min=0)
    muscle_scale: FloatProperty(name="Muscle Scale", description="Size of the muscle bellies (0 = smooth arm)",
                                default=1.0, min=0.0, soft_max=3.0)
    rings_per_metre: IntProperty(name="Rings per Metre", description="Skin resolution along the arm (400: 2.5 mm "
                                 "rings, about 33,000 vertices with the default resolution around)",
                                 default=400, min=20, soft_max=1000)
    segments_around: IntProperty(name="Segments Around", description="Skin resolution around the arm",
                                 default=96, min=8, soft_max=256)
    show_truth: BoolProperty(name="Show True Muscles",
                             description="Also add the known muscles as tubes parented to their bones",
                             default=False)

    def execute(self, context):
        wm = context.window_manager
        wm.progress_begin(0, 3)
        try:
            core = core_loader.core()
            character, truth = core.make_synthetic_arm(seed=self.seed, muscle_scale=self.muscle_scale,
                                                       rings_per_metre=self.rings_per_metre,
                                                       segments_around=self.segments_around)
            wm.progress_update(1)
            collection = context.collection or context.scene.collection
            arm_obj, mesh_obj = blender_io.character_to_blender(character, "SyntheticArm", collection)
            wm.progress_update(2)
            if self.show_truth:
                blender_io.truth_to_curves(truth, collection, armature_obj=arm_obj)
            for obj in context.selected_objects:
                obj.select_set(False)
            arm_obj.select_set(True)
            mesh_obj.select_set(True)
            context.view_layer.objects.active = mesh_obj
            wm.progress_update(3)
        except Exception as e:  # noqa: BLE001  (operators report, never raise)
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        self.report({'INFO'}, f"Added {mesh_obj.name}: {character.num_vertices:,} vertices, "
                              f"{character.num_bones} bones, {len(truth)} true muscles")
        return {'FINISHED'}


class MYOSKIN_OT_character_info(bpy.types.Operator):
    """Report counts and topology of the active skinned mesh, or with the armature active of the whole
    character (every mesh it deforms, welded), through the core"""
    bl_idname = "myoskin.character_info"
    bl_label = "Character Info"
    bl_options = {'REGISTER'}

    def execute(self, context):
        try:
            obj = context.active_object
            if obj is not None and obj.type == 'ARMATURE':  # the whole character, its meshes welded
                meshes, arm_obj, skipped = blender_io.resolve_character(obj)
                character = blender_io.combined_character(meshes, arm_obj).character
                extra = (f" [{len(meshes)} mesh(es): {', '.join(o.name for o in meshes)}]"
                         + blender_io.skipped_message(skipped))
            else:
                mesh_obj, arm_obj = blender_io.resolve_skinned_mesh(obj)
                character = blender_io.character_from_blender(mesh_obj, arm_obj)
                extra = ""
            summary = character_summary(character)
        except Exception as e:  # noqa: BLE001
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        self.report({'INFO'}, format_summary(summary) + extra)
        return {'FINISHED'}


classes = (MYOSKIN_OT_add_synthetic_arm, MYOSKIN_OT_character_info)
