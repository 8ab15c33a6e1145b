"""Hard numerical cases, each checked against an independent 60-digit oracle (tests/oracle.py).

Cases from real renderers' suites (pbrt-v4 shapes_test, Embree verify, Mitsuba 3
test_sphere): huge spheres, far-away scenes, grazing and tangent rays, tiny far spheres,
cameras inside spheres, rays leaving hit points, touching and coincident spheres, NaN/inf.
"""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

import core
from core.context import RayStats, make_context
from core.rays import RayBatch
from core.geometry.spheres import OriginTerms
from core.precision import choose_precision
from oracle import exact_hit, exact_roots

DTYPES = [np.float64, np.float32]


def _context(spheres, dtype=np.float64, semantics="default", eye=(0, 0, 0)):
    scene = core.Scene(camera=core.ScreenCamera(width=2, height=2, eye=eye), spheres=spheres,
                       lights=(core.PointLight((0, 1e3, 0)),))
    return make_context(scene, core.RenderSettings(semantics=semantics), dtype)


def _shoot(ctx, origins, directions, exclude=None):
    """Nearest hits; one origin row takes the shared-origin path camera and shadow rays use."""
    dirs = np.asarray(directions, np.float64)
    dirs = (dirs / np.linalg.norm(dirs, axis=1, keepdims=True)).astype(ctx.dtype)
    origins = np.asarray(origins, np.float64)
    shared = ctx.geometry.shared_origin(origins[0]) if len(origins) == 1 else None
    # The tracer's bundles are (3, n): one row per component.
    batch = RayBatch(origins.T.astype(ctx.dtype), dirs.T.copy(), 0.0, np.inf, shared, exclude)
    return ctx.geometry.intersect(batch, RayStats())[:2]


def _relative_error(t, exact):
    return abs(Decimal(float(t)) - exact) / exact


@pytest.mark.parametrize("shared, bound", [(True, "1e-13"), (False, "1e-11")])
@pytest.mark.parametrize("radius", [8999.3, 1e6])
def test_huge_floor_sphere_hit_distances(radius, shared, bound):
    """The article's floor (and a 1e6 one): rays from just above it, at grazing to steep angles.
    Rays sharing an origin get c' in extended precision; rays with their own origins are
    limited by f = o - c itself, rounded at |f| ~ r (relative ~1e-12 of t, docs/article.md "Numerics worth knowing")."""
    center = (0.0, -radius - 0.7, 0.0)
    sphere = core.Sphere(center, radius)
    ctx = _context((sphere,))
    rng = np.random.default_rng(1)
    directions = np.column_stack([rng.uniform(-1, 1, 500), -rng.uniform(0.01, 1, 500),
                                  -rng.uniform(0.1, 1, 500)])
    origin = np.array([[0.0, 0.0, 1.0]])
    t, index = _shoot(ctx, origin if shared else np.repeat(origin, 500, 0), directions)
    dirs = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    worst = Decimal(0)
    for ti, i, d in zip(t, index, dirs):
        exact = exact_hit(origin[0], d, center, radius)
        if exact is None:
            assert i == -1
            continue
        assert i == 0
        worst = max(worst, _relative_error(ti, exact))
    assert worst < Decimal(bound)


