"""Render passes: what each pixel's camera ray hit first.

``render(scene, settings, passes=True)`` fills a ``PrimaryPasses`` beside the image, tile by
tile (each tile writes only its own slice, like the image).  Path-traced frames take them,
as Cycles does, from each pixel's first sample: its tiles' first jobs carry them beside
their sums (``first_hit_channels``).  Other frames trace the tile's pixel centres once more
to their first hits (``fill_tile_passes``: ``trace_bundle(record_primary=True,
primary_only=True)``, which reads t, the primitive and the normal at the bounce loop's first
hit and shades nothing).  Either way passes are one ray's, not averaged over anti-aliasing
samples, as depth, normals and indices cannot be meaningfully averaged across an edge.

Conventions are Blender's render passes':
* depth: distance along the camera's view axis (Blender's Depth/Z pass, as Cycles writes it),
  ``MISSED_DEPTH`` where the ray hit nothing (Blender's value for the background);
* position: the hit point in world space (Position pass); 0 where missed;
* normal: the unit world-space shading normal, turned towards the camera (Normal pass);
  0 where missed;
* primitive: the global primitive id of what was hit (``core.arrays``: the scene's spheres,
  then each SphereSet's, then each mesh's triangles instance by instance), -1 where missed;
  ``primitive_sources`` maps it to the scene entry it belongs to (Object Index);
* material: the scene's material table index of the hit's material, -1 where missed
  (Material Index);
* emission (when asked for, ``PrimaryPasses.empty(..., emission=True)``): the emission the
  pixel centre's camera path meets (its first hit, and what it sees straight through
  Transparent BSDFs), as Cycles' Emission pass holds it; emission seen in mirrors or through
  refraction is not in it (Cycles counts that as glossy or transmission light), nor is the
  world.  It needs the whole camera path, so the passes' trace then follows the render's
  max_depth instead of stopping at the first hit.

The tracer works in the scene's canonical frame (``core.frame``); positions and depths are
mapped back to world units here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import BlenderCamera, camera_rays, camera_to_world
from .trace import trace_bundle

#: Blender's Depth pass value where nothing was hit.
MISSED_DEPTH = 1e10


@dataclass
class PrimaryPasses:
    """(H, W[, 3]) float32 arrays (int32 for primitive and material), row 0 = top; see the
    module docstring."""

    depth: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    primitive: np.ndarray
    material: np.ndarray
    emission: np.ndarray | None = None   # (H, W, 3) float32 when asked for

    #: depth, position and normal float32 (1 + 3 + 3), primitive and material int32.
    BYTES_PER_PIXEL = 4 * (1 + 3 + 3) + 4 + 4
    #: The emission pass, float32 RGB.
    EMISSION_BYTES_PER_PIXEL = 4 * 3

    @classmethod
    def empty(cls, width: int, height: int, emission: bool = False) -> "PrimaryPasses":
        return cls(np.full((height, width), MISSED_DEPTH, np.float32),
                   np.zeros((height, width, 3), np.float32),
                   np.zeros((height, width, 3), np.float32),
                   np.full((height, width), -1, np.int32),
                   np.full((height, width), -1, np.int32),
                   np.zeros((height, width, 3), np.float32) if emission else None)


def view_axis(camera) -> np.ndarray:
    """(3,) the unit direction the camera looks along."""
    if isinstance(camera, BlenderCamera):
        return -camera_to_world(camera)[0][:, 2]
    return np.array([0.0, 0.0, np.sign(camera.screen_z - camera.eye[2]) or -1.0])


def fill_tile_passes(passes: PrimaryPasses, ctx, camera, tile, stats, world=None) -> None:
    """Trace the pixel centres of tile (y0, y1, x0, x1) to their first hit and write that
    tile's part of ``passes``.  camera, ctx: the render's (canonical frame); world: the
    ``core.frame.Frame`` mapping the render's frame to the scene's (None: the same)."""
    y0, y1, x0, x1 = tile
    rows, cols = np.mgrid[y0:y1, x0:x1]
    rows, cols = rows.ravel(), cols.ravel()
    rays = camera_rays(camera, cols + 0.5, rows + 0.5, ctx.dtype)
    emission = passes.emission is not None
    # The first hit is all the other passes need, not its shading (its shadow rays and the
    # world's cost a supersampled corpus scene 0.8 s of 3.8); emission follows the path.
    traced = trace_bundle(ctx, rays, stats, record_primary=True, record_emission=emission,
                          primary_only=not emission)
    hits = traced.primary
    channels = first_hit_channels(camera, rays.origins, rays.directions, hits.t,
                                  hits.primitive, hits.material, hits.normal, world)
    store_first_hits(passes, tile, channels.reshape(y1 - y0, x1 - x0, PASS_CHANNELS))
    if emission:
        passes.emission[y0:y1, x0:x1] = traced.emission.T.reshape(y1 - y0, x1 - x0, 3)


#: The channels ``first_hit_channels`` packs a pixel's passes into, as floats a tile's sums
#: can carry: depth, position (3), normal (3), then the primitive and material ids each as
#: two 16-bit halves (exact in float32).
PASS_CHANNELS = 11


def first_hit_channels(camera, origins, directions, t, primitive, material, normal,
                       world=None) -> np.ndarray:
    """(n, PASS_CHANNELS) the passes of n camera rays (origins (3, n) or (3, 1), directions
    (3, n), in the render's frame) from their first hits: t (n,) (anything where missed),
    primitive and material (n,) ids (-1 where missed), normal (3, n)."""
    hit = primitive >= 0
    t = np.where(hit, t, 0.0).astype(np.float64)
    position = origins + t * directions            # (3, n)
    # Perspective rays start at the eye, orthographic ones on the camera's plane: either way
    # the view-axis depth is t times the direction's component along the axis.
    depth = t * (view_axis(camera) @ directions)
    if world is not None:
        position = position / world.scale + world.centre[:, None]
        depth = depth / world.scale
    ids = np.stack([primitive, material]).astype(np.int64) + 1   # >= 0
    return np.concatenate([np.where(hit, depth, MISSED_DEPTH)[None],
                           np.where(hit, position, 0.0), normal,
                           ids[:1] >> 16, ids[:1] & 0xFFFF,
                           ids[1:] >> 16, ids[1:] & 0xFFFF]).T


def store_first_hits(passes: PrimaryPasses, tile, channels: np.ndarray) -> None:
    """Write tile (y0, y1, x0, x1)'s ``first_hit_channels`` (h, w, PASS_CHANNELS) into
    ``passes``."""
    y0, y1, x0, x1 = tile
    passes.depth[y0:y1, x0:x1] = channels[..., 0]
    passes.position[y0:y1, x0:x1] = channels[..., 1:4]
    passes.normal[y0:y1, x0:x1] = channels[..., 4:7]
    ids = np.rint(channels[..., 7:11]).astype(np.int64)
    passes.primitive[y0:y1, x0:x1] = (ids[..., 0] << 16) + ids[..., 1] - 1
    passes.material[y0:y1, x0:x1] = (ids[..., 2] << 16) + ids[..., 3] - 1


def primitive_sources(scene) -> np.ndarray:
    """(P,) for each global primitive id, the index of the scene entry it belongs to, in the
    order: ``scene.spheres`` (one entry each), ``scene.sphere_sets`` (one each), then every
    instance of every mesh (one entry per transform), as ``entry_names`` lists them."""
    counts = [np.ones(len(scene.spheres), np.intp)]
    counts.append(np.array([len(s.radii) for s in scene.sphere_sets], np.intp))
    for mesh in scene.meshes:
        counts.append(np.full(len(mesh.transforms), len(mesh.triangles), np.intp))
    counts = np.concatenate(counts) if counts else np.zeros(0, np.intp)
    return np.repeat(np.arange(len(counts)), counts)


def entry_names(scene) -> list[str]:
    """The names of the entries ``primitive_sources`` indexes (a mesh's once per instance)."""
    names = [s.name for s in scene.spheres] + [s.name for s in scene.sphere_sets]
    for mesh in scene.meshes:
        names += [mesh.name] * len(mesh.transforms)
    return names


def material_entries(scene) -> list:
    """The scene's material table in ``core.arrays``' order (each material once, by identity,
    in primitive order: spheres, sphere sets, meshes), so a pass's material id names its
    core material."""
    entries, seen = [], set()
    materials = [s.material for s in scene.spheres]
    materials += [m for s in scene.sphere_sets for m in s.materials]
    materials += [m for mesh in scene.meshes for m in mesh.materials]
    for material in materials:
        if id(material) not in seen:
            seen.add(id(material))
            entries.append(material)
    return entries
