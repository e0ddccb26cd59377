# SPDX-License-Identifier: GPL-3.0-or-later
"""Myoskin: anatomy-based skinning (Yang & Zhang 2006) for Blender.

A thin layer over the compiled core: blender_io converts Blender data to and from the core's arrays,
operators/ call the core, panels/ draw. Only core_loader imports the compiled module `_core`; when it
cannot (missing, or built for another Python), the add-on still registers and the panels say what to do.

Layers, bottom to top; a module imports only from its own layer or below, at module level
(tests/python/test_addon_layers.py checks it):
  0  core_loader, anim_compat, gltf_io, runtime (re-entrancy guard, caches, callback dispatcher, errors)
  1  blender_io, rig_io, truth                   Blender <-> core arrays
  2  state                                       the properties in the .blend; callbacks -> runtime.dispatch
  3  muscle_io, binding                          muscle and rig services
  4  live, handlers                              runtime: application handlers, live update, callback work
  5  operators/, panels/, preferences, batch     user interface
"""

bl_info = {
    "name": "Myoskin",
    "author": "Myoskin contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Myoskin",
    "description": "Extract muscles from a rigged character's skin and deform the skin with muscles and skeleton",
    "category": "Animation",
    "support": "COMMUNITY",
}

import bpy  # noqa: E402

from . import core_loader, handlers, live, operators, panels, preferences, state  # noqa: E402,F401

classes = (*state.classes, *preferences.classes, *operators.classes, *panels.classes)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    state.register()
    handlers.register()
    live.register()
    if not core_loader.available():
        print(f"Myoskin: {core_loader.status().message}")


def unregister():
    live.unregister()
    handlers.unregister()
    state.unregister()
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
