# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene helpers shared by the example scripts (run inside Blender): empty scene, translucent skin and
muscle materials, an orthographic camera fitted to points, a sun, Cycles CPU render settings."""
import importlib
import sys

import bpy
import numpy as np
from mathutils import Vector


def addon_module(name):
    """A module of the enabled add-on, whatever its package: "myoskin" or "bl_ext.<repository>.myoskin"."""
    enabled = sorted(n for n in bpy.context.preferences.addons.keys() if n == "myoskin" or n.endswith(".myoskin"))
    return importlib.import_module(f"{(enabled or ['myoskin'])[0]}.{name}")


def require_addon(prog):
    """The add-on's core_loader with its compiled core loaded, or a clear exit saying what to do."""
    try:
        core_loader = addon_module("core_loader")
    except ImportError:
        sys.exit(f"{prog}: the Myoskin add-on is not importable: run Blender with "
                 "BLENDER_USER_SCRIPTS=<build>/blender_scripts and --addons myoskin (./myoskin.sh does)")
    if not core_loader.available():
        sys.exit(f"{prog}: {core_loader.status().message}")
    return core_loader


# ------------------------------------------------------------------------------------------------
# Scene
# ------------------------------------------------------------------------------------------------

def empty_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for coll in (bpy.data.meshes, bpy.data.materials, bpy.data.cameras, bpy.data.lights):
        for block in list(coll):
            if block.users == 0:
                coll.remove(block)


def skin_material():
    """Translucent skin: more opaque where seen edge-on (facing), so the silhouette reads."""
    mat = bpy.data.materials.new("Myoskin Skin")
    mat.use_nodes = True
    mat.diffuse_color = (0.85, 0.62, 0.5, 0.35)
    if hasattr(mat, "surface_render_method"):  # EEVEE Next (4.2+); Cycles uses the node tree
        mat.surface_render_method = 'BLENDED'
    else:
        mat.blend_method = 'BLEND'
        mat.shadow_method = 'NONE'  # from 4.2 on an object setting: see use_skin_material
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.85, 0.62, 0.5, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    transparent = nodes.new("ShaderNodeBsdfTransparent")
    weight = nodes.new("ShaderNodeLayerWeight")
    weight.inputs["Blend"].default_value = 0.35
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["To Min"].default_value = 0.12
    ramp.inputs["To Max"].default_value = 0.9
    mix = nodes.new("ShaderNodeMixShader")
    links.new(weight.outputs["Facing"], ramp.inputs["Value"])
    links.new(ramp.outputs["Result"], mix.inputs["Fac"])
    links.new(transparent.outputs["BSDF"], mix.inputs[1])
    links.new(bsdf.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


def use_skin_material(obj):
    """Give `obj` the translucent skin material; it casts no shadow (Object.visible_shadow from 4.2)."""
    obj.data.materials.append(skin_material())
    if hasattr(obj, "visible_shadow"):
        obj.visible_shadow = False


def muscle_material():
    mat = bpy.data.materials.new("Myoskin Muscle")
    mat.use_nodes = True
    mat.diffuse_color = (0.75, 0.06, 0.05, 1.0)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.75, 0.06, 0.05, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.45
    return mat


def look_at(obj, target):
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()


def frame_camera(points, resolution, direction=(0.25, -1.0, 0.45), margin=1.12):
    """An orthographic camera looking along -direction at all `points` (world, #N by 3), fitted to them."""
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = 'ORTHO'
    cam = bpy.data.objects.new("Camera", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    d = Vector(direction).normalized()
    centre = Vector(points.mean(axis=0))
    cam.location = centre + d * 3.0
    look_at(cam, centre)
    rot = np.array(cam.rotation_euler.to_matrix())
    local = (points - np.array(cam.location)) @ rot  # camera space (x right, y up)
    lo, hi = local.min(axis=0), local.max(axis=0)
    mid = (lo + hi) / 2.0
    cam.location = Vector(np.array(cam.location) + rot[:, 0] * mid[0] + rot[:, 1] * mid[1])
    aspect = resolution[0] / resolution[1]
    cam_data.ortho_scale = float(max(hi[0] - lo[0], (hi[1] - lo[1]) * aspect) * margin)
    cam_data.clip_end = 10.0
    bpy.context.scene.camera = cam
    return cam


def add_sun():
    sun_data = bpy.data.lights.new("Sun", 'SUN')
    sun_data.energy = 3.5
    sun_data.angle = np.radians(8.0)
    sun = bpy.data.objects.new("Sun", sun_data)
    sun.rotation_euler = (np.radians(40.0), np.radians(-15.0), np.radians(-30.0))
    bpy.context.scene.collection.objects.link(sun)
    return sun


def setup_render(scene, samples, resolution):
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.transparent_max_bounces = 16
    scene.cycles.max_bounces = 4
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.render.film_transparent = False
    scene.view_settings.view_transform = 'Standard'
    world = bpy.data.worlds.new("Myoskin World") if scene.world is None else scene.world
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.42, 0.45, 0.5, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6


def render_still(scene, path):
    """Render the current frame to a PNG at `path`."""
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
