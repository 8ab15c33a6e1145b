"""The evaluated depsgraph -> a core Scene, in one pure step.

``export_scene`` walks ``depsgraph.object_instances``, so what Blender renders is what Glint
gets: modifiers, parenting, constraints, drivers and collection or geometry-node instances
are already applied, and each instance comes with its own world matrix.  When the only
instancers are Geometry Nodes objects read in bulk (``instances.InstanceExporter.covers``),
``depsgraph.objects`` is visited instead, so a million instances cost no Python step each.
It only reads Blender data; nothing in the .blend changes.

Visibility: a depsgraph evaluated for rendering (the render engine's) holds exactly the
objects Blender renders.  A viewport depsgraph (``context.evaluated_depsgraph_get()``, which
the panel's Render button uses) holds the viewport's objects, so objects and collections
hidden for render (the camera icon, ``hide_render``) and instancers not shown in renders
(``show_instancer_for_render``, e.g. a particle emitter) are dropped here; objects disabled in
viewports are absent from it and modifiers run at their viewport settings, as Blender's own
viewport exporters see them.

Each instance goes to the exporter of its concept, all sharing one ``ExportContext`` (the
caches, the results, the skipped lists and the notes; ``context``):

* MESH instances (mesh objects, and the meshes that curve, text, surface and metaball
  objects evaluate to) -> ``meshes.MeshExporter``: analytic spheres where the render cannot
  tell them from the mesh (``geometry``), triangle meshes otherwise, each evaluated mesh read
  once and instanced;
* POINTCLOUD -> ``pointclouds``: a sphere set;
* Geometry Nodes instances -> ``instances.InstanceExporter``, read in bulk from the
  instancer's evaluated geometry instead of one Python step per instance;
* LIGHT -> ``lights``; the camera -> ``camera``; materials -> ``materials`` through the
  context's cache; the world -> ``world``.

The default semantics exports Blender's look in Cycles' units (shader nodes, every light
type, the world's radiance, scene-linear); the article semantics keeps the article's model
(its Material and PointLight, sRGB-encoded colours).  What is not rendered is never dropped
silently: other object types, zero-scale instances and (article semantics) non-point lights
are each named in one warning.
"""

from __future__ import annotations

from typing import Optional

import bpy

from ...core import Scene, SceneError
from ..utils.colour import colour_from_blender
from .camera import export_camera
from .context import ExportContext, instance_name
from .errors import ExportError
from .instances import InstanceExporter, InstanceWalk
from .lights import article_light_problem, colour_note, export_article_light, power_note
from .lights import export_light as export_cycles_light
from .meshes import EVALUATED_AS_MESH, MeshExporter
from .pointclouds import export_point_cloud
from .world import export_world

#: The scene-linear space Glint's sRGB conversions assume (Blender's default; Blender 5.0
#: lets a file choose another).
WORKING_SPACE = "Linear Rec.709"

#: Object types that never draw anything in a render, so skipping them needs no warning.
NON_RENDERING_TYPES = {'CAMERA', 'EMPTY', 'LIGHT_PROBE', 'SPEAKER', 'ARMATURE', 'LATTICE'}


def _collections_hidden_for_render() -> set:
    """Names of collections whose content is not rendered (hidden themselves or by a parent)."""
    hidden = set()
    for collection in bpy.data.collections:
        if collection.hide_render:
            hidden.add(collection.name)
            hidden.update(child.name for child in collection.children_recursive)
    return hidden


#: A child of an object instancing these is hidden in renders (Blender's depsgraph hides
#: the original in render mode, ``deg_object_hide_original``), shown in viewports.
INSTANCING_PARENTS = ('VERTS', 'FACES')


