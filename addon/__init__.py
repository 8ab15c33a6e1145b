"""Glint's Blender side: properties, export, render engine, operator, panels, and the command
line (``cli``, render.py's modules).

``register``/``unregister`` are symmetric and may be repeated (register, unregister,
register again), as Blender does when an extension is disabled and enabled.  They import
what they register: importing this package loads no Blender module, so render.py checks its
arguments (``cli.arguments``) before it loads ``bpy``.
"""

import sys


def _classes():
    from . import operators, properties, ui
    from .engine.base import GlintRenderEngine

    return (*properties.classes, GlintRenderEngine, *operators.classes, *ui.classes)


def renders_one_frame(argv) -> bool:
    """Whether Blender's command line renders one frame and exits (``blender -b file.blend
    -f 7``, the usual render-farm job): then 'auto' weighs the workers' start-up, as
    render.py does for one frame (``core.workers.one_render``).  ``-f 1,3`` or ``-f 1..5``,
    or ``-a``, render more than one."""
    import bpy

    if not bpy.app.background or any(arg in ("-a", "--render-anim") for arg in argv):
        return False
    for flag in ("-f", "--render-frame"):
        if flag in argv:
            index = argv.index(flag)
            frames = argv[index + 1] if index + 1 < len(argv) else ""
            return "," not in frames and ".." not in frames
    return False


def register():
    import bpy

    from ..core import workers
    from . import properties, ui

    for cls in _classes():
        bpy.utils.register_class(cls)
    properties.register_pointers()
    ui.register_panels()
    if renders_one_frame(sys.argv):
        workers.expect_one_render()


def unregister():
    import bpy

    from ..core import workers
    from . import properties, ui

    ui.unregister_panels()
    properties.unregister_pointers()
    for cls in reversed(_classes()):
        bpy.utils.unregister_class(cls)
    # The render worker processes (core.workers) end with the add-on, not with Blender: a
    # disabled or reloaded extension leaves no process behind (the next render starts new
    # ones).
    workers.shutdown()
    from ..core import cluster

    cluster.close_clients()    # (a Dask cluster's connections likewise; its workers stay)

