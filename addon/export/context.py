"""The export context: everything one export accumulates, in one object.

Like mitsuba-blender's ``SceneConverter`` and BlendLuxCore's ``Exporter``, the per-concept
exporters (``meshes``, ``pointclouds``, ``instances``, lights, materials) take an
``ExportContext`` instead of passing caches and lists around:

* caches, so that each thing is converted once however often it is used: sphere fits and
  mesh arrays by evaluated mesh (see ``meshes``), core materials by Blender material;
* the objects and lights that were not exported, by reason (``Skipped``), and the notes the
  converters wrote (linked inputs counted as their values, ...), which become the warnings;
* the exported results (spheres, sphere sets, meshes, lights), which ``scene`` assembles
  into one core Scene.

The context reads the camera once, so the exporters can ask how large something appears in
the image (``pixel_size``), which decides whether a sphere-like mesh is drawn as an analytic
sphere (``geometry``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...core import SceneError, SurfaceMaterial
from ...core.camera import blender_view_plane, camera_to_world
from .errors import ExportError
from .images import ImageExporter
from .materials import export_article_material, export_material


def instance_name(instance) -> str:
    """How warnings and sets name an instance: 'object (instanced by parent)', or the object's
    name for its own evaluated geometry (a curve's mesh is an instance of the curve)."""
    name = instance.object.name
    if instance.is_instance and instance.parent is not None and instance.parent.name != name:
        return f"{name} (instanced by {instance.parent.name})"
    return name


class Skipped:
    """Names of what was not exported, by reason, for one warning per kind."""

    def __init__(self):
        self.by_name: dict[str, str] = {}

    def add(self, name: str, reason: str) -> None:
        self.by_name.setdefault(name, reason)

    def __contains__(self, name: str) -> bool:
        return name in self.by_name

    def warning(self, header: str) -> list[str]:
        if not self.by_name:
            return []
        listed = ", ".join(f"{name} ({reason})" for name, reason in self.by_name.items())
        return [f"{header} {len(self.by_name)} skipped: {listed}"]


@dataclass
class CameraFootprint:
    """How large one pixel is, in scene units, at a point of the scene (the camera's view).

    Perspective: a pixel spans ``pixel_at_unit_depth * depth`` at depth ``depth`` along the view
    axis; orthographic: ``pixel_at_unit_depth`` everywhere.  With non-square pixels the smaller
    side counts (the finer sampling is the one that shows more).
    """

    rotation: np.ndarray          # (3, 3) camera to world, unit columns
    translation: np.ndarray       # (3,)
    pixel_at_unit_depth: float
    orthographic: bool
    clip_start: float
    clip_end: float

    @classmethod
    def unbounded(cls) -> "CameraFootprint":
        """No camera to judge from: every pixel is infinitely large (nothing is resolved)."""
        return cls(np.eye(3), np.zeros(3), np.inf, True, 0.0, np.inf)

    @classmethod
    def of(cls, camera) -> "CameraFootprint":
        plane = blender_view_plane(camera)
        rotation, translation = camera_to_world(camera)
        pixel = min(2.0 * plane.half_width / camera.width,
                    2.0 * plane.half_height / camera.height)
        return cls(rotation, translation, pixel, camera.projection == "ORTHO",
                   camera.clip_start, camera.clip_end)

    def pixel_size(self, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """(N,) the size of a pixel, in scene units, at the nearest visible point of each
        sphere (centres (N, 3), radii (N,)); inf for spheres wholly outside the clip range,
        which no pixel sees."""
        depth = (np.asarray(centers, np.float64) - self.translation) @ -self.rotation[:, 2]
        radii = np.asarray(radii, np.float64)
        hidden = (depth + radii < self.clip_start) | (depth - radii > self.clip_end)
        if self.orthographic:
            size = np.full(depth.shape, self.pixel_at_unit_depth)
        else:
            nearest = np.maximum(depth - radii, self.clip_start)
            size = self.pixel_at_unit_depth * nearest
        return np.where(hidden, np.inf, size)


@dataclass
class ExportContext:
    """One export's caches, results and reports (module docstring)."""

    camera: object                     # the exported core camera
    footprint: CameraFootprint
    materials: dict = field(default_factory=dict)      # material name_full (or None) -> core
    sphere_fits: dict = field(default_factory=dict)    # evaluated mesh key -> SphereFit | None
    mesh_arrays: dict = field(default_factory=dict)    # evaluated mesh key -> MeshArrays
    skipped_objects: Skipped = field(default_factory=Skipped)
    skipped_lights: Skipped = field(default_factory=Skipped)
    notes: list = field(default_factory=list)
    spheres: list = field(default_factory=list)        # core.Sphere
    sphere_sets: list = field(default_factory=list)    # core.SphereSet
    meshes: list = field(default_factory=list)         # core.TriangleMesh
    lights: list = field(default_factory=list)         # core lights
    article: bool = False     # article semantics: the article's Material and PointLight
    view_layer: object = None  # the evaluated view layer, for holdouts (``is_holdout``)
    frame: int = 0            # the scene frame (animated images' frame)
    images: object = None     # the ImageExporter, made on first use (``image_exporter``)

    @classmethod
    def for_camera(cls, camera, judged_from=..., article: bool = False) -> "ExportContext":
        """A context rendering through ``camera`` whose sphere-or-triangles rule judges from
        ``judged_from`` (default: the same camera; None: no camera, nothing is resolved);
        article: the article semantics' materials."""
        judge = camera if judged_from is ... else judged_from
        footprint = CameraFootprint.of(judge) if judge is not None else \
            CameraFootprint.unbounded()
        return cls(camera=camera, footprint=footprint, article=article)

    def is_holdout(self, obj) -> bool:
        """Whether an evaluated object is a holdout in the view layer (Object > Visibility >
        Holdout, or in a holdout collection); never in the article semantics, whose model has
        no holdouts (``ignored`` names them)."""
        if self.article or self.view_layer is None:
            return False
        return bool(obj.holdout_get(view_layer=self.view_layer))

    def material(self, material, owner: str, holdout: bool = False):
        """The core material for a bpy Material (None: Blender's default surface), converted
        once per export; the converter's note, if any, is kept for the warnings.  An invalid
        value raises ExportError naming ``owner`` (the object), the material and the field.
        holdout: for a holdout object (``is_holdout``): the same material marked
        ``holdout_object``."""
        key = material.name_full if material is not None else None
        if holdout:
            held = (key, "holdout")
            if held not in self.materials:
                surface = self.material(material, owner)
                if isinstance(surface, SurfaceMaterial):
                    surface = dataclasses.replace(surface, holdout_object=True)
                else:
                    self.note(f"holdout object '{owner}': its Custom (article) material "
                              f"'{key}' is not held out")
                self.materials[held] = surface
            return self.materials[held]
        if key not in self.materials:
            try:
                if self.article:
                    core_material, note = export_article_material(material, owner)
                else:
                    core_material, note = export_material(material, owner, self)
            except SceneError as error:
                raise ExportError(f"object '{owner}', material '{key}': {error}") from None
            self.materials[key] = core_material
            if note:
                self.note(note)
        return self.materials[key]

    def image_exporter(self):
        """The export's ``images.ImageExporter``: each image read once, its warnings kept
        as notes."""
        if self.images is None:
            self.images = ImageExporter(self.frame, self.note)
        return self.images

    def note(self, text: Optional[str]) -> None:
        if text and text not in self.notes:
            self.notes.append(text)

    def skip(self, name: str, reason: str) -> None:
        self.skipped_objects.add(name, reason)

    @property
    def has_geometry(self) -> bool:
        return bool(self.spheres or self.sphere_sets or self.meshes)
