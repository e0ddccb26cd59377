# SPDX-License-Identifier: GPL-3.0-or-later
"""Corrective operators: Add Corrective (the sculpt at the current pose, from a shape key or a sculpted copy,
becomes a driven shape key in rest space) and Remove Corrective. Small: resolve the skin and the armature,
call the corrective service, report."""
import math

import bpy
from bpy.props import FloatProperty, StringProperty

from .. import blender_io, correctives, live
from .muscles import _MuscleOperator


def resolve_skin(context, skin_name=""):
    """(skin mesh, its armature): the named mesh, else the active mesh, else the active armature's one skin."""
    obj = bpy.data.objects.get(skin_name) if skin_name else context.active_object
    if skin_name and obj is None:
        raise ValueError(f"There is no object '{skin_name}'")
    if obj is None:
        raise ValueError("Select the skinned mesh to add a corrective to")
    if obj.type == 'ARMATURE':
        skins = blender_io.find_skin_meshes(obj)
        if len(skins) != 1:
            raise ValueError(f"Armature '{obj.name}' deforms {len(skins)} meshes: select the one to correct")
        return skins[0], obj
    if obj.type != 'MESH':
        raise ValueError(f"'{obj.name}' is not a mesh: select the skinned mesh")
    arm = blender_io.find_armature(obj)
    if arm is None:
        raise ValueError(f"'{obj.name}' has no armature: correctives fix a skinned mesh at a pose")
    return obj, arm


def pose_muscle_joints(arm):
    """A bound rig's muscle joints follow the current skeleton pose before the skin is read."""
    if arm.myoskin.bound and arm.myoskin.live:
        live.update_armature(arm, force=True)


class MYOSKIN_OT_add_corrective(_MuscleOperator, bpy.types.Operator):
    """Store the fix sculpted at the current pose as a shape key in rest space, driven by the bone's direction
    (native drivers: plays without the add-on), so the skin takes exactly the sculpted shape at this pose"""
    bl_idname = "myoskin.add_corrective"
    bl_label = "Add Corrective"

    bone: StringProperty(name="Bone", description="The bone whose direction drives the corrective")
    name: StringProperty(name="Name", description="The corrective's shape key (empty: the source key's name, or "
                         "corrective_<bone>)")
    source_key: StringProperty(name="Sculpt Shape Key", description="The skin's shape key holding the sculpt "
                               "(sculpted in Sculpt Mode on the posed skin)")
    source_object: StringProperty(name="Sculpt Object", description="Or a sculpted copy of the posed skin (same "
                                  "vertices), in place of the shape key")
    skin: StringProperty(name="Skin", description="The skinned mesh (empty: the active object)")
    falloff: FloatProperty(name="Falloff", description="The corrective fades to nothing where the bone's direction "
                           "is this far from the sculpted pose (at least 10 degrees: below, Blender's float32 bone "
                           "rotations make the driver inexact)", default=math.radians(60.0), min=math.radians(10.0),
                           max=math.pi, subtype='ANGLE')

    def run(self, context):
        skin, arm = resolve_skin(context, self.skin)
        if bool(self.source_key) == bool(self.source_object):
            raise ValueError("Give the sculpt as a shape key of the skin or as a sculpted object (one of them)")
        source = None
        if self.source_object:
            source = bpy.data.objects.get(self.source_object)
            if source is None:
                raise ValueError(f"There is no object '{self.source_object}'")
        bone = self.bone or (context.active_pose_bone.name if getattr(context, "active_pose_bone", None) else "")
        if not bone:
            raise ValueError("Name the bone that drives the corrective (or make it the active pose bone)")
        if skin.mode != 'OBJECT':
            raise ValueError(f"'{skin.name}' is in {skin.mode.title()} Mode: go back to Object Mode to add a corrective")
        pose_muscle_joints(arm)
        name, largest, moved = correctives.add_corrective(context, skin, arm, bone, self.name, self.falloff,
                                                          self.source_key, source)
        return (f"Added corrective '{name}' on '{skin.name}', driven by '{bone}' (sculpt moves the skin up to "
                f"{moved:.4g}, rest-space offset up to {largest:.4g})")


class MYOSKIN_OT_remove_corrective(_MuscleOperator, bpy.types.Operator):
    """Remove a corrective's shape key and its drivers (the others keep theirs)"""
    bl_idname = "myoskin.remove_corrective"
    bl_label = "Remove Corrective"

    name: StringProperty(name="Name", description="The corrective to remove")
    skin: StringProperty(name="Skin", description="The skinned mesh (empty: the active object)")

    def run(self, context):
        skin, arm = resolve_skin(context, self.skin)
        left = correctives.remove_corrective(context, skin, arm, self.name)
        return f"Removed corrective '{self.name}' from '{skin.name}' ({left} left)"


classes = (MYOSKIN_OT_add_corrective, MYOSKIN_OT_remove_corrective)
