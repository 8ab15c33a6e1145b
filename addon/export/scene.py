"""The evaluated depsgraph -> a core Scene, in one pure step.

``export_scene`` walks ``depsgraph.object_instances``, so what Blender renders is what Glint
gets: modifiers, parenting, constraints, drivers and collection or geometry-node instances
are already applied, and each instance comes with its own world matrix.  It only reads
Blender data; nothing in the .blend changes.

Visibility: a depsgraph evaluated for rendering (the render engine's) holds exactly the
objects Blender renders.  A viewport depsgraph (``context.evaluated_depsgraph_get()``, which
the panel's Render button uses) holds the viewport's objects, so objects and collections
hidden for render (the camera icon, ``hide_render``) are dropped here; objects disabled in
viewports are absent from it and modifiers run at their viewport settings, as Blender's own
viewport exporters see them.

What is not rendered is never dropped silently: objects that are not spheres, spheres scaled
non-uniformly and non-point lights are each named in one warning.
"""

from __future__ import annotations

import bpy
import numpy as np

from ...core import Scene, SceneError, Sphere
from ..utils.colour import colour_from_blender
from .camera import export_camera
from .errors import ExportError
from .geometry import mesh_sphere, world_sphere
from .lights import export_article_light, export_light
from .materials import export_article_material, export_material
from .world import world_colour

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


class _RenderVisibility:
    """Whether an instance of a viewport depsgraph would be rendered (see module docstring)."""

    def __init__(self, depsgraph):
        self.filter = depsgraph.mode != 'RENDER'
        self.hidden_collections = _collections_hidden_for_render() if self.filter else set()

    def _hidden(self, obj) -> bool:
        collections = obj.users_collection
        return obj.hide_render or bool(collections) and all(
            collection.name in self.hidden_collections for collection in collections)

    def __call__(self, instance) -> bool:
        if not self.filter:
            return True
        if self._hidden(instance.object.original):
            return False
        parent = instance.parent if instance.is_instance else None
        return parent is None or not self._hidden(parent.original)


def instance_name(instance) -> str:
    name = instance.object.name
    if instance.is_instance and instance.parent is not None:
        return f"{name} (instanced by {instance.parent.name})"
    return name


def _main_material(obj, mesh):
    """The material on most of the mesh's faces (None if it has none)."""
    slots = obj.material_slots
    if not slots:
        return None
    index = 0
    if len(slots) > 1:
        indices = np.empty(len(mesh.polygons), np.int64)
        mesh.polygons.foreach_get("material_index", indices)
        index = int(np.bincount(indices).argmax())
    return slots[min(index, len(slots) - 1)].material


class _Skipped:
    """Names of what was not exported, by reason, for one warning per kind."""

    def __init__(self):
        self.by_name = {}

    def add(self, name: str, reason: str) -> None:
        self.by_name.setdefault(name, reason)

    def warning(self, header: str) -> list[str]:
        if not self.by_name:
            return []
        listed = ", ".join(f"{name} ({reason})" for name, reason in self.by_name.items())
        return [f"{header} {len(self.by_name)} skipped: {listed}"]


def export_scene(depsgraph, camera_override=None) -> tuple[Scene, list[str]]:
    """(core Scene, warnings) for an evaluated depsgraph.

    camera_override: the camera object to render through instead of the scene camera (the
    render engine's ``camera_override``).  Raises ExportError, naming the culprit, when the
    scene cannot be rendered at all (no camera, a panoramic camera, invalid values).
    """
    camera = export_camera(depsgraph, camera_override)
    # Article semantics keeps the article's model (its Material and PointLight); the default
    # semantics exports Blender's look in Cycles' units.
    article = depsgraph.scene_eval.glint.semantics == 'ARTICLE'
    light_exporter = export_article_light if article else export_light
    material_exporter = export_article_material if article else export_material
    visible = _RenderVisibility(depsgraph)
    spheres, lights, notes = [], [], []
    skipped_objects, skipped_lights = _Skipped(), _Skipped()
    fits, materials = {}, {}

    for instance in depsgraph.object_instances:
        if not instance.show_self or not visible(instance):
            continue
        obj = instance.object
        name = instance_name(instance)
        matrix = [list(row) for row in instance.matrix_world]
        if obj.type == 'LIGHT':
            try:
                light = light_exporter(obj.data, matrix, name)
            except SceneError as error:
                raise ExportError(f"light '{name}': {error}") from None
            if light is None:
                skipped_lights.add(name, f"{obj.data.type.lower()} light")
                continue
            lights.append(light)
        elif obj.type == 'MESH':
            mesh = obj.data
            key = mesh.as_pointer()
            if key not in fits:
                fits[key] = mesh_sphere(mesh)
            if fits[key] is None:
                skipped_objects.add(name, "not a sphere")
                continue
            placed = world_sphere(fits[key], matrix)
            if placed is None:
                skipped_objects.add(name, "non-uniformly scaled sphere")
                continue
            material = _main_material(obj, mesh)
            material_key = material.name_full if material is not None else None
            if material_key not in materials:
                core_material, note = material_exporter(material)
                materials[material_key] = core_material
                if note:
                    notes.append(note)
            try:
                spheres.append(Sphere(placed[0], placed[1], materials[material_key], name))
            except SceneError as error:
                raise ExportError(f"object '{name}': {error}") from None
        elif obj.type not in NON_RENDERING_TYPES:
            skipped_objects.add(name, f"{obj.type.lower().replace('_', ' ')} object")

    world = depsgraph.scene_eval.world
    colour, world_note = world_colour(world)
    background = colour_from_blender(colour) if article else tuple(colour)

    warnings = skipped_objects.warning("Glint renders spheres only;")
    warnings += skipped_lights.warning("the article semantics renders point lights only;")
    if not spheres:
        warnings.append("no sphere to render: the image shows only the background")
    if not lights:
        warnings.append("no light: only the world's light shows")
    warnings += notes + ([world_note] if world_note else [])
    working_space = getattr(getattr(bpy.data, "colorspace", None), "working_space", None)
    if working_space not in (None, WORKING_SPACE):
        warnings.append(f"the file's working colour space is {working_space}: Glint reads and "
                        f"writes colours as {WORKING_SPACE}")
    scene = Scene(camera=camera, spheres=tuple(spheres), lights=tuple(lights),
                  background=background, ambient=background)
    return scene, warnings
