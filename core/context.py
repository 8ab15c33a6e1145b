"""Everything a render precomputes once and every tile reads, in three layouts: the scene's
geometry (``core.geometry.Aggregate``), its lights (``Lights``: positions, intensities,
sample points of soft lights and the geometry's terms at each) and its material table
(``Materials``), plus the settings, the bound that lets paths stop early, the Whitted
integrator's shading model (the article's, ``core.article``, or Glint's own,
``core.shading``) and the physically based model (``PhysicalModel``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .geometry import ARTICLE_RULES, DEFAULT_POLICY, HIT_RULES, Aggregate, GeometryPolicy
from .arrays import LightArrays, scene_arrays
from .article import ARTICLE_SHADING
from .bsdf import SurfaceArrays, surface_arrays, translucent_view
from .camera import BlenderCamera, eye_position
from .rays import ARTICLE_OFFSET, RAY_EPSILON, RayStats, SharedOrigin, ray_offsets
from .lights import PreparedLight, prepare_light
from .light_sources import PointLight
from .materials import SurfaceMaterial
from .sampler import fibonacci_sphere
from .scene import Scene
from .settings import RenderSettings
from .shader.program import Register
from .shading import WHITTED_SHADING, WhittedShading
from .vectors import dot

__all__ = ["ARTICLE_OFFSET", "RAY_EPSILON", "RayStats", "ray_offsets", "Lights", "Materials",
           "TraceContext", "make_context"]


@dataclass(frozen=True)
class Materials:
    """The scene's material table in the render precision, indexed by material id:
    ambient, diffuse, specular as (3, M) (one row per channel, ready for ``vectors.take``),
    exponent and reflection (M,)."""

    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    exponent: np.ndarray
    reflection: np.ndarray


@dataclass(frozen=True)
class Lights(LightArrays):
    """The scene's L point lights (``core.arrays.LightArrays``), and per light its sample
    points ``samples[l]`` (S, 3) (one, the centre, for a point light) and the geometry's
    shared-origin terms at each, ``origins[l]`` (S SharedOrigin)."""

    samples: tuple = ()
    origins: tuple = ()


@dataclass(frozen=True)
class LightTerms:
    """One light's factors per material, in the render precision: ambient, diffuse and
    specular (3, M), the material's coefficient times the light's intensity (the products
    the shading would otherwise form per point, with the same rounding), and reflective
    (M,): whether the material's diffuse or specular answer to this light can add anything."""

    ambient: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    reflective: np.ndarray

    @classmethod
    def of(cls, materials: "Materials", ambient, diffuse, specular) -> "LightTerms":
        dtype = materials.ambient.dtype
        column = lambda values: np.asarray(values, dtype)[:, None]  # noqa: E731
        d, s = materials.diffuse * column(diffuse), materials.specular * column(specular)
        reflective = ((dot(materials.diffuse, column(diffuse)) > 0)
                      | (dot(materials.specular, column(specular)) > 0))
        return cls(materials.ambient * column(ambient), d, s, reflective)


@dataclass(frozen=True)
class PhysicalModel:
    """What the physically based model in Cycles' units needs (``core.bsdf``,
    ``core.lights``): the material table's lobes and Blender's lights prepared for
    sampling."""

    surfaces: SurfaceArrays
    lights: tuple[PreparedLight, ...]
    translucent: SurfaceArrays | None = None   # ``bsdf.translucent_view``: None if none is


@dataclass(frozen=True)
class TraceContext:
    settings: RenderSettings
    dtype: np.dtype
    shading: WhittedShading              # the Whitted integrator's shading model (semantics)
    geometry: Aggregate
    lights: Lights
    materials: Materials
    eye: np.ndarray                      # (3,) camera position, float64
    camera_origin: SharedOrigin | None   # the geometry's terms at the eye (perspective only)
    background: np.ndarray               # (3,) float64, seen where rays escape
    ambient: np.ndarray                  # (3,) float64 scene ambient (default semantics)
    path_gain_bound: float               # max colour one bounce can add per unit weight
    # The physically based model where it shades this frame (default semantics, something
    # in the scene physically based or one of Blender's lights), else None: Blinn-Phong alone.
    physical: PhysicalModel | None = None
    paths: object = None                 # core.path.PathSetup: the path integrator's frame

    @functools.cached_property
    def light_terms(self) -> tuple:
        """Per point light, its Blinn-Phong factors per material (``LightTerms``), made from
        this context's own tables on first use (so a context made with another material
        table never shades with stale ones)."""
        lights = self.lights
        return tuple(LightTerms.of(self.materials, *intensities)
                     for intensities in zip(lights.ambient, lights.diffuse, lights.specular))

    @property
    def centers(self):
        """(N, 3) sphere centres, float64."""
        return self.geometry.spheres.centers

    @property
    def radii(self):
        """(N,) sphere radii, float64."""
        return self.geometry.spheres.radii


