"""Glint's Blender side: properties, export, render engine, operator, panels.

``register``/``unregister`` are symmetric and may be repeated (register, unregister,
register again), as Blender does when an extension is disabled and enabled.
"""

import bpy

from ..core import workers
from . import operators, properties, ui
from .engine import final

_classes = (
    *properties.classes,
    final.GlintRenderEngine,
    *operators.classes,
    *ui.classes,
)


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    properties.register_pointers()
    final.register_panels()


def unregister():
    final.unregister_panels()
    properties.unregister_pointers()
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
    # The render worker processes (core.workers) end with the add-on, not with Blender: a
    # disabled or reloaded extension leaves no process behind (the next render starts new
    # ones).
    workers.shutdown()

