# SPDX-License-Identifier: GPL-3.0-or-later
"""Add-on preferences: defaults for new muscles and extraction."""
import bpy
from bpy.props import FloatProperty, IntProperty

from .panels.common import draw_core_status


ADDON_PACKAGE = __package__  # "myoskin", or "bl_ext.<repo>.myoskin" when installed as an extension


class MyoskinPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_PACKAGE

    # Named for its unit: preferences saved when the spacing was in metres keep that value under the old name, unused.
    section_spacing_radii: FloatProperty(
        name="Section Spacing", description="Distance between cutting planes during extraction, in limb radii "
                                            "(the body's median limb radius; 0 = automatic: 1/80 of the "
                                            "character's largest extent)",
        default=0.0, min=0.0, soft_max=4.0)
    min_confidence: FloatProperty(
        name="Minimum Confidence", description="Extraction drops muscles less significant than this",
        default=0.5, min=0.0, max=1.0)
    min_sections: IntProperty(
        name="Minimum Sections", description="Sections a muscle needs to be kept by extraction",
        default=3, min=1, soft_max=20)
    joints_per_muscle: IntProperty(
        name="Joints per Muscle", description="Muscle joints (deform bones) placed along each muscle's action path",
        default=4, min=1, soft_max=16)
    bulge_factor: FloatProperty(
        name="Bulge Factor", description="How much of a muscle's thickening goes to its belly "
                                         "(0 = uniform; volume stays constant for every value)",
        default=1.0, min=0.0, soft_max=4.0)

    def draw(self, context):
        layout = self.layout
        draw_core_status(layout)
        col = layout.column(align=True)
        col.label(text="Extraction")
        col.prop(self, "section_spacing_radii")
        col.prop(self, "min_confidence")
        col.prop(self, "min_sections")
        col = layout.column(align=True)
        col.label(text="New muscles")
        col.prop(self, "joints_per_muscle")
        col.prop(self, "bulge_factor")


class _Defaults:
    """The preference defaults, for scripts run without the add-on enabled."""
    section_spacing_radii = 0.0
    min_confidence = 0.5
    min_sections = 3
    joints_per_muscle = 4
    bulge_factor = 1.0


def get_preferences(context=None):
    """The add-on's preferences, or their defaults when the add-on is not enabled."""
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_PACKAGE)
    return addon.preferences if addon is not None and addon.preferences is not None else _Defaults()


classes = (MyoskinPreferences,)
