# SPDX-License-Identifier: GPL-3.0-or-later
"""A stand-in for UILayout (unavailable in background mode) that records what a panel's draw() shows:
("label", text), ("operator", idname), ("prop", attr), ("template_list", list class)."""
import types

import bpy


class FakeLayout:
    def __init__(self, log=None):
        self.log = [] if log is None else log
        self.enabled = True
        self.alert = False

    def _child(self, *args, **kwargs):
        return FakeLayout(self.log)

    row = column = box = split = _child

    def separator(self, *args, **kwargs):
        pass

    def label(self, text="", icon='NONE'):
        self.log.append(("label", text))

    def operator(self, idname, text="", icon='NONE'):
        self.log.append(("operator", idname))
        return types.SimpleNamespace()  # operator properties set by the panel land here

    def prop(self, data, attr, **kwargs):
        assert hasattr(data, attr), (data, attr)
        self.log.append(("prop", attr))

    def prop_search(self, data, attr, search_data, search_attr, **kwargs):
        assert hasattr(data, attr) and hasattr(search_data, search_attr), (attr, search_attr)
        self.log.append(("prop", attr))

    def template_list(self, list_cls, list_id, data, attr, active_data, active_attr, **kwargs):
        assert hasattr(bpy.types, list_cls) and hasattr(data, attr) and hasattr(active_data, active_attr)
        self.log.append(("template_list", list_cls))

    def text(self):
        return "\n".join(t for kind, t in self.log if kind == "label")


def draw_panel(panel_cls, context=None):
    """Run a panel's draw() on a FakeLayout; returns the layout (its .log lists what was drawn)."""
    layout = FakeLayout()
    fake_self = types.SimpleNamespace(layout=layout, hint=getattr(panel_cls, "hint", ""),
                                      draw_step=getattr(panel_cls, "draw_step", None))
    if fake_self.draw_step is not None:
        fake_self.draw_step = types.MethodType(panel_cls.draw_step, fake_self)
    panel_cls.draw(fake_self, context or bpy.context)
    return layout
