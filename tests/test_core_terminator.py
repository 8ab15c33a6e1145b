"""The shadow terminator's smooth-surface lift (``core.terminator``): shadow rays off a smooth
triangle leave from the surface its corner normals describe, as Cycles' do (its match with
Cycles: tests/test_look_cycles.py)."""

from __future__ import annotations

import numpy as np

import core
from core.terminator import TerminatorLift, smooth_surface_lift


def _facet_of_sphere(radius=2.0, angle=0.3):
    """A triangle with corners on a sphere (centre 0) around +Z, its corner normals radial."""
    directions = []
    for azimuth in (0.0, 2.1, 4.2):
        d = np.array([np.sin(angle) * np.cos(azimuth), np.sin(angle) * np.sin(azimuth),
                      np.cos(angle)])
        directions.append(d)
    corners = [radius * d for d in directions]
    return corners, directions


def _barycentric_grid(steps=7):
    u, v = np.meshgrid(np.linspace(0.02, 0.96, steps), np.linspace(0.02, 0.96, steps))
    keep = u + v < 0.98
    u, v = u[keep], v[keep]
    return u, v, 1 - u - v


def test_the_lift_takes_a_sphere_facet_between_the_sphere_and_its_tangent_planes():
    radius = 2.0
    corners, normals = _facet_of_sphere(radius)
    u, v, w = _barycentric_grid()
    m = len(u)
    column = lambda a: np.repeat(np.asarray(a, float)[:, None], m, axis=1)  # noqa: E731
    c = tuple(column(x) for x in corners)
    n = tuple(column(x) for x in normals)
    facet_normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    facet_normal /= np.linalg.norm(facet_normal)
    lift = smooth_surface_lift(c, n, (u, v, w), column(facet_normal))
    points = u * c[0] + v * c[1] + w * c[2]
    lifted = points + lift
    # The flat facet lies inside the sphere it approximates (by up to 4 % of the radius
    # here); lifted, every point is on or outside the sphere (so the facet cannot shadow
    # what the smooth surface would see) and on or below each corner's tangent plane (the
    # envelope that bounds Hanika's parabolic patch: no higher than the surface could be).
    assert (np.linalg.norm(points, axis=0) - radius).max() < -0.005 * radius
    assert (np.linalg.norm(lifted, axis=0) - radius).min() >= 0
    heights = [np.einsum("ij,i->j", lifted - column(corner), normal)
               for corner, normal in zip(corners, normals)]
    assert np.max(heights) <= 1e-12
    # The lift goes out along the normals, on the viewer's side.
    assert np.all(np.einsum("ij,i->j", lift, facet_normal) >= 0)


def test_a_flat_facet_or_the_far_side_gets_no_outward_lift():
    corners, normals = _facet_of_sphere()
    u, v, w = _barycentric_grid()
    m = len(u)
    column = lambda a: np.repeat(np.asarray(a, float)[:, None], m, axis=1)  # noqa: E731
    c = tuple(column(x) for x in corners)
    facet_normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    facet_normal /= np.linalg.norm(facet_normal)
    flat = tuple(column(facet_normal) for _ in range(3))
    assert np.abs(smooth_surface_lift(c, flat, (u, v, w), column(facet_normal))).max() < 1e-12
    # Seen from inside the sphere, the lift goes inwards (towards the viewer), and no further
    # than the corners' tangent planes allow.
    inside = smooth_surface_lift(c, tuple(column(x) for x in normals), (u, v, w),
                                 column(-facet_normal))
    assert np.all(np.einsum("ij,i->j", inside, facet_normal) <= 1e-12)


def test_only_grazing_rays_move_and_those_under_the_facet_may_hit_it():
    m = 4
    geometric = np.repeat(np.array([[0.0], [0.0], [1.0]]), m, axis=1)
    shading = geometric.copy()
    lift = np.repeat(np.array([[0.0], [0.0], [0.01]]), m, axis=1)
    terminator = TerminatorLift(lift, np.full(m, 0.1), geometric, shading)
    # Light straight above, at cos 0.05 above the facet, at cos -0.05 below it (shading
    # normal tilted so the smooth surface still sees it), and behind the surface.
    towards = np.array([[0.0, 0.9987, 0.9987, 0.0], [0.0, 0.0, 0.0, 0.0],
                        [1.0, 0.05, -0.05, -1.0]])
    shading[:, 2] = [0.3, 0.0, 0.954]
    points = np.zeros((3, m))
    exclude = np.array([7, 7, 7, 7])
    moved, origins, ignored = terminator.origins(points, towards, exclude)
    assert list(moved) == [1, 2]
    assert np.all(origins[2] > 0)
    # Above the facet's plane it still cannot hit its own triangle; below it, it may.
    assert list(ignored) == [7, -1]


def test_the_offset_is_validated_and_defaults_to_blenders():
    mesh = core.TriangleMesh(np.eye(3), [[0, 1, 2]], None, [0], (core.SurfaceMaterial(),))
    assert mesh.shadow_terminator_offset == 0.1
    try:
        core.TriangleMesh(np.eye(3), [[0, 1, 2]], None, [0], (core.SurfaceMaterial(),),
                          name="plate", shadow_terminator_offset=-0.5)
    except core.SceneError as error:
        assert "mesh 'plate'.shadow_terminator_offset" in str(error)
    else:
        raise AssertionError("a negative offset was accepted")
