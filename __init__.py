"""Glint: a Python + NumPy ray tracer for spheres and point lights, as a Blender extension.

This directory is the extension package (``blender_manifest.toml`` beside this file):
``core/`` is the tracer (no bpy), ``addon/`` is everything Blender sees.  Blender imports
the package under its own name (``bl_ext.<repository>.glint``), so everything inside uses
relative imports.  Outside Blender the package can be imported too (``render.py`` loads it
as ``glint``); ``addon`` is imported only when registering, so ``glint.core`` works without
bpy.
"""


def register():
    from . import addon

    addon.register()


def unregister():
    from . import addon

    addon.unregister()
