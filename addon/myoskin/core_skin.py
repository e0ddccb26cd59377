# SPDX-License-Identifier: GPL-3.0-or-later
"""Skins whose positions the core computes (deformers other than Blender's Armature modifier: the anchored
skin). Blender has no Python modifier, so the core's result reaches the mesh as data:

- each such mesh gets a Geometry Nodes modifier "Myoskin Core Skin" (a shared node group that offsets every
  vertex by the point attribute OFFSET_ATTRIBUTE: Named Attribute -> Set Position's Offset), and its
  Armature modifier is switched off in the viewport and renders (Unbind switches it back on);
- the live handlers write offset = core position - rest position (mesh object space) into that attribute
  before Blender evaluates, so the rest mesh itself is never touched (saving, Unbind and the add-on disabled
  all keep it), a missing or zero attribute shows the rest pose, and shape keys still add on top.

Layer: service (imports blender_io, core_loader).
"""

import bpy
import numpy as np
from mathutils import Matrix

from . import blender_io

PINNED_GROUP = "myoskin_pinned"  # a vertex group on an anchored skin: vertices (weight > 0.5) relaxation never moves
MODIFIER = "Myoskin Core Skin"
NODE_GROUP = "Myoskin Core Skin"
OFFSET_ATTRIBUTE = "myoskin_offset"


def node_group():
    """The shared node group: Geometry in -> Set Position (Offset = named attribute OFFSET_ATTRIBUTE) -> out."""
    group = bpy.data.node_groups.get(NODE_GROUP)
    if group is not None and group.bl_idname == 'GeometryNodeTree':
        return group
    group = bpy.data.node_groups.new(NODE_GROUP, 'GeometryNodeTree')
    if hasattr(group, "interface"):  # 4.0+
        group.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
        group.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    else:  # 3.x
        group.inputs.new('NodeSocketGeometry', "Geometry")
        group.outputs.new('NodeSocketGeometry', "Geometry")
    nodes, links = group.nodes, group.links
    group_in, group_out = nodes.new('NodeGroupInput'), nodes.new('NodeGroupOutput')
    attribute = nodes.new('GeometryNodeInputNamedAttribute')
    attribute.data_type = 'FLOAT_VECTOR'
    attribute.inputs["Name"].default_value = OFFSET_ATTRIBUTE
    set_position = nodes.new('GeometryNodeSetPosition')
    group_in.location, attribute.location, set_position.location, group_out.location = \
        (-400, 0), (-400, -150), (-150, 0), (100, 0)
    vector = next(s for s in attribute.outputs if s.name == "Attribute" and s.type == 'VECTOR' and s.enabled)
    links.new(group_in.outputs[0], set_position.inputs["Geometry"])
    links.new(vector, set_position.inputs["Offset"])
    links.new(set_position.outputs["Geometry"], group_out.inputs[0])
    return group


def modifier(skin):
    for mod in skin.modifiers:
        if mod.type == 'NODES' and mod.name == MODIFIER:
            return mod
    return None


def attach(skin, armature_modifier):
    """Drive `skin` from the core: add the Core Skin modifier (last in the stack) with a zero offset and switch
    its Armature modifier off. Returns what Unbind needs to restore (the modifier's visibility)."""
    was = {}
    if armature_modifier is not None:
        was = {"show_viewport": bool(armature_modifier.show_viewport),
               "show_render": bool(armature_modifier.show_render)}
        armature_modifier.show_viewport = armature_modifier.show_render = False
    mod = modifier(skin)
    if mod is None:
        mod = skin.modifiers.new(MODIFIER, 'NODES')
    mod.node_group = node_group()
    write_offsets(skin, np.zeros((len(skin.data.vertices), 3), dtype=np.float32))
    return was


def detach(skin, armature_modifier, was):
    """Undo attach: remove the Core Skin modifier and the offset attribute, restore the Armature modifier."""
    mod = modifier(skin)
    if mod is not None:
        skin.modifiers.remove(mod)
    attribute = skin.data.attributes.get(OFFSET_ATTRIBUTE)
    if attribute is not None:
        skin.data.attributes.remove(attribute)
    if armature_modifier is not None:
        armature_modifier.show_viewport = bool(was.get("show_viewport", True))
        armature_modifier.show_render = bool(was.get("show_render", True))


