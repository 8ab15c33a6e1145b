"""Adaptive anti-aliasing on triangle meshes finds the edges the picture shows: a silhouette,
or a crease between flat facets, but not the inner edges of a smooth mesh, whose shading is
continuous across them (``core.arrays._surfaces``, ``Aggregate.surface_keys``)."""

from __future__ import annotations

import numpy as np

import core


def uv_sphere(segments=48, rings=24):
    """(vertices (V, 3), triangles (T, 3), corner normals (T, 3, 3)) of a unit UV sphere."""
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    vertices = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)],
                        axis=-1).reshape(-1, 3)
    triangles = []
    for r in range(rings):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            c, d = a + segments, b + segments
            triangles += [(a, c, b), (b, c, d)]
    triangles = np.array(triangles)
    # Drop the poles' degenerate triangles (two corners on the same pole vertex).
    keep = np.array([len(set(tuple(np.round(vertices[i], 9)) for i in tri)) == 3
                     for tri in triangles])
    triangles = triangles[keep]
    return vertices, triangles, vertices[triangles]


def render(smooth: bool):
    vertices, triangles, normals = uv_sphere()
    mesh = core.TriangleMesh(vertices, triangles, normals if smooth else None,
                             np.zeros(len(triangles), int), (core.Material(reflection=0.0),))
    camera = core.BlenderCamera(
        matrix_world=((1, 0, 0, 0), (0, 0, -1, -4), (0, 1, 0, 0), (0, 0, 0, 1)),
        resolution_x=96, resolution_y=72)
    scene = core.Scene(camera=camera, meshes=(mesh,),
                       lights=(core.PointLight((3.0, -4.0, 3.0)),))
    return core.render(scene, core.RenderSettings(anti_aliasing="adaptive", samples=4))


def test_a_smooth_mesh_is_supersampled_at_its_silhouette_only():
    smooth, flat = render(smooth=True), render(smooth=False)
    covered = int((smooth.image[..., 3] > 0).sum())

    # The silhouette of a ball about 50 pixels across is about 160 pixels around, and the
    # shadow terminator adds one line more; every facet edge inside would be several times
    # that (a UV sphere of 48 x 24 faces shows hundreds of them).
    assert 0 < smooth.stats.supersampled_pixels < 0.35 * covered
    # Flat facets shade differently: their creases are edges in the picture.
    assert flat.stats.supersampled_pixels > 2 * smooth.stats.supersampled_pixels
