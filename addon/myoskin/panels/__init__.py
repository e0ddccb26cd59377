# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's panels: the View3D sidebar tab and the Properties editor's modifier tab."""
from . import correctives, dynamics, modifier, sidebar

classes = (*sidebar.classes, *dynamics.classes, *correctives.classes, *modifier.classes)
