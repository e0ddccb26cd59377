# SPDX-License-Identifier: GPL-3.0-or-later
"""Persistent application handlers. They hold no references to Blender data (those die on reload): every
call looks the armatures up in bpy.data, and returns early when nothing relevant changed.

- locator watcher (depsgraph_update_post): a moved origin/insertion locator re-attaches its muscle (path
  and surface rebuilt through the core) right away.
- live update: see live.py (registered from there).
"""
import bpy
from bpy.app.handlers import persistent

_busy = False  # re-entrancy guard: our own writes trigger depsgraph updates too


def _armatures_with_muscles():
    return [o for o in bpy.data.objects if o.type == 'ARMATURE' and len(o.myoskin.muscles)]


@persistent
def watch_locators(scene, depsgraph=None):
    """Re-attach the muscles whose locators moved (rest positions differ from the stored data)."""
    global _busy
    if _busy:
        return
    if depsgraph is not None and not any(u.is_updated_transform and isinstance(u.id, bpy.types.Object)
                                         and u.id.get("myoskin_end") is not None for u in depsgraph.updates):
        return  # no locator moved (e.g. playback, posing): nothing to do
    from . import core_loader, muscle_io
    if not core_loader.available():
        return
    _busy = True
    try:
        for arm in _armatures_with_muscles():
            moved = muscle_io.moved_locator_muscles(arm)
            for item in moved:
                try:
                    muscle_io.refresh_muscle(arm, item)
                except (ValueError, RuntimeError) as e:
                    print(f"Myoskin: muscle '{item.name}' not updated: {e}")
            if moved:
                arm.myoskin.dirty = arm.myoskin.bound
                muscle_io.sync_text(arm)
    finally:
        _busy = False


def register():
    if watch_locators not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(watch_locators)


def unregister():
    if watch_locators in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(watch_locators)
