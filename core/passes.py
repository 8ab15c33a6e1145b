"""Render passes: what the camera ray through each pixel's centre hit first.

``render(scene, settings, passes=True)`` fills a ``PrimaryPasses`` beside the image, tile by
tile (each tile writes only its own slice, like the image).  The values come from one extra
trace of the tile's pixel centres at depth 1 (``trace_bundle(record_primary=True)``, which
reads t, the sphere and the normal at the bounce loop's first hit): passes are per pixel
centre, not averaged over anti-aliasing samples, as depth, normals and indices cannot be
meaningfully averaged across an edge anyway.

Conventions are Blender's render passes':
* depth: distance along the camera's view axis (Blender's Depth/Z pass, as Cycles writes it),
  ``MISSED_DEPTH`` where the ray hit nothing (Blender's value for the background);
* position: the hit point in world space (Position pass); 0 where missed;
* normal: the unit world-space shading normal, turned towards the camera (Normal pass);
  0 where missed;
* sphere: the index into ``scene.spheres`` of what was hit, -1 where missed (the caller maps
  it to Object / Material Index).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .camera import camera_rays, camera_to_world
from .scene import BlenderCamera
from .trace import trace_bundle

#: Blender's Depth pass value where nothing was hit.
MISSED_DEPTH = 1e10


@dataclass
class PrimaryPasses:
    """(H, W[, 3]) float32 arrays (int32 for sphere), row 0 = top; see the module docstring."""

    depth: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    sphere: np.ndarray

    @classmethod
    def empty(cls, width: int, height: int) -> "PrimaryPasses":
        return cls(np.full((height, width), MISSED_DEPTH, np.float32),
                   np.zeros((height, width, 3), np.float32),
                   np.zeros((height, width, 3), np.float32),
                   np.full((height, width), -1, np.int32))


def view_axis(camera) -> np.ndarray:
    """(3,) the unit direction the camera looks along."""
    if isinstance(camera, BlenderCamera):
        return -camera_to_world(camera)[0][:, 2]
    return np.array([0.0, 0.0, np.sign(camera.screen_z - camera.eye[2]) or -1.0])


def fill_tile_passes(passes: PrimaryPasses, ctx, camera, tile, stats) -> None:
    """Trace the pixel centres of tile (y0, y1, x0, x1) to their first hit and write that
    tile's part of ``passes``."""
    y0, y1, x0, x1 = tile
    rows, cols = np.mgrid[y0:y1, x0:x1]
    rows, cols = rows.ravel(), cols.ravel()
    rays = camera_rays(camera, cols + 0.5, rows + 0.5, ctx.dtype)
    first_hit_only = dataclasses.replace(ctx, settings=dataclasses.replace(ctx.settings,
                                                                           max_depth=1))
    hits = trace_bundle(first_hit_only, rays, stats, record_primary=True).primary
    hit = hits.sphere >= 0
    t = np.where(hit, hits.t, 0.0)
    position = rays.origins + t * rays.directions            # (3, n)
    shape = (y1 - y0, x1 - x0)
    # Perspective rays start at the eye, orthographic ones on the camera's plane: either way
    # the view-axis depth is t times the direction's component along the axis.
    depth = np.where(hit, t * (view_axis(camera) @ rays.directions), MISSED_DEPTH)
    passes.depth[y0:y1, x0:x1] = depth.reshape(shape)
    passes.position[y0:y1, x0:x1] = np.where(hit, position, 0.0).T.reshape(*shape, 3)
    passes.normal[y0:y1, x0:x1] = hits.normal.T.reshape(*shape, 3)
    passes.sphere[y0:y1, x0:x1] = hits.sphere.reshape(shape)
