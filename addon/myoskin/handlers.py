# SPDX-License-Identifier: GPL-3.0-or-later
"""Persistent application handlers. They hold no references to Blender data (those die on reload): every
call looks the armatures up in bpy.data, and returns early when nothing relevant changed.

- locator watcher (depsgraph_update_post): a moved origin/insertion locator re-attaches its muscle (path
  and surface rebuilt through the core) right away; on a bound rig (with Auto Rebind on) a timer binds
  again once the locators have been still for REBIND_DELAY seconds, so the muscle joints follow too
  (bones cannot be re-created from inside a depsgraph handler).
- live update: see live.py (registered from there).
"""
import time

import bpy
from bpy.app.handlers import persistent

_busy = False  # re-entrancy guard: our own writes trigger depsgraph updates too
REBIND_DELAY = 0.4  # seconds the locators must stay still before a bound rig binds again
_rebind = {"armatures": set(), "last_move": 0.0}


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
                if arm.myoskin.bound and arm.myoskin.auto_rebind:
                    schedule_rebind(arm.name)
    finally:
        _busy = False


def schedule_rebind(arm_name):
    """Bind `arm_name` again once its locators have been still for REBIND_DELAY seconds."""
    _rebind["armatures"].add(arm_name)
    _rebind["last_move"] = time.monotonic()
    if not bpy.app.timers.is_registered(rebind_pending):
        bpy.app.timers.register(rebind_pending, first_interval=REBIND_DELAY)


def rebind_pending(force=False):
    """Timer: bind again the armatures whose locators moved (in Object Mode only; later otherwise).
    Returns the seconds until the next try, or None when done."""
    wait = REBIND_DELAY - (time.monotonic() - _rebind["last_move"])
    if not force and wait > 0:
        return wait
    if not force and bpy.context.mode != 'OBJECT':
        return REBIND_DELAY  # never switch modes under the user: try again when they are back
    from .operators import rig
    global _busy
    _busy = True
    try:
        for name in sorted(_rebind["armatures"]):
            arm = bpy.data.objects.get(name)
            state = arm.myoskin if arm is not None else None
            if state is None or not state.bound or not state.dirty or state.skin is None:
                continue
            try:
                rig.unbind(state.skin, arm)
                rig.bind(bpy.context, state.skin, arm)
            except (ValueError, RuntimeError) as e:
                state.dirty = True
                print(f"Myoskin: '{name}' not bound again after the locator move: {e} (use Bind)")
    finally:
        _busy = False
        _rebind["armatures"].clear()
    return None


def register():
    if watch_locators not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(watch_locators)


def unregister():
    if watch_locators in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(watch_locators)
    if bpy.app.timers.is_registered(rebind_pending):
        bpy.app.timers.unregister(rebind_pending)
