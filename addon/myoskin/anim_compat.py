# SPDX-License-Identifier: GPL-3.0-or-later
"""The F-curves that animate an object, in every supported Blender: `Action.fcurves` up to 4.3; from 4.4 on
the channelbag of the Action slot the object uses (slotted actions; `Action.fcurves` is a legacy proxy in
4.4 and 4.5 and is gone in 5.0). Bottom layer: imports nothing of the add-on."""
import bpy

SLOTTED_ACTIONS = bpy.app.version >= (4, 4, 0)


def action_key(anim_data):
    """What identifies the F-curves an object plays: (Action pointer, slot handle), (0, 0) for none."""
    if anim_data is None or anim_data.action is None:
        return (0, 0)
    slot = anim_data.action_slot if SLOTTED_ACTIONS else None
    return (anim_data.action.as_pointer(), slot.handle if slot is not None else 0)


def object_fcurves(anim_data):
    """The F-curves of the object's Action for its slot (an empty tuple when it has none)."""
    if anim_data is None or anim_data.action is None:
        return ()
    if not SLOTTED_ACTIONS:
        return anim_data.action.fcurves
    slot = anim_data.action_slot
    if slot is None:
        return ()
    from bpy_extras import anim_utils
    bag = anim_utils.action_get_channelbag_for_slot(anim_data.action, slot)
    return bag.fcurves if bag is not None else ()
