"""Drawing into Blender's editors with the ``gpu`` module.  ``gpu`` is imported inside the
functions that draw, never at module level: Blender's background mode (``blender -b``, the pip
``bpy``) has no GPU context and refuses even to build a ``gpu.types.Buffer``, and nothing on
the background path calls these functions."""
