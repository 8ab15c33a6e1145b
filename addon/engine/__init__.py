"""Rendering: ``base`` (the RenderEngine in Blender's engine list) hands each render to
``final`` (F12, animations, render.py), ``preview`` (material, light and world previews) or
``viewport`` (Rendered shading); ``job`` (export + trace + finish) is shared by everyone who
renders, the Render button included."""