def write_offsets(skin, offsets):
    """Write #V by 3 offsets (mesh object space) into the skin's offset attribute and tag it for evaluation."""
    mesh = skin.data
    attribute = mesh.attributes.get(OFFSET_ATTRIBUTE)
    if attribute is None or attribute.data_type != 'FLOAT_VECTOR' or attribute.domain != 'POINT':
        if attribute is not None:
            mesh.attributes.remove(attribute)
        attribute = mesh.attributes.new(OFFSET_ATTRIBUTE, 'FLOAT_VECTOR', 'POINT')
    attribute.data.foreach_set("vector", np.ascontiguousarray(offsets, dtype=np.float32).ravel())
    mesh.update_tag()


class MeshFrame:
    """One mesh of a core-driven character: its rest positions in armature space (what the core deforms) and
    the map back to mesh object space."""

    def __init__(self, skin, arm):
        self.name = skin.name
        to_arm = blender_io.mesh_to_armature_matrix(skin, arm)
        local = blender_io.mesh_vertices(skin.data)
        self.rest_local = local.astype(np.float64)
        self.rest = local @ to_arm[:3, :3].T + to_arm[:3, 3]  # #V by 3, armature space
        self.to_mesh = np.linalg.inv(to_arm)

    def offsets(self, posed):
        """#V by 3 mesh-space offsets of armature-space positions `posed` from this mesh's rest."""
        posed = np.asarray(posed, dtype=np.float64)
        return posed @ self.to_mesh[:3, :3].T + self.to_mesh[:3, 3] - self.rest_local


# ------------------------------------------------------------------------------------------------
# Stuffing: ellipsoids the artist places (empties) for the anchored skin
# ------------------------------------------------------------------------------------------------

STUFFING_KEY = "myoskin_stuffing"  # ID property marking an Empty as a stuffing ellipsoid


def add_stuffing(context, arm, bone_name):
    """A stuffing ellipsoid for the anchored skin: an Empty (sphere display) parented to the bone, at the bone's
    middle, radii a quarter of the bone's length; the artist moves, turns and scales it. Returns the Empty."""
    bone = arm.data.bones.get(bone_name)
    if bone is None:
        raise ValueError(f"Armature '{arm.name}' has no bone '{bone_name}'")
    empty = bpy.data.objects.new(f"Stuffing.{bone_name}", None)
    empty.empty_display_type = 'SPHERE'
    empty.empty_display_size = 1.0
    empty[STUFFING_KEY] = True
    (arm.users_collection[0] if arm.users_collection else context.scene.collection).objects.link(empty)
    empty.parent, empty.parent_type, empty.parent_bone = arm, 'BONE', bone_name
    # Bone parenting hangs the child at the bone's tail: the bone's middle is half its length back along Y.
    empty.matrix_parent_inverse = Matrix.Identity(4)
    empty.location = (0.0, -0.5 * bone.length, 0.0)
    empty.scale = (0.25 * bone.length,) * 3
    return empty


def stuffing_of(arm):
    """The stuffing ellipsoids of an armature as the core's component dicts ({"kind": "stuffing", "name", "bone",
    "center", "axes", "radii"}, armature space at rest): every Empty marked STUFFING_KEY parented to one of its
    bones, its rest place the bone's rest matrix times the Empty's transform under it, its radii the Empty's
    display size times its scale (a zero or negative scale is refused with the Empty's name)."""
    out = []
    for obj in sorted(bpy.data.objects, key=lambda o: o.name):
        if obj.type != 'EMPTY' or not obj.get(STUFFING_KEY) or obj.parent != arm:
            continue
        bone = arm.data.bones.get(obj.parent_bone) if obj.parent_type == 'BONE' else None
        if bone is None:
            raise ValueError(f"Stuffing '{obj.name}' must be parented to a bone of '{arm.name}' (Parent Type: Bone)")
        tail = Matrix.Translation((0.0, bone.length, 0.0))
        rest = np.array(bone.matrix_local @ tail @ obj.matrix_parent_inverse @ obj.matrix_basis)
        columns = rest[:3, :3]
        scale = np.linalg.norm(columns, axis=0)
        if not np.all(scale > 1e-12) or not np.all(np.isfinite(rest)):
            raise ValueError(f"Stuffing '{obj.name}' has a zero or invalid scale")
        axes = columns / scale
        if np.linalg.det(axes) < 0:
            raise ValueError(f"Stuffing '{obj.name}' is mirrored (negative scale): use positive scales")
        out.append({"kind": "stuffing", "name": obj.name, "bone": bone.name, "center": rest[:3, 3].tolist(),
                    "axes": axes.tolist(), "radii": (scale * obj.empty_display_size).tolist()})
    return out