def make_context(scene: Scene, settings: RenderSettings, dtype, *,
                 root_formula: str | None = None, threads: int = 1,
                 frame=None,
                 geometry_policy: GeometryPolicy = DEFAULT_POLICY) -> TraceContext:
    """The context of a render of ``scene`` in precision ``dtype``.  root_formula:
    'textbook' or 'stable' ray/sphere roots (``core.geometry.ROOT_FORMULAS``); None picks
    the article's textbook formula in article semantics and the stable one otherwise.
    threads: how many threads the geometry's tree may be built on (the same tree for any).
    frame: the ``core.frame.Frame`` that took the scene to ``scene`` (its canonical frame),
    so that shader programs see positions in the scene's own units; None: the same.
    geometry_policy: the thresholds by which the geometry picks its strategies
    (``GeometryPolicy``)."""
    arrays = scene_arrays(scene)
    lights, table = arrays.lights, arrays.materials
    article = settings.semantics == "article"
    if root_formula is None:
        root_formula = "textbook" if article else "stable"
    # (Whether an origin's bins pay depends on how many rays leave it: about one a pixel
    # for the eye and each light sample.)
    geometry = Aggregate(arrays.spheres, arrays.triangles, dtype,
                         rules=ARTICLE_RULES if article else HIT_RULES,
                         root_formula=root_formula, threads=threads,
                         rays_per_origin=scene.camera.width * scene.camera.height,
                         policy=geometry_policy)
    eye = eye_position(scene.camera)
    perspective = not (isinstance(scene.camera, BlenderCamera) and scene.camera.projection == "ORTHO")
    samples = []
    for position, radius in zip(lights.positions, lights.radii):
        if radius > 0 and not article:
            samples.append(position + radius * fibonacci_sphere(settings.light_samples))
        else:
            samples.append(position[None, :])
    origins = tuple(tuple(geometry.shared_origin(p) for p in s) for s in samples)
    total_light = (lights.ambient.sum(axis=0) + lights.diffuse.sum(axis=0)
                   + lights.specular.sum(axis=0) + arrays.ambient)
    if len(table):
        per_material = (table.ambient + table.diffuse + table.specular) * total_light
        gain = float(max(per_material.max(), arrays.background.max()))
    else:
        gain = float(arrays.background.max())
    physical = None
    paths = None
    if not article:
        surfaces = surface_arrays(table.entries, dtype)
        blender = [light for light in scene.lights if not isinstance(light, PointLight)]
        # (A light that emits nothing, ``core.light_sources``, is not sampled; it still makes the
        # scene one of Blender's lights.)
        blender_lights = tuple(prepare_light(light, settings.light_samples, geometry)
                               for light in blender if light.emits)
        if blender or surfaces.any_physical:
            physical = PhysicalModel(surfaces, blender_lights,
                                     translucent=translucent_view(surfaces))
            # Blender's lights have no bound on what a bounce adds (watts, not the article's
            # unit intensities): paths then stop only where their weight is zero.
            gain = np.inf
            if settings.integrator == "path":
                paths = _path_setup(scene, settings, arrays, surfaces, frame, geometry)
    cast = lambda a: np.ascontiguousarray(a, dtype)  # noqa: E731
    materials = Materials(cast(table.ambient.T), cast(table.diffuse.T), cast(table.specular.T),
                          cast(table.exponent), cast(table.reflection))
    return TraceContext(
        settings=settings, dtype=np.dtype(dtype),
        shading=ARTICLE_SHADING if article else WHITTED_SHADING, geometry=geometry,
        lights=Lights(lights.positions, lights.ambient, lights.diffuse, lights.specular,
                      lights.radii, samples=tuple(samples), origins=origins),
        materials=materials,
        eye=eye, camera_origin=geometry.shared_origin(eye) if perspective else None,
        background=arrays.background, ambient=arrays.ambient, path_gain_bound=gain,
        physical=physical, paths=paths,
    )


def path_traced(scene: Scene, settings: RenderSettings) -> bool:
    """Whether the path integrator renders this frame: default semantics asking for it, and
    something in the scene physically based (a SurfaceMaterial or one of Blender's lights;
    else the article's model runs alone, with the Whitted integrator)."""
    if settings.semantics != "default" or settings.integrator != "path":
        return False
    if any(not isinstance(light, PointLight) for light in scene.lights):
        return True
    materials = [sphere.material for sphere in scene.spheres]
    materials += [m for group in scene.sphere_sets + scene.meshes for m in group.materials]
    return any(isinstance(material, SurfaceMaterial) for material in materials)


