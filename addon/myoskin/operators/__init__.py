# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's operators (all callable from Python as bpy.ops.myoskin.*)."""
from . import character, correctives, dynamics, muscles, rig

classes = (*character.classes, *muscles.classes, *rig.classes, *correctives.classes, *dynamics.classes)
