"""Glint in Blender's engine list: the RenderEngine, which hands each kind of render to the
module that makes it: ``final`` (F12, animations, ``blender -b file -f/-a``, render.py),
``preview`` (material, light and world previews) and ``viewport`` (Rendered shading)."""

from __future__ import annotations

import bpy

from .final import render_final
from .passes import register_passes
from .preview import render_preview
from .viewport import ViewportEngine


class GlintRenderEngine(bpy.types.RenderEngine):
    bl_idname = "GLINT"
    bl_label = "Glint"
    # Material, light and world previews: addon.engine.preview.
    bl_use_preview = True
    # The viewport's Rendered (and Material Preview) shading is Glint's own, through
    # view_update / view_draw (addon.engine.viewport), not EEVEE's.
    bl_use_eevee_viewport = False
    # Glint reads the materials' shader nodes (``addon.export.materials``): the Shader Editor
    # must be available to edit them.
    bl_use_shading_nodes_custom = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._viewport = None

    def __del__(self):
        # Blender frees a viewport's engine when Rendered shading ends: stop its worker.  An
        # engine whose Blender data is already gone (a finished F12) raises ReferenceError on
        # any attribute, and has no viewport to stop.
        try:
            viewport = self._viewport
        except (AttributeError, ReferenceError):
            return
        if viewport is not None:
            viewport.free()

    def _viewport_engine(self):
        if self._viewport is None:
            self._viewport = ViewportEngine()
        return self._viewport

    def view_update(self, context, depsgraph):
        self._viewport_engine().view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        self._viewport_engine().view_draw(self, context, depsgraph)

    def render(self, depsgraph):
        if self.is_preview:
            render_preview(self, depsgraph)
        else:
            render_final(self, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        register_passes(self, scene, renderlayer)
