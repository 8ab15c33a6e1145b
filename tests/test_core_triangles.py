"""Triangles through the aggregate: watertight intersection, robust secondary rays, an
independent oracle, smooth and flat normals, instance transforms, and whole renders."""

from __future__ import annotations

import numpy as np
import pytest

import core
from core.context import RayStats, make_context
from core.rays import RayBatch

DTYPES = [np.float64, np.float32]
MATERIAL = core.Material(reflection=0.0)


def icosphere(subdivisions: int = 1):
    """A closed unit icosphere: (vertices (V, 3), triangles (T, 3)), counter-clockwise
    seen from outside; shared vertices are shared indices (no duplicates)."""
    g = (1 + 5 ** 0.5) / 2
    vertices = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g),
                (0, -1, -g), (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    vertices = [np.array(v, float) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        middle, refined = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                p = vertices[a] + vertices[b]
                vertices.append(p / np.linalg.norm(p))
                middle[key] = len(vertices) - 1
            return middle[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    return np.array(vertices), np.array(faces)


def _mesh(vertices, triangles, normals=None, transforms=None, name="mesh"):
    extra = {} if transforms is None else {"transforms": transforms}
    return core.TriangleMesh(vertices, triangles, normals, np.zeros(len(triangles), np.int64),
                             (MATERIAL,), name=name, **extra)


def _context(meshes=(), spheres=(), dtype=np.float64, semantics="default"):
    scene = core.Scene(camera=core.ScreenCamera(2, 2), spheres=spheres, meshes=meshes,
                       lights=(core.PointLight((0, 100, 0)),))
    return make_context(scene, core.RenderSettings(semantics=semantics), dtype)


def _batch(origins, directions, dtype, exclude=None):
    directions = np.asarray(directions, np.float64)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    origins = np.broadcast_to(np.asarray(origins, np.float64), directions.shape)
    return RayBatch(origins.T.astype(dtype), directions.T.astype(dtype), exclude=exclude)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _affine(linear=np.eye(3), translation=(0, 0, 0)):
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = linear, translation
    return matrix


# ---- watertightness ------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("placement", ["identity", "rotated-far"])
def test_rays_at_shared_edges_and_vertices_never_pass_through(dtype, placement):
    """From inside a closed mesh every ray must hit it; aimed exactly at its vertices and at
    points on its shared edges (the worst case for crack-prone tests), from the centre and
    from off-centre origins, none may escape.  From outside, rays aimed at the same points
    must hit it too."""
    vertices, triangles = icosphere(2)
    transform = np.eye(4)
    if placement == "rotated-far":
        transform = _affine(_rotation((1, 2, 3), 0.7) * 3.0, (1e3, -2e2, 5e2))
    mesh = _mesh(vertices, triangles, transforms=transform[None])
    ctx = _context((mesh,), dtype=dtype)
    world = vertices @ transform[:3, :3].T + transform[:3, 3]
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    targets = [world]
    for fraction in (0.5, 1 / 3, 0.123456789):
        targets.append(world[edges[:, 0]] * (1 - fraction) + world[edges[:, 1]] * fraction)
    targets = np.concatenate(targets)
    centre = transform[:3, 3]
    scale = 3.0 if placement == "rotated-far" else 1.0
    for origin in (centre, centre + scale * np.array([0.2, -0.1, 0.05]),
                   centre + scale * np.array([-0.31, 0.27, 0.4])):
        hits = ctx.geometry.nearest(_batch(origin, targets - origin, dtype), RayStats())
        assert len(hits) == len(targets), f"{len(targets) - len(hits)} rays escaped"
        assert (hits.front == False).all()  # noqa: E712  from inside: the back faces
    outside = centre + scale * np.array([5.0, 4.0, -3.0])
    toward = targets - outside
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    # Rays passing well inside the silhouette (their line within 0.9 of the centre, the
    # mesh's inscribed radius being 0.98): each must hit, whichever side its target is on.
    off_centre = centre - outside
    miss_distance = np.linalg.norm(off_centre - (toward @ off_centre)[:, None] * toward, axis=1)
    through = miss_distance < 0.9 * scale
    assert through.sum() > 300
    hits = ctx.geometry.nearest(_batch(outside, toward[through], dtype), RayStats())
    assert len(hits) == through.sum()
    assert hits.front.all()


def test_ray_through_shared_edge_of_two_triangles_hits_exactly_one_or_both_never_none():
    """A quad of two triangles in the plane z = 0; rays straight down through points on the
    diagonal, the shared edge, at many positions: each hits the quad."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    quad = _mesh(vertices, np.array([[0, 1, 2], [0, 2, 3]]))
    for dtype in DTYPES:
        ctx = _context((quad,), dtype=dtype)
        s = np.linspace(0, 1, 1001)[1:-1]
        points = np.column_stack([s, s, np.zeros_like(s)])
        rng = np.random.default_rng(7)
        tilt = rng.normal(scale=0.3, size=(len(s), 3))
        tilt[:, 2] = -1
        origins = points - tilt * 2.0
        batch = RayBatch(origins.T.astype(dtype), (tilt / np.linalg.norm(tilt, axis=1,
                                                                          keepdims=True)).T
                         .astype(dtype))
        hits = ctx.geometry.nearest(batch, RayStats())
        assert len(hits) == len(s)


# ---- an independent oracle -------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("shared_origin", [True, False])
def test_both_kernels_shear_as_the_papers_matrix_rows_do_bit_for_bit(dtype, shared_origin):
    """The block kernel (rays grouped by their shear's axes) and the pair kernel compute a
    sheared corner as p[kx] - Sx p[kz]; the paper's per-ray 3 x 3 shear, a dot product with
    each row (entries 1, 0 and -S), rounds alike, as its products by 1 and 0 are exact: the
    same t, barycentrics and verdicts from all three, for every axis permutation."""
    from core.geometry.triangles import Shear, _hit, watertight_axes, watertight_pairs

    rng = np.random.default_rng(4)
    k, n = 9, 600
    corners = [rng.uniform(-3, 3, (3, k)).astype(dtype) for _ in range(3)]
    directions = rng.normal(size=(3, n))
    directions = (directions / np.linalg.norm(directions, axis=0)).astype(dtype)
    origins = (rng.uniform(-1, 1, (3, 1 if shared_origin else n)) * 5).astype(dtype)
    shear = Shear.of(directions)
    rows = np.zeros((3, 3, n), dtype)          # rows[r, axis, ray] of the paper's matrix
    columns = np.arange(n)
    for row in range(3):
        rows[row, shear.axes[2], columns] = shear.factors[row]
    rows[0, shear.axes[0], columns] = 1
    rows[1, shear.axes[1], columns] = 1
    sheared = []
    for v in corners:
        p = v[:, :, None] - origins[:, None, :]
        sheared += [rows[r, 0] * p[0] + rows[r, 1] * p[1] + rows[r, 2] * p[2] for r in range(3)]
    reference = _hit(*sheared, 0.0, np.inf)
    assert reference[4].sum() > 50
    key = 3 * shear.axes[2] + shear.axes[0]
    assert len(np.unique(key)) == 6
    blocks = [np.zeros((k, n), a.dtype) for a in reference]
    for value in np.unique(key):
        group = np.flatnonzero(key == value)
        start = origins if shared_origin else origins[:, group]
        found = watertight_axes(*(v[:, :, None] for v in corners), start[:, None, :],
                                tuple(int(a) for a in shear.axes[:, group[0]]),
                                shear.factors[:, group], 0.0, np.inf)
        for store, part in zip(blocks, found):
            store[:, group] = part
    triangle, ray = (a.ravel() for a in np.meshgrid(np.arange(k), columns, indexing="ij"))
    pairs = watertight_pairs(np.concatenate(corners), triangle, shear.for_pairs(origins, k),
                             ray, 0.0, np.inf)
    valid = reference[4]
    for made in (blocks, [a.reshape(k, n) for a in pairs]):
        assert np.array_equal(made[4], valid)
        for expected, got in zip(reference[:4], made[:4]):
            assert np.array_equal(expected[valid], got[valid])


def test_triangle_hits_agree_with_a_linear_solve_oracle():
    """Random triangles and rays: hit or miss and distance agree with solving
    o + t d = v0 + u (v1 - v0) + v (v2 - v0) by numpy.linalg.solve, except where the oracle's
    point lies within 1e-9 of an edge (where either answer is right)."""
    rng = np.random.default_rng(11)
    count = 300
    corners = rng.normal(size=(count, 3, 3)) * rng.uniform(0.01, 10, (count, 1, 1)) \
        + rng.normal(size=(count, 1, 3)) * 5
    origins = rng.normal(size=(count, 3)) * 20
    aims = corners.mean(axis=1) + rng.normal(size=(count, 3)) * 3
    directions = aims - origins
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    checked = 0
    for i in range(count):
        mesh = _mesh(corners[i], np.array([[0, 1, 2]]))
        ctx = _context((mesh,))
        t_found, primitive, _ = ctx.geometry.intersect(
            _batch(origins[i], directions[i:i + 1], np.float64), RayStats())
        v0, v1, v2 = corners[i]
        system = np.column_stack([-directions[i], v1 - v0, v2 - v0])
        t, u, v = np.linalg.solve(system, origins[i] - v0)
        margin = min(u, v, 1 - u - v)
        if abs(margin) < 1e-9:
            continue
        checked += 1
        expect_hit = margin > 0 and t > 0
        assert (primitive[0] == 0) == expect_hit, i
        if expect_hit:
            assert abs(t_found[0] - t) <= 1e-9 * max(1.0, abs(t))
    assert checked > 280


def test_nearest_of_many_triangles_and_spheres_matches_brute_force():
    """A soup of 200 triangles and 20 spheres: the aggregate's nearest hit per ray equals the
    minimum over every primitive tested one by one."""
    rng = np.random.default_rng(12)
    centres = rng.uniform(-3, 3, (200, 1, 3))
    corners = centres + rng.normal(scale=0.4, size=(200, 3, 3))
    soup = _mesh(corners.reshape(-1, 3), np.arange(600).reshape(200, 3))
    spheres = tuple(core.Sphere(tuple(c), r) for c, r in
                    zip(rng.uniform(-3, 3, (20, 3)), rng.uniform(0.1, 0.5, 20)))
    ctx = _context((soup,), spheres)
    origin = np.array([0.5, 0.2, 9.0])
    directions = rng.normal(size=(2000, 3)) * [0.3, 0.3, 1] - [0, 0, 1]
    t, primitive, _ = ctx.geometry.intersect(_batch(origin, directions, np.float64),
                                             RayStats())
    expected = np.full(2000, np.inf)
    for j in range(200):
        single = _context((_mesh(corners[j], np.array([[0, 1, 2]])),))
        tj, pj, _ = single.geometry.intersect(_batch(origin, directions, np.float64), RayStats())
        expected = np.minimum(expected, np.where(pj == 0, tj, np.inf))
    for s in spheres:
        single = _context((), (s,))
        tj, pj, _ = single.geometry.intersect(_batch(origin, directions, np.float64), RayStats())
        expected = np.minimum(expected, np.where(pj == 0, tj, np.inf))
    assert np.array_equal(np.isfinite(expected), primitive >= 0)
    assert np.allclose(t[primitive >= 0], expected[primitive >= 0], rtol=1e-12)
    assert (primitive >= 20).any() and ((primitive >= 0) & (primitive < 20)).any()


# ---- rays leaving triangles ------------------------------------------------------------------

# float32 carries 7 digits: beyond 1e3 'auto' renders in float64, so float32 stops there.
@pytest.mark.parametrize("dtype, scale", [(np.float64, 1e-3), (np.float64, 1.0),
                                          (np.float64, 1e3), (np.float64, 1e5),
                                          (np.float32, 1e-3), (np.float32, 1.0),
                                          (np.float32, 1e3)])
def test_rays_leaving_triangles_never_rehit_their_surface(dtype, scale):
    """pbrt-v4 style: hit points on a tilted, finely split plane (many coplanar triangles)
    and a tetrahedron's faces, at several scales and far from the origin.  Reflection rays
    spawned into the hemisphere of the side the camera ray came from, and shadow segments
    towards lights on that side, never hit the surface they leave, even with the
    self-exclusion turned off (the offset alone must do it)."""
    rng = np.random.default_rng(int(scale * 1000) % 2 ** 32)
    grid = np.linspace(-1, 1, 9)
    xs, ys = np.meshgrid(grid, grid)
    flat = np.column_stack([xs.ravel(), ys.ravel(), 0.01 * np.sin(xs.ravel()) * 0])
    index = np.arange(81).reshape(9, 9)
    quads = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], -1)
    quads = quads.reshape(-1, 4)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    place = _affine(_rotation((0.3, 1, 0.2), 0.6) * scale, np.array([3.0, -2.0, 1.5]) * scale)
    plane = _mesh(flat, triangles, transforms=place[None])
    ctx = _context((plane,), dtype=dtype)
    normal = place[:3, :3] @ [0, 0, 1.0]
    normal /= np.linalg.norm(normal)
    targets = (np.column_stack([rng.uniform(-0.99, 0.99, (400, 2)), np.zeros(400)])
               @ place[:3, :3].T + place[:3, 3])
    origins = targets + normal * 3 * scale + rng.normal(size=(400, 3)) * 0.5 * scale
    hits = ctx.geometry.nearest(_batch(origins, targets - origins, dtype), RayStats())
    assert len(hits) == 400 and hits.front.all()
    facing = hits.normals
    leaving = rng.normal(size=(3, 400))
    leaving[:, dot3(leaving, facing.astype(float)) < 0] *= -1
    leaving /= np.linalg.norm(leaving, axis=0)
    spawned = ctx.geometry.spawn(hits.points, hits.normals, hits.primitive,
                                 leaving.astype(dtype), hits.front)
    assert (spawned.exclude == hits.primitive).all()
    spawned.exclude = None
    again = ctx.geometry.nearest(spawned, RayStats())
    assert len(again) == 0, f"{len(again)} reflection rays re-hit the plane"
    # Shadow segments from lights on the front side towards the points, stopping short of
    # them by the tracer's offset, without exclusion.
    from core.rays import ray_offsets
    light = place[:3, 3] + normal * 2 * scale + place[:3, :3] @ [0.5, -0.3, 0]
    towards = hits.points.astype(float) - light[:, None]
    distance = np.linalg.norm(towards, axis=0)
    segments = RayBatch(light[:, None], (towards / distance).astype(dtype), 0.0,
                        (distance - ray_offsets(hits.points)).astype(dtype),
                        ctx.geometry.shared_origin(light))
    assert not ctx.geometry.occluded(segments, RayStats()).any()


def dot3(a, b):
    return (a * b).sum(axis=0)


# ---- normals ---------------------------------------------------------------------------------

def test_smooth_normals_interpolate_corner_normals_flat_ones_are_geometric():
    """On an icosphere with per-corner normals equal to its vertex directions, shading
    normals at hit points are within a fraction of the flat facets' error of the true
    sphere's normal; without corner normals the shading normal is the facet's."""
    vertices, triangles = icosphere(1)
    corner = vertices[triangles]                                           # (T, 3, 3)
    smooth = _context((_mesh(vertices, triangles, corner),))
    flat = _context((_mesh(vertices, triangles, None),))
    rng = np.random.default_rng(5)
    directions = rng.normal(size=(3000, 3))
    results = {}
    for name, ctx in (("smooth", smooth), ("flat", flat)):
        hits = ctx.geometry.nearest(_batch((0, 0, 0), directions, np.float64), RayStats())
        assert len(hits) == 3000
        true = hits.points / np.linalg.norm(hits.points, axis=0)
        angle = np.arccos(np.clip(dot3(hits.shading, true), -1, 1))
        results[name] = angle.mean()
        assert np.allclose(np.linalg.norm(hits.shading, axis=0), 1)
        # Geometric normals are the facets' either way, pointing outwards.
        v = corner[hits.primitive]
        facet = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        facet /= np.linalg.norm(facet, axis=1, keepdims=True)
        assert np.allclose(hits.normals.T, facet, atol=1e-12)
        assert (dot3(hits.normals, hits.points) > 0).all()
        if name == "flat":
            assert np.array_equal(hits.shading, hits.normals)
    assert results["smooth"] < results["flat"] / 5


def test_instances_transform_points_and_normals_by_inverse_transpose():
    """Instances (translated, rotated, non-uniformly scaled, mirrored) give the same hits as
    the mesh with its vertices moved by hand; their smooth normals are the object normals
    mapped by the inverse transpose; a mirrored instance keeps its front outside."""
    vertices, triangles = icosphere(1)
    corner = vertices[triangles]
    transforms = np.stack([
        _affine(translation=(4, 0, 0)),
        _affine(_rotation((0, 0, 1), 0.5) @ np.diag([2.0, 0.5, 1.0]), (-4, 1, 0)),
        _affine(np.diag([-1.0, 1.0, 1.0]) * 1.5, (0, 4, 0)),
    ])
    instanced = _context((_mesh(vertices, triangles, corner, transforms),))
    rng = np.random.default_rng(9)
    for k, matrix in enumerate(transforms):
        world = vertices @ matrix[:3, :3].T + matrix[:3, 3]
        by_hand = _context((_mesh(world, triangles),))
        origin = matrix[:3, 3] + [0.1, 0.2, 6.0]
        directions = (matrix[:3, 3] + rng.normal(scale=0.6, size=(500, 3))) - origin
        got = instanced.geometry.nearest(_batch(origin, directions, np.float64), RayStats())
        want = by_hand.geometry.nearest(_batch(origin, directions, np.float64), RayStats())
        assert np.array_equal(got.rays, want.rays) and len(got) > 100
        assert np.allclose(got.t, want.t, rtol=1e-12)
        assert got.front.all(), f"instance {k}: front faces must face outwards"
        local = got.primitive - k * len(triangles)
        assert ((local >= 0) & (local < len(triangles))).all()
        # Expected shading normal: interpolate object normals, map by inverse transpose.
        inverse = np.linalg.inv(matrix[:3, :3])
        world_corners = world[triangles[local]]                            # (m, 3, 3)
        b = np.linalg.solve(np.stack([world_corners[:, 0], world_corners[:, 1],
                                      world_corners[:, 2]], axis=2), got.points.T[..., None])
        object_corner = corner[local] @ inverse                             # rows: n^T M^-1
        object_corner /= np.linalg.norm(object_corner, axis=2, keepdims=True)
        expected = (object_corner * b).sum(axis=1)
        expected /= np.linalg.norm(expected, axis=1, keepdims=True)
        assert np.allclose(got.shading.T, expected, atol=1e-9)


# ---- whole renders ---------------------------------------------------------------------------

def test_a_cube_mesh_renders_its_silhouette_and_casts_a_shadow():
    """An axis-aligned cube seen face-on through the article's camera covers exactly the
    pixels whose rays cross its front face, and it shadows the floor sphere below it."""
    vertices = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    tint = (0.05, 0.1, 0.15)
    cube = core.TriangleMesh(vertices * 0.4, triangles, None, np.zeros(12, np.int64),
                             (core.Material(ambient=tint, reflection=0.0),),
                             _affine(translation=(0, 0, -2))[None], name="cube")
    floor = core.Sphere((0, -9000, 0), 8999.3, core.Material(reflection=0), "floor")
    width, height = 120, 80
    scene = core.Scene(camera=core.ScreenCamera(width, height), spheres=(floor,),
                       meshes=(cube,), lights=(core.PointLight((0, 5, -2)),))
    image = core.render(scene, core.RenderSettings(precision="float64")).image
    # The front face z = -1.6 spans |x|, |y| <= 0.4: a pixel ray through screen (sx, sy)
    # from the eye (0, 0, 1) reaches it at (sx, sy) * 2.6.
    sx = np.linspace(-1, 1, width)
    sy = np.linspace(1 / 1.5, -1 / 1.5, height)
    inside = (np.abs(sx[None, :] * 2.6) < 0.4 - 1e-6) & (np.abs(sy[:, None] * 2.6) < 0.4 - 1e-6)
    outside = (np.abs(sx[None, :] * 2.6) > 0.4 + 1e-6) | (np.abs(sy[:, None] * 2.6) > 0.4 + 1e-6)
    below_horizon = image[..., 3] == 1
    # The cube's front face is lit only by ambient (the light is above it): its tint.
    cube_pixels = np.isclose(image[..., :3], tint).all(axis=2)
    assert cube_pixels[inside].all()
    assert not (cube_pixels & outside & below_horizon).any()
    assert not below_horizon[0].any()
    # Its shadow: the floor (top at y = -0.7) under the cube's centre, z = -2, is seen at
    # sy = -0.7 / 3 in the middle column; it is ambient only, the floor far aside is lit.
    row = int(np.argmin(np.abs(sy + 0.7 / 3)))
    middle, aside = width // 2, int(np.argmin(np.abs(sx - 0.9)))
    assert np.allclose(image[row, middle, :3], 0.1) and below_horizon[row, middle]
    assert image[row, aside, :3].min() > 0.3


@pytest.mark.parametrize("semantics", ["default", "article"])
def test_meshes_render_finite_in_both_semantics(semantics):
    vertices, triangles = icosphere(1)
    mesh = core.TriangleMesh(vertices * 0.5, triangles, vertices[triangles],
                             np.zeros(len(triangles), np.int64), (core.Material(),),
                             _affine(translation=(0.3, 0, -2))[None])
    scene = core.Scene(camera=core.ScreenCamera(60, 40),
                       spheres=(core.Sphere((-0.5, 0, -2), 0.4),), meshes=(mesh,),
                       lights=(core.PointLight((5, 5, 5)),))
    result = core.render(scene, core.RenderSettings(semantics=semantics))
    assert np.isfinite(result.image).all()
    assert result.stats.triangle_tests > 0
    assert (result.image[..., 3] == 1).sum() > 100


def test_a_mesh_far_from_the_origin_renders_as_near_it():
    """The same scene (a smooth icosphere on a floor plane of two triangles, a light) moved by
    1e4 in every axis renders the same: meshes move into the render's frame with the camera."""
    vertices, triangles = icosphere(1)
    floor = np.array([[-5, -0.5, -8], [5, -0.5, -8], [5, -0.5, 2], [-5, -0.5, 2]], float)

    def scene(offset):
        shift = np.array([offset, offset, offset], float)
        ball = _mesh(vertices * 0.5, triangles, vertices[triangles],
                     _affine(translation=np.array([0, 0, -3]) + shift)[None])
        plane = _mesh(floor, np.array([[0, 2, 1], [0, 3, 2]]),
                      transforms=_affine(translation=shift)[None])
        camera = core.ScreenCamera(48, 32, eye=tuple(shift + [0, 0, 1]), left=offset - 1,
                                   right=offset + 1, top=offset + 1 / 1.5,
                                   bottom=offset - 1 / 1.5, screen_z=offset)
        return core.Scene(camera=camera, meshes=(ball, plane),
                          lights=(core.PointLight(tuple(shift + [2, 3, 0])),))

    settings = core.RenderSettings(precision="float64")
    near = core.render(scene(0.0), settings).image
    far = core.render(scene(1e4), settings).image
    assert (near[..., 3] == 1).mean() > 0.3
    difference = np.abs(near - far).max(axis=2)
    # Silhouette and shadow-edge pixels may flip under the ~1e-12 rounding of the offset.
    assert (difference > 1e-3).mean() <= 0.01
    assert np.median(difference) < 1e-9