def test_floor_needs_float64_and_shared_origin_terms_beat_the_textbook_form():
    """The article's c = |f|^2 - r^2 cancels ~8 digits on the floor.  In float32 every form is
    off by more than 1e-4 (why 'auto' picks float64 for the floor); in float64 the shared-origin
    form with its extended-precision c' is 100x closer to the oracle than the textbook one."""
    from core.geometry.spheres import offset_roots, origin_roots
    radius = 8999.3
    centers = np.array([[0.0, -9000.0, 0.0]])
    radii = np.array([radius])
    rng = np.random.default_rng(2)
    d = np.column_stack([rng.uniform(-1, 1, 200), -rng.uniform(0.05, 1, 200), -np.ones(200)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = np.array([[0.0, 0.0, 1.0]])
    exact = np.array([float(exact_roots(origin[0], di, centers[0], radius)[0]) for di in d])

    def error(dtype, textbook):
        f = (origin - centers).T.astype(dtype)                       # (3, 1): one ray per column
        t = offset_roots(f, d.T.astype(dtype), radii.astype(dtype), textbook=textbook)[0]
        return np.abs(t - exact).max()

    assert error(np.float32, True) > 1e-4 and error(np.float32, False) > 1e-4
    terms = OriginTerms.at(origin[0], centers, radii)
    shared = origin_roots(terms.f.T, terms.c_prime, terms.article_c, radii, d.T.copy())[0]
    assert np.abs(shared - exact).max() * 100 < error(np.float64, True)


@pytest.mark.parametrize("offset", [1e4, 1e6])
def test_scene_translated_far_away_renders_the_same(offset):
    """The whole article scene moved by (offset, offset, -offset): same image."""
    def shifted(scene, delta):
        cam = scene.camera
        camera = core.ScreenCamera(cam.width, cam.height, eye=np.add(cam.eye, delta),
                                   left=cam.left + delta[0], right=cam.right + delta[0],
                                   top=cam.top + delta[1], bottom=cam.bottom + delta[1],
                                   screen_z=cam.screen_z + delta[2])
        spheres = tuple(core.Sphere(np.add(s.center, delta), s.radius, s.material, s.name)
                        for s in scene.spheres)
        lights = tuple(core.PointLight(np.add(l.position, delta)) for l in scene.lights)
        return core.Scene(camera=camera, spheres=spheres, lights=lights)

    base = core.article_scene(150, 100)
    settings = core.RenderSettings(semantics="default", precision="auto")
    near = core.render(base, settings).image
    far = core.render(shifted(base, (offset, offset, -offset)), settings).image
    difference = np.abs(near - far).max(axis=2)
    # Stated tolerance: every pixel within 1e-3 except silhouette/shadow-edge pixels whose
    # hit flips under the ~1e-10 (1e4) / 1e-8 (1e6) rounding of positions: at most 0.1 %.
    assert (difference > 1e-3).mean() <= 1e-3
    assert np.median(difference) < 1e-6


@pytest.mark.parametrize("dtype", DTYPES)
def test_tangent_ray_misses_grazing_rays_hit(dtype):
    sphere = core.Sphere((0.0, 0.0, 0.0), 1.0)
    ctx = _context((sphere,), dtype)
    tangent_t, tangent_i = _shoot(ctx, [[-5.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    assert tangent_i[0] == -1 and np.isinf(tangent_t[0])
    gap = 1e-9 if dtype == np.float64 else 1e-4
    inside_t, inside_i = _shoot(ctx, [[-5.0, 1.0 - gap, 0.0]], [[1.0, 0.0, 0.0]])
    outside_t, outside_i = _shoot(ctx, [[-5.0, 1.0 + gap, 0.0]], [[1.0, 0.0, 0.0]])
    assert outside_i[0] == -1
    assert inside_i[0] == 0
    exact = exact_hit((-5.0, dtype(1.0 - gap), 0.0), (1, 0, 0), (0, 0, 0), 1.0)
    tolerance = 1e-12 if dtype == np.float64 else 1e-5
    assert _relative_error(inside_t[0], exact) < tolerance


def test_tiny_sphere_far_away():
    """r = 1e-3 at distance 1e3: hits and misses agree with the oracle, distances to 1e-12."""
    center, radius = (0.0, 0.0, -1000.0), 1e-3
    ctx = _context((core.Sphere(center, radius),))
    offsets = np.linspace(-1.3e-3, 1.3e-3, 401)
    directions = np.column_stack([offsets, offsets * 0.3, np.full_like(offsets, -1000.0)])
    t, index = _shoot(ctx, [[0.0, 0.0, 0.0]], directions)
    dirs = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    hits = 0
    for ti, i, d in zip(t, index, dirs):
        exact = exact_hit((0, 0, 0), d, center, radius)
        assert (exact is None) == (i == -1)
        if exact is not None:
            hits += 1
            assert _relative_error(ti, exact) < Decimal("1e-12")
    assert 200 < hits < 401


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("semantics", ["default", "article"])
def test_camera_inside_a_sphere(semantics, dtype):
    center, radius = (0.3, -0.2, 0.1), 10.0
    scene = core.Scene(camera=core.ScreenCamera(2, 2, eye=(0, 0, 0)),
                       spheres=(core.Sphere(center, radius),))
    assert choose_precision(scene, "auto") == np.float32   # so float32 must hold too
    ctx = _context((core.Sphere(center, radius),), dtype, semantics=semantics)
    rng = np.random.default_rng(3)
    directions = rng.normal(size=(300, 3))
    t, index = _shoot(ctx, [[0.0, 0.0, 0.0]], directions)
    if semantics == "article":
        assert (index == -1).all()
        return
    dirs = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    bound = Decimal("1e-13") if dtype == np.float64 else Decimal("1e-6")
    for ti, d in zip(t, dirs.astype(dtype)):
        assert _relative_error(ti, exact_hit((0, 0, 0), d, center, radius)) < bound


def _random_hits(rng, count, dtype):
    """count random spheres (radii 1e-4..1e4) and a hit on each.  Centres lie up to 1e4 away in
    float64; in float32 only as far as 'auto' would still choose float32 (100 radii)."""
    radii = 10 ** rng.uniform(-4, 4, count)
    if dtype == np.float64:
        centers = rng.uniform(-1e4, 1e4, (count, 3))
    else:
        centers = rng.uniform(-100, 100, (count, 3)) * radii[:, None]
        for center, radius in zip(centers, radii):
            scene = core.Scene(camera=core.ScreenCamera(2, 2, eye=tuple(center + 3 * radius)),
                               spheres=(core.Sphere(center, radius),))
            assert choose_precision(scene, "auto") == np.float32
    normals = rng.normal(size=(count, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # Shoot at each sphere from outside along -normal to get a hit point as the tracer finds it.
    origins = centers + normals * radii[:, None] * 3
    points = []
    for i in range(count):
        ctx = _context((core.Sphere(centers[i], radii[i]),), dtype)
        t, index = _shoot(ctx, origins[i:i + 1], -normals[i:i + 1])
        assert index[0] == 0
        direction = (-normals[i]).astype(dtype)
        points.append(origins[i].astype(dtype) + t[0] * direction)
    return centers, radii, np.array(points, dtype), normals


@pytest.mark.parametrize("dtype", DTYPES)
def test_rays_leaving_a_hit_point_never_rehit_its_sphere(dtype):
    """pbrt-v4 style: from many hit points on spheres of radii 1e-4..1e4, rays spawned into
    the outer hemisphere with the tracer's own offset never hit the same sphere again, even
    without the self-exclusion the tracer also applies."""
    from core.context import ray_offsets
    rng = np.random.default_rng(4)
    centers, radii, points, _ = _random_hits(rng, 60, dtype)
    for center, radius, point in zip(centers, radii, points):
        ctx = _context((core.Sphere(center, radius),), dtype)
        normal = (point.astype(np.float64) - center)
        normal /= np.linalg.norm(normal)
        directions = rng.normal(size=(200, 3))
        directions[directions @ normal < 0] *= -1
        scale = ray_offsets(point[:, None])[0]
        origin = (point + scale * normal.astype(dtype))[None, :]
        _, index = _shoot(ctx, np.repeat(origin, 200, 0), directions)
        assert (index == -1).all(), f"re-hit on radius {radius:g} at {center}"


@pytest.mark.parametrize("dtype", DTYPES)
def test_rays_leaving_an_inner_surface_reach_the_far_side(dtype):
    """From inside, the reflected ray hits the same sphere again, far away, never at ~0."""
    center, radius = np.array([1e3, -2e3, 5e2]), 50.0
    ctx = _context((core.Sphere(center, radius),), dtype)
    rng = np.random.default_rng(5)
    directions = rng.normal(size=(200, 3))
    t, index = _shoot(ctx, np.repeat(center[None, :], 200, 0), directions)
    assert (index == 0).all()
    points = center + t[:, None].astype(np.float64) * (
        directions / np.linalg.norm(directions, axis=1, keepdims=True))
    inward = -(points - center) / radius
    leaving = rng.normal(size=(200, 3))
    leaving[np.einsum("nc,nc->n", leaving, inward) < 0] *= -1
    t2, index2 = _shoot(ctx, points + 1e-4 * inward, leaving)
    assert (index2 == 0).all()
    assert t2.min() > 1e-3


@pytest.mark.parametrize("dtype", DTYPES)
def test_touching_and_coincident_spheres(dtype):
    a = core.Sphere((-1.0, 0.0, -5.0), 1.0, name="a")
    b = core.Sphere((1.0, 0.0, -5.0), 1.0, name="b")       # touches a at (0, 0, -5)
    twin = core.Sphere((1.0, 0.0, -5.0), 1.0, name="twin")  # coincides with b
    ctx = _context((a, b, twin), dtype)
    xs = np.linspace(-0.05, 0.05, 101)
    directions = np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, -5.0)])
    t, index = _shoot(ctx, [[0.0, 0.0, 0.0]], directions)
    # Left of the contact the ray meets a, right of it b (never the twin: b is listed first).
    assert set(index[xs < -1e-9]) <= {0} and set(index[xs > 1e-9]) <= {1, -1}
    assert (index != 2).all()
    scene = core.Scene(camera=core.ScreenCamera(60, 40, eye=(0, 0, 0)), spheres=(a, b, twin),
                       lights=(core.PointLight((0, 5, 0)),))
    assert choose_precision(scene, "auto") == np.float32
    for semantics in ("default", "article"):
        image = core.render(scene, core.RenderSettings(semantics=semantics,
                                                       precision=np.dtype(dtype).name)).image
        assert np.isfinite(image).all()


@pytest.mark.parametrize("make, field", [
    (lambda: core.Sphere((np.nan, 0, 0), 1.0, name="ball"), "sphere 'ball'.center[0]"),
    (lambda: core.Sphere((0, 0, 0), np.inf, name="ball"), "sphere 'ball'.radius"),
    (lambda: core.Sphere((0, 0, 0), 0.0, name="ball"), "sphere 'ball'.radius"),
    (lambda: core.Sphere((0, 0, 0), -1.0), "sphere.radius"),
    (lambda: core.Material(diffuse=(0.1, np.nan, 0)), "material.diffuse[1]"),
    (lambda: core.Material(reflection=1.5), "material.reflection"),
    (lambda: core.PointLight((0, np.inf, 0), name="key"), "light 'key'.position[1]"),
    (lambda: core.PointLight.from_power((0, 0, 0), (1, 1, 1), np.nan), "energy"),
    (lambda: core.ScreenCamera(width=0, height=10), "camera.width"),
    (lambda: core.BlenderCamera(((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, np.nan), (0, 0, 0, 1))),
     "camera.matrix_world[2][3]"),
    (lambda: core.BlenderCamera(np.eye(4), resolution_x=1, resolution_percentage=10),
     "gives a 0x"),
    (lambda: core.BlenderCamera(np.eye(4), sensor_fit="DIAGONAL"), "camera.sensor_fit"),
    (lambda: core.BlenderCamera(np.eye(4), clip_end=-1.0), "camera.clip_end"),
    (lambda: core.RenderSettings(precision="float16"), "settings.precision"),
    (lambda: core.RenderSettings(max_depth=0), "settings.max_depth"),
    (lambda: core.RenderSettings(anti_aliasing="msaa"), "settings.anti_aliasing"),
])
def test_invalid_input_names_the_field(make, field):
    with pytest.raises(core.SceneError) as error:
        make()
    assert field in str(error.value)


def test_render_rejects_non_scene_before_tracing():
    with pytest.raises(core.SceneError, match="scene must be a core.Scene"):
        core.render("article")


def test_precision_auto_picks_float64_for_the_floor_float32_for_small_scenes():
    assert choose_precision(core.article_scene(10, 10), "auto") == np.float64
    small = core.Scene(camera=core.ScreenCamera(10, 10),
                       spheres=(core.Sphere((0, 0, -3), 1.0), core.Sphere((1, 0, -4), 0.2)),
                       lights=(core.PointLight((5, 5, 5)),))
    assert choose_precision(small, "auto") == np.float32
    assert choose_precision(small, "float64") == np.float64


def test_float32_floor_speckles_in_article_semantics_not_in_default():
    """In float32 the floor's hit points are off by up to ~4e-4 (docs/article.md, "Numerics worth knowing"), 40x the article's
    fixed 1e-5 shift: the article's semantics in float32 speckles the floor (measured: 296 of
    60,000 pixels off by > 0.1), which is why 'auto' keeps the floor in float64.  The default
    semantics' scaled offsets and self-exclusion keep float32 close (measured: 2 pixels)."""
    scene = core.article_scene(300, 200)

    def speckles(semantics):
        exact = core.render(scene, core.RenderSettings(semantics=semantics,
                                                       precision="float64")).image
        single = core.render(scene, core.RenderSettings(semantics=semantics,
                                                        precision="float32")).image
        return int((np.abs(exact - single).max(axis=2) > 0.1).sum())

    assert speckles("article") > 100
    assert speckles("default") <= 20


@pytest.mark.parametrize("semantics", ["default", "article"])
def test_no_nan_reaches_the_image_in_hard_scenes(semantics):
    scenes = [
        core.Scene(camera=core.ScreenCamera(40, 30, eye=(0, 0, 0)),
                   spheres=(core.Sphere((0, 0, 0), 3.0), core.Sphere((0, 0, 0), 3.0),
                            core.Sphere((1e-7, 0, -1), 1e-4)),
                   lights=(core.PointLight((0, 0, 0)),)),                  # light inside too
        core.Scene(camera=core.ScreenCamera(40, 30, eye=(148376, 1234, -223423),
                                            left=148375, right=148377, top=1235, bottom=1233,
                                            screen_z=-223424),
                   spheres=(core.Sphere((148376, 1234, -223430), 2.0,
                                        core.Material(shininess=3.0)),),
                   lights=(core.PointLight((148376, 1240, -223423)),)),
    ]
    for scene in scenes:
        image = core.render(scene, core.RenderSettings(semantics=semantics)).image
        assert np.isfinite(image).all()
