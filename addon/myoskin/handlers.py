# SPDX-License-Identifier: GPL-3.0-or-later
"""Persistent application handlers and the work behind the property update callbacks. They hold no
references to Blender data (those die on reload): every call looks the armatures up in bpy.data, and
returns early when nothing relevant changed. Their state (the pending rebinds) and the re-entrancy guard
they share with live.py are owned by runtime.py; failures are reported through runtime.report_error
(the panels show them).

- locator watcher (depsgraph_update_post): a moved origin/insertion locator re-attaches its muscle (path
  and surface rebuilt through the core) right away; on a bound rig (with Auto Rebind on) a timer binds
  again once the locators have been still for REBIND_DELAY seconds, so the muscle joints follow too
  (bones cannot be re-created from inside a depsgraph handler).
- property callbacks (state.py dispatches them through runtime): a muscle setting changed, a muscle
  renamed, Live Update or Preserve Volume toggled.
- live update: see live.py (registered from there).

Layer: runtime. Imports downward only (binding, core_loader, live, muscle_io, runtime).
"""
import time

import bpy
from bpy.app.handlers import persistent

from . import binding, core_loader, live, muscle_io, runtime

REBIND_DELAY = 0.4  # seconds the locators must stay still before a bound rig binds again


def _armatures_with_muscles():
    return [o for o in bpy.data.objects if o.type == 'ARMATURE' and len(o.myoskin.muscles)]


@persistent
def watch_locators(scene, depsgraph=None):
    """Re-attach the muscles whose locators moved (rest positions differ from the stored data)."""
    if runtime.busy():
        return
    if depsgraph is not None and not any(u.is_updated_transform and isinstance(u.id, bpy.types.Object)
                                         and u.id.get("myoskin_end") is not None for u in depsgraph.updates):
        return  # no locator moved (e.g. playback, posing): nothing to do
    if not core_loader.available():
        return
    with runtime.guard():
        for arm in _armatures_with_muscles():
            moved = muscle_io.moved_locator_muscles(arm)
            for item in moved:
                try:
                    muscle_io.refresh_muscle(arm, item)
                except (ValueError, RuntimeError) as e:
                    runtime.report_error(arm, f"muscle '{item.name}' not updated: {e}")
            if moved:
                arm.myoskin.dirty = arm.myoskin.bound
                muscle_io.sync_text(arm)
                if arm.myoskin.bound and arm.myoskin.auto_rebind:
                    schedule_rebind(arm.name)


def schedule_rebind(arm_name):
    """Bind `arm_name` again once its locators have been still for REBIND_DELAY seconds."""
    runtime.rebind["armatures"].add(arm_name)
    runtime.rebind["last_move"] = time.monotonic()
    if not bpy.app.timers.is_registered(rebind_pending):
        bpy.app.timers.register(rebind_pending, first_interval=REBIND_DELAY)


def rebind_pending(force=False):
    """Timer: bind again the armatures whose locators moved (in Object Mode only; later otherwise).
    Returns the seconds until the next try, or None when done."""
    pending = runtime.rebind
    wait = REBIND_DELAY - (time.monotonic() - pending["last_move"])
    if not force and wait > 0:
        return wait
    if not force and bpy.context.mode != 'OBJECT':
        return REBIND_DELAY  # never switch modes under the user: try again when they are back
    with runtime.guard():
        try:
            for name in sorted(pending["armatures"]):
                arm = bpy.data.objects.get(name)
                state = arm.myoskin if arm is not None else None
                skins = binding.bound_skins(arm) if state is not None else []
                if state is None or not state.bound or not state.dirty or not skins:
                    continue
                try:
                    binding.unbind(arm)
                    binding.bind(bpy.context, skins, arm)
                    live.update_armature(arm, force=True)
                except (ValueError, RuntimeError) as e:
                    state.dirty = True
                    runtime.report_error(arm, f"'{name}' not bound again after the edit: {e} (use Bind)")
        finally:
            pending["armatures"].clear()
    return None


# ------------------------------------------------------------------------------------------------
# The work of the property update callbacks (state.py -> runtime.dispatch -> here)
# ------------------------------------------------------------------------------------------------


def on_settings_changed(arm_obj, item):
    """A muscle's settings changed: redraw its wrap display, rewrite muscles.json; on a bound rig apply the
    change live when the joints stay the same (bulge), else mark the rig edited (bind again)."""
    state = arm_obj.myoskin
    muscle_io.update_wrap_display(arm_obj, item)
    if state.bound and not state.dirty:
        state.dirty = not live.apply_settings_to_bound(arm_obj)
    muscle_io.sync_text(arm_obj)


def on_preserve_volume_changed(arm_obj, state):
    """Preserve Volume toggled: a bound rig's Armature modifiers follow at once (unbound: Bind sets them)."""
    binding.apply_preserve_volume(arm_obj)


def on_volume_blend_changed(arm_obj, state):
    """Volume Blend toggled: a bound rig's modifiers follow at once; a rig bound with it off has no shares yet, so
    it binds again (Auto Rebind's timer; marked edited, and a message says so, when Auto Rebind is off)."""
    waiting = binding.apply_volume_blend(arm_obj)
    if waiting:
        _bind_again(arm_obj, state, f"Volume Blend on '{arm_obj.name}' needs a Bind: it was bound without the "
                                    f"volume blend's shares ({', '.join(waiting)})")


def _bind_again(arm_obj, state, message):
    """A setting a bound rig was built with changed: mark it edited and bind again (Auto Rebind's timer), or say
    `message` when Auto Rebind is off."""
    state.dirty = True
    if state.auto_rebind:
        schedule_rebind(arm_obj.name)
    else:
        runtime.report_error(arm_obj, message)


def on_joints_slide_changed(arm_obj, state):
    """Joints Slide toggled: a bound Muscle Joints rig whose joints and volume keys were made for the other setting
    binds again (Auto Rebind's timer; marked edited, and a message says so, when Auto Rebind is off). The anchored
    deformer's skin does not use the muscle joints."""
    if not state.bound:
        return
    record, problem = binding.read_bind_record_or_empty(arm_obj)  # an unreadable record: bind again
    if not problem and (record.get("deformer") == "anchored" or live.joints_slide(record) == bool(state.joints_slide)):
        return
    _bind_again(arm_obj, state, f"Joints Slide on '{arm_obj.name}' takes effect at the next Bind")


CALLBACKS = {"settings_changed": on_settings_changed, "renamed": muscle_io.on_renamed,
             "live_changed": live.on_live_changed, "preserve_volume_changed": on_preserve_volume_changed,
             "volume_blend_changed": on_volume_blend_changed, "joints_slide_changed": on_joints_slide_changed}


def register():
    runtime.connect(**CALLBACKS)
    if watch_locators not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(watch_locators)


def unregister():
    if watch_locators in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(watch_locators)
    if bpy.app.timers.is_registered(rebind_pending):
        bpy.app.timers.unregister(rebind_pending)
    runtime.disconnect()
