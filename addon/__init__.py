"""Glint's Blender side: properties, export, render engine, operator, panels.

``register``/``unregister`` are symmetric and may be repeated (register, unregister,
register again), as Blender does when an extension is disabled and enabled.
"""

import sys

import bpy

from ..core import cluster, workers
from . import operators, properties, ui
from .engine import final

_classes = (
    *properties.classes,
    final.GlintRenderEngine,
    *operators.classes,
    *ui.classes,
)


def renders_one_frame(argv) -> bool:
    """Whether Blender's command line renders one frame and exits (``blender -b file.blend
    -f 7``, the usual render-farm job): then 'auto' weighs the workers' start-up, as
    render.py does for one frame (``core.workers.one_render``).  ``-f 1,3`` or ``-f 1..5``,
    or ``-a``, render more than one."""
    if not bpy.app.background or any(arg in ("-a", "--render-anim") for arg in argv):
        return False
    for flag in ("-f", "--render-frame"):
        if flag in argv:
            index = argv.index(flag)
            frames = argv[index + 1] if index + 1 < len(argv) else ""
            return "," not in frames and ".." not in frames
    return False


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    properties.register_pointers()
    final.register_panels()
    if renders_one_frame(sys.argv):
        workers.expect_one_render()


def unregister():
    final.unregister_panels()
    properties.unregister_pointers()
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
    # The render worker processes (core.workers) end with the add-on, not with Blender: a
    # disabled or reloaded extension leaves no process behind (the next render starts new
    # ones).
    workers.shutdown()
    cluster.close_clients()    # (a Dask cluster's connections likewise; its workers stay)