def _path_setup(scene: Scene, settings: RenderSettings, arrays, surfaces, frame, geometry):
    """The path integrator's frame (``core.path.PathSetup``): Blender's lights, the
    emitting triangles, the materials' and the world's programs."""
    from .emitters import mesh_lights, prepare_lights
    from .path import LIGHT_SAMPLE_RAY, path_setup
    from .surface_points import SurfaceTables
    # (A light scaled to 0 or of size 0 emits nothing, as in Cycles: ``emits``.)
    lights = prepare_lights([light for light in scene.lights if getattr(light, "emits", True)],
                            scene_radius=1.0)
    programs = {row: material.program for row, material in enumerate(arrays.materials.entries)
                if getattr(material, "program", None) is not None}
    tables = SurfaceTables.of(scene, frame) if programs else None
    textured = {row: _emission_estimate(program, tables, geometry)
                for row, program in programs.items() if may_emit(program)}
    mesh = mesh_lights(arrays.triangles, len(arrays.spheres),
                       surfaces.emission.astype(np.float64), textured)
    world = None
    if scene.world is not None:
        from .emitters import world_light
        from .shader.program import run
        from .shader.world import world_points

        def run_world(directions, program):
            # (The map is the world as light samples see it: no ray type, as Cycles
            # evaluates a background for its importance map.)
            value = run(program, world_points(directions, LIGHT_SAMPLE_RAY))
            return np.broadcast_to(np.maximum(value.emission, 0), directions.shape)
        world = world_light(scene.world, run_world, _world_image_size(scene.world))
    return path_setup(settings, lights, mesh, arrays.background,
                      any_holdout=surfaces.any_holdout, programs=programs,
                      surface_tables=tables, world_program=scene.world,
                      pixel=pixel_footprint(scene.camera), world_light=world,
                      transparent_shadows=bool(surfaces.transparency.any()) or any(
                          may_be_transparent(program) for program in programs.values()),
                      frame=frame)


def may_emit(program) -> bool:
    """Whether a material's program may emit light: an Emission (or Background) shader in
    it, or a Principled BSDF whose Emission Color and Strength are not both constant with
    one of them black."""
    for instruction in program.instructions:
        if instruction.node in ("ShaderNodeEmission", "ShaderNodeBackground"):
            return True
        if instruction.node == "ShaderNodeBsdfPrincipled":
            colour = instruction.argument("Emission Color")
            strength = instruction.argument("Emission Strength")
            if isinstance(colour, Register) or isinstance(strength, Register):
                return True
            if not isinstance(colour, tuple) or (float(strength) != 0
                                                 and any(float(c) != 0 for c in colour)):
                return True
    return False


def _emission_estimate(program, tables, geometry):
    """The emission of the material ``program`` at points of its triangles
    (``core.emitters.mesh_lights``' ``textured_estimate``: their normals facing the view)."""
    from .surface_points import program_emission

    def estimate(primitive, barycentrics, points, normal):
        return program_emission(program, tables, geometry, points, normal, normal, primitive,
                                barycentrics)
    return estimate


def may_be_transparent(program) -> bool:
    """Whether a material's program may give a hit some transparency: a Transparent BSDF in
    it, or a Principled BSDF whose Alpha is not a constant 1 (so shadow rays must look
    through its surfaces)."""
    for instruction in program.instructions:
        if instruction.node == "ShaderNodeBsdfTransparent":
            return True
        if instruction.node == "ShaderNodeBsdfPrincipled":
            alpha = instruction.argument("Alpha")
            if isinstance(alpha, Register) or float(alpha) < 1:
                return True
    return False


def _world_image_size(program):
    """(width, height) of the largest image a world program reads (an Environment
    Texture's), or None."""
    sizes = [(value.width, value.height) for instruction in program.instructions
             for _, value in instruction.options if hasattr(value, "width")]
    return max(sizes, key=lambda size: size[0] * size[1]) if sizes else None


def pixel_footprint(camera) -> tuple[float, float]:
    """(base, spread) of a camera ray's footprint: its width is base + spread x distance
    (a perspective pixel's size on the plane at unit depth; an orthographic pixel's size)."""
    from .camera import blender_view_plane
    if isinstance(camera, BlenderCamera):
        plane = blender_view_plane(camera)
        size = 2 * plane.half_width / camera.width
        return (size, 0.0) if camera.projection == "ORTHO" else (0.0, size)
    span = abs(camera.right - camera.left) / max(camera.width - 1, 1)
    return 0.0, span / max(abs(camera.screen_z - camera.eye[2]), 1e-9)
