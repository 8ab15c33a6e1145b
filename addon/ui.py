"""Panels: Glint's settings and Render button in the 3D viewport's sidebar (tab "Glint", any
render engine) and in Render properties (when Glint is the render engine, per Blender's
COMPAT_ENGINES convention), and a Glint section in Material properties."""

from __future__ import annotations

import bpy

from .engine.final import GlintRenderEngine
from .operators import GLINT_OT_render


def draw_render_settings(layout, scene) -> None:
    settings = scene.glint
    layout.use_property_split = True
    layout.use_property_decorate = False

    column = layout.column()
    column.prop(settings, "semantics")
    column.prop(settings, "precision")
    column.prop(settings, "max_depth")

    column = layout.column()
    column.prop(settings, "anti_aliasing")
    row = column.row()
    row.active = settings.anti_aliasing != 'OFF'
    row.prop(settings, "samples")
    row = column.row()
    row.active = settings.semantics == 'DEFAULT'
    row.prop(settings, "light_samples")
    row = column.row()
    row.active = settings.semantics == 'DEFAULT'
    row.prop(settings, "world_samples")

    layout.prop(scene.render, "film_transparent", text="Transparent Film")
    layout.prop(settings, "image_name")
    layout.operator(GLINT_OT_render.bl_idname, icon='RENDER_STILL')


def draw_performance(layout, scene) -> None:
    """How tiles render at once: Glint's parallelism, and Blender's own Performance > Threads,
    which sets how many (threads or worker processes; ``job.render_settings``)."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    layout.prop(scene.glint, "parallelism")
    layout.prop(scene.glint, "cluster_address")
    render = scene.render
    column = layout.column()
    column.prop(render, "threads_mode")
    row = column.row()
    row.enabled = render.threads_mode == 'FIXED'
    row.prop(render, "threads")


class RenderPropertiesPanel:
    """Placement of Glint's panels in Render properties: shown while Glint is the engine."""

    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {GlintRenderEngine.bl_idname}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class SidebarPanel:
    """Placement of Glint's panels in the 3D viewport's sidebar, tab "Glint": any engine."""

    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Glint"

    @classmethod
    def poll(cls, context):
        return context.scene is not None


class GLINT_PT_render(RenderPropertiesPanel, bpy.types.Panel):
    bl_label = "Glint"

    def draw(self, context):
        draw_render_settings(self.layout, context.scene)


class GLINT_PT_sidebar(SidebarPanel, bpy.types.Panel):
    bl_label = "Glint"

    def draw(self, context):
        draw_render_settings(self.layout, context.scene)


class GLINT_PT_render_performance(RenderPropertiesPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_parent_id = "GLINT_PT_render"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        draw_performance(self.layout, context.scene)


class GLINT_PT_sidebar_performance(SidebarPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_parent_id = "GLINT_PT_sidebar"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        draw_performance(self.layout, context.scene)


class GLINT_PT_material(bpy.types.Panel):
    """Shown with every engine: the sidebar's Render button works whichever is selected."""

    bl_label = "Glint"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        material = context.material
        return material is not None and not material.is_grease_pencil

    def draw_header(self, context):
        self.layout.prop(context.material.glint, "use_custom", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.material.glint
        column = layout.column()
        column.active = settings.use_custom
        for name in ("ambient", "diffuse", "specular", "shininess", "reflection"):
            column.prop(settings, name)
        if not settings.use_custom:
            layout.label(text="Off: derived from the Principled BSDF or Viewport Display",
                         icon='INFO')


classes = (GLINT_PT_render, GLINT_PT_render_performance, GLINT_PT_sidebar,
           GLINT_PT_sidebar_performance, GLINT_PT_material)
