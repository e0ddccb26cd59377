# SPDX-License-Identifier: GPL-3.0-or-later
"""Drawing helpers shared by the panels (UI only)."""
import textwrap

from .. import core_loader, runtime
from ..blender_io import find_armature, find_skin_meshes


def draw_wrapped(layout, text, context=None, icon='NONE'):
    """Labels for `text` wrapped to the region's width (the first line carries the icon)."""
    width = getattr(getattr(context, "region", None), "width", 0) or 300
    chars = max(20, int(width / 7))
    col = layout.column(align=True)
    for i, line in enumerate(textwrap.wrap(text, chars) or [""]):
        col.label(text=line, icon=icon if i == 0 else 'NONE')
    return col


def draw_core_status(layout, context=None):
    """The core's status: one line when it loaded, the full instructions when it did not."""
    status = core_loader.status()
    if status.available:
        layout.label(text=f"Core {status.build_info.get('myoskin_version', '')} ready", icon='CHECKMARK')
        return True
    box = layout.box()
    box.alert = True
    draw_wrapped(box, status.message, context, icon='ERROR')
    box.label(text=f"This Blender runs Python {core_loader.running_python_version()}; the add-on has a core "
                   f"for Python {core_loader.pythons_text(core_loader.available_pythons())}")
    return False


def draw_last_error(layout, arm, context=None):
    """The last error a handler or property callback reported for the armature (runtime.report_error), in a
    red box with a Dismiss button; nothing when there is none. Returns True when it drew one."""
    message = runtime.last_error(arm) if arm is not None else ""
    if not message:
        return False
    box = layout.box()
    box.alert = True
    draw_wrapped(box, message, context, icon='ERROR')
    box.operator("myoskin.clear_error", text="Dismiss", icon='X').armature = arm.name
    return True


def draw_character_info(layout, obj):
    """Cheap facts about the active object (no core call: panels redraw often)."""
    if obj is None:
        layout.label(text="No active object", icon='INFO')
        return
    arm = find_armature(obj)
    col = layout.column(align=True)
    if obj.type == 'MESH':
        mesh = obj.data
        col.label(text=f"{obj.name}: {len(mesh.vertices):,} vertices, {len(mesh.polygons):,} faces",
                  icon='MESH_DATA')
        col.label(text=f"{len(obj.vertex_groups)} vertex groups")
    else:
        col.label(text=f"{obj.name} ({obj.type.lower()})", icon='OBJECT_DATA')
    if obj.type == 'ARMATURE':  # the whole character: what Extract uses with the armature active
        meshes = [o.name for o in find_skin_meshes(obj) if o.get("myoskin_muscle") is None]
        col.label(text=f"Character: {len(meshes)} mesh(es) {', '.join(meshes[:4])}"
                       f"{' ...' if len(meshes) > 4 else ''}", icon='OUTLINER_OB_MESH')
    if arm is not None:
        col.label(text=f"Armature {arm.name}: {len(arm.data.bones)} bones", icon='ARMATURE_DATA')
    else:
        col.label(text="No armature", icon='ERROR')
