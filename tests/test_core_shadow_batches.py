"""Shadow rays of one shading call go to the aggregate in few batches
(``core.shading._blocked_each``): the world's directions and a sun's share of its disc from
the points, a soft light's samples from their own positions where the aggregate would not use
a sample's shared origin (``Aggregate.segments_need_origin``).  The answers are the same as
batch by batch, so the images are too."""

from __future__ import annotations

import numpy as np
import pytest

import core
from core import shading
from core.geometry import Aggregate
from core.context import make_context


def _uv_sphere(centre, radius, segments=16, rings=8):
    """(vertices (V, 3), triangles (T, 3), corner normals (T, 3, 3)) of a smooth UV sphere,
    counter-clockwise seen from outside."""
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1)
    index = np.arange((rings + 1) * segments).reshape(rings + 1, segments)
    nxt = np.roll(index, -1, axis=1)
    quads_a = np.stack([index[:-1], index[1:], nxt[1:]], axis=-1).reshape(-1, 3)
    quads_b = np.stack([index[:-1], nxt[1:], nxt[:-1]], axis=-1).reshape(-1, 3)
    triangles = np.concatenate([quads_a, quads_b])
    unit = unit.reshape(-1, 3)
    vertices = np.asarray(centre, float) + radius * unit
    corners = vertices[triangles]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    keep = np.linalg.norm(cross, axis=1) > 1e-12          # (the poles' degenerate ones)
    triangles = triangles[keep]
    outward = (cross[keep] * (corners[keep].mean(axis=1) - centre)).sum(axis=1) > 0
    triangles[~outward] = triangles[~outward][:, ::-1]
    return vertices, triangles, unit[triangles]


LIGHTS = {
    "area": core.AreaLight((0.5, 3.0, 0.5), (0, -1, 0), (1, 0, 0), (0, 0, 1), size_x=1.5,
                           size_y=1.5, power=300.0),
    "sphere": core.SphereLight((1.0, 3.0, 1.0), power=500.0, radius=0.4),
    "sun": core.SunLight((-0.4, -1.0, -0.3), strength=3.0, angle=0.2),
    # The article's kind of light with a radius (the default semantics' Blinn-Phong).
    "point": core.PointLight((0.8, 3.0, 0.6), ambient=(0.0, 0.0, 0.0),
                             diffuse=(0.6, 0.6, 0.6), specular=(0.3, 0.3, 0.3), radius=0.4),
}


def _scene(light: str, spheres: int = 0) -> core.Scene:
    """Three smooth UV-sphere meshes (their shadow rays lifted off the facets) over a floor,
    a grey world, and ``spheres`` analytic spheres beside them."""
    matte = core.SurfaceMaterial(diffuse=(0.7, 0.5, 0.3))
    meshes = []
    for centre in ((-0.8, 0.45, 0.0), (0.4, 0.35, -0.6), (0.6, 0.3, 0.6)):
        vertices, triangles, normals = _uv_sphere(centre, centre[1])
        meshes.append(core.TriangleMesh(vertices, triangles, normals,
                                        np.zeros(len(triangles), int), (matte,),
                                        name=f"ball {centre[0]}"))
    floor = core.TriangleMesh(np.array([[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]], float),
                              np.array([[0, 2, 1], [0, 3, 2]]), None, np.zeros(2, int),
                              (core.SurfaceMaterial(),), name="floor")
    sets = ()
    if spheres:
        rng = np.random.default_rng(5)
        centres = np.column_stack([rng.uniform(-2, 2, spheres), rng.uniform(0.1, 0.4, spheres),
                                   rng.uniform(-2, 1, spheres)])
        sets = (core.SphereSet(centres, rng.uniform(0.05, 0.1, spheres),
                               np.zeros(spheres, int), (matte,), name="pebbles"),)
    eye = ((1, 0, 0, 0), (0, 0.94, 0.34, 1.6), (0, -0.34, 0.94, 4.5), (0, 0, 0, 1))
    return core.Scene(core.BlenderCamera(eye, resolution_x=48, resolution_y=36, lens=30.0),
                      (), (LIGHTS[light],), background=(0.05, 0.05, 0.05),
                      ambient=(0.05, 0.05, 0.05), meshes=(*meshes, floor), sphere_sets=sets)


def _batch_by_batch(ctx, terminator, points, batches, stats):
    return [shading._segments_blocked(ctx, terminator, points, rows, rays, stats)
            for rows, rays in batches]


