# SPDX-License-Identifier: GPL-3.0-or-later
"""glTF import and export with the options each Blender's glTF add-on has (3.4 to 5.x). Bottom layer:
imports nothing of the add-on."""
import json
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


MAX_JSON_CHARS = 256 * 1024 * 1024


def check_gltf_file(filepath):
    """ValueError saying what is wrong when a .glb/.gltf is not even a readable glTF container (empty,
    truncated, a chunk length past the end, its JSON not JSON), before Blender's importer sees it (its own
    failures on such files are tracebacks). Checks the container only: the importer reads the rest."""
    size = os.path.getsize(filepath)
    if size == 0:
        raise ValueError("the file is empty")
    with open(filepath, "rb") as f:
        head = f.read(20)
        if filepath.lower().endswith(".glb") or head[:4] == b"glTF":
            if len(head) < 20 or head[:4] != b"glTF":
                raise ValueError(f"not a binary glTF (no 'glTF' header; {size} bytes)")
            version, length, json_length, kind = (int.from_bytes(head[i:i + 4], "little") for i in (4, 8, 12, 16))
            if version != 2:
                raise ValueError(f"glTF version {version}, not 2")
            if length != size:
                raise ValueError(f"the header says {length:,} bytes, the file has {size:,} (truncated?)")
            if kind != 0x4E4F534A or json_length > size - 20:
                raise ValueError(f"the JSON chunk ({json_length:,} bytes) does not fit in the file (damaged?)")
            content = f.read(json_length)
        else:
            if size > MAX_JSON_CHARS:
                raise ValueError(f"{size:,} bytes of JSON, more than {MAX_JSON_CHARS:,}")
            content = head + f.read()
    try:
        doc = json.loads(content.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise ValueError("its JSON part is not valid JSON (damaged?)") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("asset"), dict):
        raise ValueError("its JSON part is not a glTF document (no 'asset')")


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
