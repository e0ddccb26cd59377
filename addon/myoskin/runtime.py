# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's runtime state, owned in one place below everything that uses it. Imports nothing of the
add-on, so any layer may import it:

- the one re-entrancy guard of every handler (`busy()`, `with guard():`): our own writes trigger
  depsgraph updates and frame changes too;
- the caches that live between handler calls (`live_rigs`, `rebind`, `frame_armatures`), keyed by armature
  name and dropped by `forget()` (they hold no Blender data: those die on reload and undo), and `deferred`, the
  modifiers one frame change's first pass skips (names; emptied by the frame_change_post of that change);
- the dispatcher of the property update callbacks (state.py defines the properties, but the work is done by
  layers above it, which `connect()` their functions at register time);
- the errors facility: `report_error()` stores the last error per armature where the panels draw it
  (`last_error()`), prints it and asks the Myoskin panels to redraw (headless: store and print only).
"""
from contextlib import contextmanager

import bpy

# ------------------------------------------------------------------------------------------------
# Re-entrancy guard
# ------------------------------------------------------------------------------------------------

_busy = False


def busy():
    """True while a handler (or a timer acting like one) is writing Blender data."""
    return _busy


@contextmanager
def guard():
    """Mark the runtime busy for the block (nests: an inner block leaves it busy)."""
    global _busy
    previous, _busy = _busy, True
    try:
        yield
    finally:
        _busy = previous


# ------------------------------------------------------------------------------------------------
# Caches (filled and read by live.py and handlers.py)
# ------------------------------------------------------------------------------------------------

live_rigs = {}  # armature name -> live.LiveRig
rebind = {"armatures": set(), "last_move": 0.0}  # armatures to bind again once their locators are still
# The bound armatures found by the last frame_change_pre, for the frame_change_post of the same frame change
# (scene pointer, frame, live-update armature names, baked armature names); used once, then cleared.
frame_armatures = None
# Skinning modifiers switched off for the first evaluation pass of a frame change (live.defer_skinning), as
# (object name, modifier name); switched back on by live.restore_deferred in the frame_change_post.
deferred = []


def forget(arm_name=None):
    """Drop cached rigs (all, or one armature's)."""
    if arm_name is None:
        live_rigs.clear()
    else:
        live_rigs.pop(arm_name, None)


# ------------------------------------------------------------------------------------------------
# Dispatcher of the property update callbacks
# ------------------------------------------------------------------------------------------------

_hooks = {}  # event name -> function(arm_obj, *args)


def connect(**functions):
    """Register the functions that do the work of the property callbacks, e.g. settings_changed=f."""
    _hooks.update(functions)


def disconnect():
    _hooks.clear()


def dispatch(event, arm_obj, *args):
    """Call the function connected to `event` (nothing when none is: the add-on is not registered)."""
    function = _hooks.get(event)
    if function is not None:
        return function(arm_obj, *args)
    return None


# ------------------------------------------------------------------------------------------------
# Errors where the user sees them
# ------------------------------------------------------------------------------------------------

_errors = {}  # armature name -> the last error message of a handler or property callback on it
REDRAW_AREAS = {'VIEW_3D', 'PROPERTIES'}


def _name(arm):
    return arm if isinstance(arm, str) else getattr(arm, "name", str(arm))


def report_error(arm, message):
    """A handler or property callback failed on armature `arm` (object or name): keep the message for the
    panels (sidebar, modifier tab), print it, and redraw the panels when there is a window."""
    _errors[_name(arm)] = message
    print(f"Myoskin: {message}")
    _redraw()


def last_error(arm):
    """The last error reported for an armature (object or name), or "" when none is pending."""
    return _errors.get(_name(arm), "")


def clear_error(arm=None):
    """Forget the error of one armature (object or name), or of all when None."""
    if arm is None:
        _errors.clear()
    else:
        _errors.pop(_name(arm), None)
    _redraw()


def _redraw():
    try:
        windows = bpy.context.window_manager.windows
    except AttributeError:  # no window manager (e.g. while a file loads)
        return
    try:
        for window in windows:
            for area in window.screen.areas:
                if area.type in REDRAW_AREAS:
                    area.tag_redraw()
    except (AttributeError, ReferenceError, RuntimeError):  # a window without a screen; render thread
        pass