@pytest.mark.parametrize("light", sorted(LIGHTS))
@pytest.mark.parametrize("spheres", [0, 600])
def test_batched_shadow_rays_give_the_images_of_batch_by_batch(monkeypatch, light, spheres):
    """Adaptive AA (each round traces its share of every light sample and world direction),
    smooth meshes (lifted shadow rays), with analytic spheres beside them or not: the same
    image, bit for bit, with the shading call's batches joined as with each traced alone,
    in fewer traces of the aggregate."""
    # (Shading calls and adaptive AA are the Whitted integrator's.)
    settings = core.RenderSettings(integrator="whitted", anti_aliasing="adaptive", samples=16,
                                   threads=1, parallelism="threads")
    scene = _scene(light, spheres)
    calls = []
    occluded = Aggregate.occluded

    def counted(self, segments, stats):
        calls.append(len(segments))
        return occluded(self, segments, stats)

    monkeypatch.setattr(Aggregate, "occluded", counted)
    joined = core.render(scene, settings)
    joined_calls = len(calls)
    calls.clear()
    monkeypatch.setattr(shading, "_blocked_each", _batch_by_batch)
    alone = core.render(scene, settings)
    assert joined.stats.supersampled_pixels > 0
    assert np.array_equal(joined.image, alone.image)
    assert joined.stats.shadow_rays == alone.stats.shadow_rays
    # (With the spheres, a soft light's samples keep their shared origins: only the world's
    # directions and a sun's disc join.)
    assert joined_calls < (len(calls) / 2 if spheres == 0 or light == "sun" else len(calls))


def test_segments_need_their_origin_only_where_the_aggregate_uses_it():
    settings = core.RenderSettings()
    meshes = make_context(_scene("area"), settings, np.float64).geometry
    assert meshes.tree is not None and meshes.sphere_count == 0
    primitives = len(meshes)
    # Triangles in a tree: the origin pays only through its bins, for large batches.
    assert not meshes.segments_need_origin(primitives - 1)
    assert meshes.segments_need_origin(primitives)
    # Spheres take the origin's terms; a few triangles are tested against it flat.
    assert make_context(_scene("area", spheres=600), settings,
                        np.float64).geometry.segments_need_origin(1)
    one_ball = _scene("area")
    one_ball = core.Scene(one_ball.camera, (), one_ball.lights, meshes=one_ball.meshes[-1:])
    flat = make_context(one_ball, settings, np.float64).geometry
    assert flat.tree is None and flat.segments_need_origin(1)


def test_segments_from_several_samples_are_each_samples_own():
    """Segments from two light samples towards points on smooth meshes, some leaving from
    the smooth surface over their facets (``core.terminator``): joined, each ray traced from
    its own sample, they are blocked exactly where each sample's own batch is."""
    from core.rays import RayBatch, RayStats, ray_offsets
    from core.vectors import normalize

    ctx = make_context(_scene("area"), core.RenderSettings(), np.float64)
    geometry = ctx.geometry
    rng = np.random.default_rng(11)
    eye = np.array([0.2, 2.5, 3.0])
    aims = rng.uniform((-1.5, 0.0, -1.5), (1.5, 0.9, 1.5), (500, 3)).T
    directions, _ = normalize(aims - eye[:, None])
    hits = geometry.nearest(RayBatch(eye[:, None], directions), RayStats())
    points, exclude = hits.points, geometry.exclusions(hits.primitive, hits.front)
    samples = [np.array([0.3, 3.0, 0.2]), np.array([-0.9, 1.2, 1.4])]
    batches = []
    for index, sample in enumerate(samples):
        rows = np.arange(index, len(exclude), 2)
        towards, reach = normalize(points[:, rows] - sample[:, None])
        rays = shading._ShadowRays(towards, exclude[rows], ray_offsets(points[:, rows]),
                                   origin=geometry.shared_origin(sample), reach=reach)
        assert not geometry.segments_need_origin(len(rows))
        batches.append((rows, rays))
    stats = RayStats()
    each = _batch_by_batch(ctx, hits.terminator, points, batches, stats)
    joined = shading._blocked_each(ctx, hits.terminator, points, batches, stats)
    for alone, together in zip(each, joined):
        assert np.array_equal(alone, together)
        assert 0 < alone.sum() < len(alone)
    moved = [len(hits.terminator.take(rows).origins(points[:, rows], rays.to_light,
                                                    rays.exclude)[0])
             for rows, rays in batches]
    assert min(moved) > 0