def _collection_members(hidden_names: set) -> tuple[set, set]:
    """(pointers of the objects directly in a collection named in ``hidden_names``, those
    directly in any other collection or a scene's own collection), in one pass over the
    collections.  ``Object.users_collection`` answers the same for one object by walking
    every collection (a Python loop in Blender's ``_bpy_types``): asked once per object, the
    viewport's export of 30,000 objects took 67 s in it."""
    hidden, shown = set(), set()
    for collection in bpy.data.collections:
        members = hidden if collection.name in hidden_names else shown
        members.update(obj.as_pointer() for obj in collection.objects)
    for scene in bpy.data.scenes:
        shown.update(obj.as_pointer() for obj in scene.collection.objects)
    return hidden, shown


class _RenderVisibility:
    """Whether an instance of a viewport depsgraph would be rendered (see module docstring)."""

    def __init__(self, depsgraph):
        self.filter = depsgraph.mode != 'RENDER'
        self.hidden_collections = _collections_hidden_for_render() if self.filter else set()
        self.hidden_objects: dict[int, bool] = {}  # original object pointer -> hidden
        self._members: Optional[tuple[set, set]] = None

    def _hidden(self, obj) -> bool:
        """Hidden for render itself, or every collection holding it is (or is inside) one
        hidden for render; once per object."""
        key = obj.as_pointer()
        hidden = self.hidden_objects.get(key)
        if hidden is None:
            hidden = self.hidden_objects[key] = obj.hide_render or \
                self._only_in_hidden_collections(key)
        return hidden

    def _only_in_hidden_collections(self, key: int) -> bool:
        if not self.hidden_collections:
            return False
        if self._members is None:
            self._members = _collection_members(self.hidden_collections)
        in_hidden, in_shown = self._members
        return key in in_hidden and key not in in_shown

    def __call__(self, instance) -> bool:
        if not self.filter:
            return True
        # A particle system renders its instance object even when that object itself is
        # hidden for render (the usual set-up: the source is hidden, its copies are not), as
        # F12 does; only the emitter's visibility counts.
        original = instance.object.original
        by_particles = instance.is_instance and instance.particle_system is not None
        if not by_particles and self._hidden(original):
            return False
        if not instance.is_instance and original.is_instancer and \
                not original.show_instancer_for_render:
            return False  # an emitter or instancer Blender does not render itself
        if not instance.is_instance and original.parent is not None and \
                original.parent.instance_type in INSTANCING_PARENTS:
            return False  # instanced by its parent's vertices or faces: only the copies render
        parent = instance.parent if instance.is_instance else None
        return parent is None or not self._hidden(parent.original)




def export_light(context, obj, matrix, name: str) -> None:
    """A light instance -> a core light in the context (``lights``: every type in Cycles'
    units in default semantics, point lights only in the article's), or a skipped entry."""
    try:
        if context.article:
            light = export_article_light(obj.data, matrix, name)
        else:
            light, note = export_cycles_light(obj.data, matrix, name, context)
            context.note(note)
    except SceneError as error:
        raise ExportError(str(error)) from None  # the core's message names the light
    if light is None:
        problem = article_light_problem(obj.data) if obj.data.type == 'POINT' else None
        if problem:
            context.note(f"light '{name}': {problem}: the article semantics leaves it out")
        else:
            context.skipped_lights.add(name, f"{obj.data.type.lower()} light")
        return
    context.note(power_note(obj.data, name))
    context.note(colour_note(obj.data, name))
    context.lights.append(light)


class _ObjectEntry:
    """An evaluated object as the depsgraph walk's entry for it (the fields of
    ``DepsgraphObjectInstance`` the exporters read), for exports that skip the walk."""

    is_instance = False
    parent = None
    show_self = True

    def __init__(self, obj):
        self.object = obj
        self.matrix_world = obj.matrix_world


def _export_entry(context, meshes, instance, visible) -> None:
    """One depsgraph entry (an object or an instance) to the exporter of its type."""
    if not instance.show_self or not visible(instance):
        return
    obj = instance.object
    kind = obj.type
    if kind == 'MESH':
        meshes.add(instance)
    elif kind == 'LIGHT':
        export_light(context, obj, [list(row) for row in instance.matrix_world],
                     instance_name(instance))
    elif kind == 'POINTCLOUD':
        export_point_cloud(context, obj, instance.matrix_world, instance_name(instance))
    elif kind not in NON_RENDERING_TYPES and kind not in EVALUATED_AS_MESH:
        context.skip(instance_name(instance), f"{kind.lower().replace('_', ' ')} object")


