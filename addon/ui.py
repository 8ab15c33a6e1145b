"""Panels: Glint's settings and Render button in the 3D viewport's sidebar (tab "Glint", any
render engine) and in Render properties (when Glint is the render engine, per Blender's
COMPAT_ENGINES convention), a Glint section in Material properties, and which of Blender's
own panels show with Glint (``register_panels``)."""

from __future__ import annotations

import bpy

from .compat import LIGHT_NODES_ALWAYS, node_tree_in_use
from .engine.base import GlintRenderEngine
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


class GLINT_PT_light_nodes(bpy.types.Panel):
    """A light's node tree (``export.lights.light_nodes``), as Cycles' Nodes panel shows it:
    Use Nodes, then what reaches its Light Output's Surface."""

    bl_label = "Nodes"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "data"
    COMPAT_ENGINES = {GlintRenderEngine.bl_idname}

    @classmethod
    def poll(cls, context):
        return context.light is not None and context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        light = context.light
        if not LIGHT_NODES_ALWAYS:
            layout.prop(light, "use_nodes", icon='NODETREE')
        tree = node_tree_in_use(light, LIGHT_NODES_ALWAYS)
        output = tree.get_output_node('CYCLES') if tree is not None else None
        if output is not None:
            layout.template_node_view(tree, output, output.inputs["Surface"])
        elif tree is not None:
            layout.label(text="No output node")


classes = (GLINT_PT_render, GLINT_PT_render_performance, GLINT_PT_sidebar,
           GLINT_PT_sidebar_performance, GLINT_PT_material, GLINT_PT_light_nodes)


#: Panels marked for every engine that Glint does not show: Blender's type-only light panel
#: and its node variant (Glint shows one Light panel, EEVEE's, which edits what Glint
#: exports: type, colour, temperature, power, exposure, radius, angle, shape and size; its
#: Beam Shape sub-panel, DATA_PT_spot, edits the spot cone) and light probes (Glint does not
#: use them).
EXCLUDED_PANEL_PREFIXES = ('DATA_PT_lightprobe', 'DATA_PT_context_lightprobe')
EXCLUDED_PANELS = {'DATA_PT_light', 'NODE_DATA_PT_light'}


def _excluded(name: str) -> bool:
    return (name in EXCLUDED_PANELS or name.startswith(EXCLUDED_PANEL_PREFIXES)
            or 'FREESTYLE' in name.upper())


def compatible_panels():
    """Blender's panels Glint's users need, as other engines choose them: every panel marked
    for all engines ('BLENDER_RENDER': output, format, colour management, camera, ...), minus
    those that do not apply to Glint (EXCLUDED_PANELS), plus the EEVEE panels that edit what
    Glint exports (material slots and surface, world surface, the light)."""
    included = {'EEVEE_MATERIAL_PT_context_material', 'EEVEE_MATERIAL_PT_surface',
                'EEVEE_WORLD_PT_surface', 'DATA_PT_EEVEE_light'}
    panels = []
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None:
            continue
        name = panel.__name__
        if name in included or ('BLENDER_RENDER' in engines and not _excluded(name)):
            panels.append(panel)
    return panels


def _own_engine_sets(panels) -> None:
    """A panel subclass shares its parent's COMPAT_ENGINES set object unless it defines its
    own (NODE_DATA_PT_light shares DATA_PT_light's): give each panel Glint adds itself to a
    set of its own where that set is shared with a panel Glint leaves out, so adding Glint to
    one does not show the other."""
    chosen = {id(panel) for panel in panels}
    others = {id(panel.COMPAT_ENGINES) for panel in bpy.types.Panel.__subclasses__()
              if id(panel) not in chosen and getattr(panel, "COMPAT_ENGINES", None) is not None}
    for panel in panels:
        if id(panel.COMPAT_ENGINES) in others:
            panel.COMPAT_ENGINES = set(panel.COMPAT_ENGINES)


def register_panels():
    panels = compatible_panels()
    _own_engine_sets(panels)
    for panel in panels:
        panel.COMPAT_ENGINES.add(GlintRenderEngine.bl_idname)


def unregister_panels():
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.discard(GlintRenderEngine.bl_idname)
