# SPDX-License-Identifier: GPL-3.0-or-later
"""glTF import and export with the options each Blender's glTF add-on has (3.4 to 5.x). Bottom layer:
imports nothing of the add-on."""
import os
import warnings

import bpy
import numpy as np


def numpy_bool_for_gltf():
    """Debian's Blender 3.4 glTF add-on uses numpy.bool, removed in numpy 1.24."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if not hasattr(np, "bool"):
            np.bool = bool


def _supported(op, options):
    """`options` less those this Blender's operator does not have."""
    names = set(op.get_rna_type().properties.keys())
    return {k: v for k, v in options.items() if k in names}


def import_gltf(filepath):
    """Import a .glb/.gltf as a character: without the bone-shape mesh 4.2+ adds for display (an
    `Icosphere` in a hidden collection, which would count as a second mesh)."""
    numpy_bool_for_gltf()
    op = bpy.ops.import_scene.gltf
    return op(filepath=os.path.abspath(filepath), **_supported(op, {"disable_bone_shape": True}))


def export_gltf(filepath, use_selection=True):
    """Export the selection (skin, armature with the muscle joints' helper bones, their Actions)."""
    numpy_bool_for_gltf()
    op = bpy.ops.export_scene.gltf
    options = {"export_format": 'GLTF_SEPARATE' if filepath.endswith(".gltf") else 'GLB',
               "use_selection": use_selection, "export_animations": True, "export_skins": True,
               "export_def_bones": True}
    return op(filepath=filepath, **_supported(op, options))