def _render_camera(depsgraph, camera_override):
    """The scene's render camera as a core camera, or None when it has none (or one Glint
    cannot render through)."""
    try:
        return export_camera(depsgraph, camera_override)
    except ExportError:
        return None


def export_scene(depsgraph, camera_override=None, *, view_camera=None
                 ) -> tuple[Scene, list[str]]:
    """(core Scene, warnings) for an evaluated depsgraph.

    camera_override: the camera object to render through instead of the scene camera (the
    render engine's ``camera_override``).  view_camera: a core camera to use instead of any
    Blender camera (the viewport renders its own view, with or without a scene camera).  The
    sphere-or-triangles rule (``geometry``) always judges from the scene's render camera, so
    the viewport draws the shapes the final render will; without one, sphere-like meshes are
    analytic spheres.
    Raises ExportError, naming the culprit, when the scene cannot be rendered at all (no
    camera, a panoramic camera, invalid values).
    """
    article = depsgraph.scene_eval.glint.semantics == 'ARTICLE'
    if view_camera is None:
        camera = export_camera(depsgraph, camera_override)
        context = ExportContext.for_camera(camera, article=article)
    else:
        context = ExportContext.for_camera(view_camera, _render_camera(depsgraph,
                                                                       camera_override),
                                           article=article)
    context.view_layer = depsgraph.view_layer_eval
    context.frame = depsgraph.scene_eval.frame_current
    visible = _RenderVisibility(depsgraph)
    meshes = MeshExporter(context)
    bulk = InstanceExporter(context, meshes, visible)

    objects = list(depsgraph.objects)
    if bulk.covers(objects, depsgraph.view_layer_eval.objects):
        # Nothing but bulk-read instancers makes instances: the objects themselves suffice.
        for obj in objects:
            entry = _ObjectEntry(obj)
            bulk.export_instancer(entry, obj)
            _export_entry(context, meshes, entry, visible)
    else:
        walk = InstanceWalk(bulk, meshes, visible,
                            lambda entry: _export_entry(context, meshes, entry, visible),
                            particles_matter=visible.filter)
        for instance in depsgraph.object_instances:
            if instance.is_instance:
                walk(instance)
            else:
                _export_entry(context, meshes, instance, visible)
    meshes.finish()

    world = depsgraph.scene_eval.world
    colour, world_program, world_note = export_world(world, context)
    if article:
        world_program = None
    background = colour_from_blender(colour) if article else tuple(colour)
    try:
        Scene(camera=context.camera, background=background)  # checks the world's colour alone
    except SceneError as error:
        raise ExportError(f"world '{world.name}' (Background colour x Strength): "
                          f"{error}") from None
    context.note(world_note)

    warnings = context.skipped_objects.warning("Glint renders meshes, spheres and point "
                                               "clouds;")
    warnings += context.skipped_lights.warning("the article semantics renders point lights "
                                               "only;")
    if not context.has_geometry:
        warnings.append("nothing to render: no sphere, mesh or point cloud; the image shows "
                        "only the background")
    if not context.lights:
        warnings.append("no light: only the world's light shows")
    warnings += context.notes
    working_space = getattr(getattr(bpy.data, "colorspace", None), "working_space", None)
    if working_space not in (None, WORKING_SPACE):
        warnings.append(f"the file's working colour space is {working_space}: Glint reads and "
                        f"writes colours as {WORKING_SPACE}")
    scene = Scene(camera=context.camera, spheres=tuple(context.spheres),
                  lights=tuple(context.lights), background=background, ambient=background,
                  sphere_sets=tuple(context.sphere_sets), meshes=tuple(context.meshes),
                  world=world_program)
    # What the core renders otherwise than Blender holds it (docs/invalid-data.md).
    return scene, warnings + list(scene.warnings)
