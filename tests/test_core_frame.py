"""An image does not depend on where the scene is or the unit it was modelled in
(``core.frame``): the same scene translated and scaled over the whole range validation
accepts (coordinates up to 1e300) renders the same picture, in the precision 'auto' picks
for its shape; a scene float64 cannot resolve is refused, naming the sphere."""

from __future__ import annotations

import numpy as np
import pytest

import core
from core.frame import MAX_SCALE_RATIO, canonical_scene


def cube(scale, at):
    """A 2 x 2 x 2 cube mesh (12 triangles) drawn twice: beside the balls and tilted above."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = [t for a, b, c, d in faces for t in ((a, b, c), (a, c, d))]
    def placed(centre, size, tilt):
        c, s_ = np.cos(tilt), np.sin(tilt)
        matrix = np.eye(4)
        matrix[:3, :3] = scale * size * np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
        matrix[:3, 3] = at(centre)
        return matrix
    return core.TriangleMesh(corners, np.array(triangles), None, np.zeros(12, int),
                             (core.Material(diffuse=(0.3, 0.8, 0.3), reflection=0.0),),
                             np.stack([placed((2.2, 1.0, 0.3), 0.3, 0.5),
                                       placed((0.3, 1.5, 1.6), 0.25, 1.0)]), "box")


def scene(scale=1.0, offset=(0.0, 0.0, 0.0), width=96, height=64, floor=True, extras=False):
    """Three balls (one a mirror) over a floor, a light with a radius and a Blender camera,
    all placed at scale * (x + offset); extras: a sphere set and an instanced cube mesh."""
    def at(p):
        return tuple(scale * (c + o) for c, o in zip(p, offset))
    balls = [((0.0, 0.0, 0.5), 0.5, core.Material(diffuse=(0.8, 0.2, 0.1), reflection=0.2)),
             ((1.2, 0.4, 0.3), 0.3, core.Material(diffuse=(0.1, 0.6, 0.9), reflection=0.0)),
             ((-1.0, 0.8, 0.4), 0.4, core.Material(diffuse=(0.9, 0.9, 0.9), reflection=0.9))]
    if floor:
        balls.append(((0.0, 0.0, -1000.0), 1000.0, core.Material(reflection=0.1)))
    spheres = tuple(core.Sphere(at(c), scale * r, m, f"ball{i}")
                    for i, (c, r, m) in enumerate(balls))
    light = core.PointLight(at((3.0, -3.0, 4.0)), radius=scale * 0.3, name="lamp")
    # A camera at (0, -6, 1.5) looking along +Y (rotation of 90 degrees about X).
    t = at((0.0, -6.0, 1.5))
    camera = core.BlenderCamera(
        matrix_world=((1, 0, 0, t[0]), (0, 0, -1, t[1]), (0, 1, 0, t[2]), (0, 0, 0, 1)),
        resolution_x=width, resolution_y=height, clip_start=scale * 0.1,
        clip_end=scale * 1e5)
    more = {}
    if extras:
        centres = np.array([at((x, -0.8, 0.12)) for x in np.linspace(-1.5, 1.5, 7)])
        more = dict(sphere_sets=(core.SphereSet(centres, np.full(7, scale * 0.12),
                                                np.zeros(7, int), (core.Material(),), "beads"),),
                    meshes=(cube(scale, at),))
    return core.Scene(camera=camera, spheres=spheres, lights=(light,),
                      background=(0.05, 0.1, 0.2), ambient=(0.05, 0.1, 0.2), **more)


SETTINGS = core.RenderSettings(light_samples=4)

#: (scale, offset in scene units): from 1e-300 to 1e290 (coordinates up to ~1e296, below
#: validation's 1e300), moved up to 1e6 scene units from the origin.  Powers of ten are not
#: powers of two, so the inputs themselves round; offsets round them once more.
PLACEMENTS = [(1e-300, (0, 0, 0)), (1e-150, (3e5, -1e6, 2e5)), (1e-19, (0, 0, 0)),
              (1.0, (1e6, 1e6, -1e6)), (1e19, (0, 0, 0)), (1e20, (-7e5, 0, 1e3)),
              (1e154, (0, 0, 0)), (1e155, (1e6, 0, 0)), (1e290, (2e5, 2e5, 2e5))]


@pytest.fixture(scope="module")
def reference():
    return core.render(scene(), SETTINGS)


@pytest.mark.parametrize("scale, offset", PLACEMENTS, ids=[f"{s:g}@{o}" for s, o in PLACEMENTS])
def test_a_scene_renders_the_same_wherever_and_however_large_it_is(reference, scale, offset):
    result = core.render(scene(scale, offset), SETTINGS)

    assert result.precision == reference.precision
    assert np.isfinite(result.image).all()
    # Rounding the inputs (1e-16 relative, 1e-10 of a ball's radius with the offsets) can
    # move a silhouette or shadow edge across a pixel centre, nothing more.
    moved = np.abs(result.image - reference.image).max(axis=2) > 1 / 255
    assert moved.mean() < 0.002, f"{moved.sum()} pixels differ"
    # Not a blank or flat picture: balls, floor, shadow and sky all differ.
    assert len(np.unique(np.round(result.image[..., :3], 2).reshape(-1, 3), axis=0)) > 50


@pytest.fixture(scope="module")
def reference_with_meshes():
    return core.render(scene(extras=True), SETTINGS)


#: Mesh instances: their validation needs the determinant of the 3 x 3 part to be a normal
#: float64 (scale^3), so meshes are accepted from about 1e-100 to 1e100.
MESH_PLACEMENTS = [(1e-90, (0, 0, 0)), (1.0, (1e6, -1e6, 0)), (1e20, (0, 5e5, 0)),
                   (1e90, (1e6, 0, 0))]


@pytest.mark.parametrize("scale, offset", MESH_PLACEMENTS,
                         ids=[f"{s:g}@{o}" for s, o in MESH_PLACEMENTS])
def test_meshes_and_sphere_sets_move_and_scale_with_the_scene(reference_with_meshes, scale,
                                                              offset):
    result = core.render(scene(scale, offset, extras=True), SETTINGS)
    moved = np.abs(result.image - reference_with_meshes.image).max(axis=2) > 1 / 255
    assert moved.mean() < 0.002, f"{moved.sum()} pixels differ"
    # The extras are in the picture: without them it differs.
    assert (np.abs(reference_with_meshes.image - core.render(scene(), SETTINGS).image)
            .max(axis=2) > 0.1).sum() > 50


def test_auto_precision_depends_on_the_shape_not_the_position():
    without_floor = [core.render(scene(scale, offset, floor=False), SETTINGS).precision
                     for scale, offset in [(1.0, (0, 0, 0)), (1e100, (1e6, 0, 0)),
                                           (1e-100, (0, -1e6, 0))]]
    assert without_floor == ["float32"] * 3  # balls only: extent / radius well under 500
    assert core.render(scene(1e100, (1e6, 0, 0)), SETTINGS).precision == "float64"  # floor


def test_a_scene_too_deep_for_float64_is_refused_naming_the_sphere():
    near = scene()
    tiny = core.Sphere((0.0, 0.0, 2.0), 1e-13, core.Material(), "speck")
    deep = core.Scene(camera=near.camera, spheres=near.spheres + (tiny,), lights=near.lights)

    with pytest.raises(core.SceneError, match=r"sphere 'speck' \(size 1e-13\).*float64"):
        core.render(deep, SETTINGS)


def test_the_canonical_scene_has_its_smallest_sphere_near_unit_size_at_the_eye():
    for scale, offset in PLACEMENTS:
        canonical = canonical_scene(scene(scale, offset), SETTINGS)
        matrix = np.array(canonical.camera.matrix_world)
        np.testing.assert_array_equal(matrix[:3, 3], 0.0)
        assert 0.5 <= min(s.radius for s in canonical.spheres) < 1.0
        assert max(np.abs(s.center).max() for s in canonical.spheres) < MAX_SCALE_RATIO


def test_article_semantics_keeps_the_scene_as_given():
    given = core.article_scene(30, 20)
    assert canonical_scene(given, core.RenderSettings(semantics="article")) is given


def mixed_scene(scale=1.0, offset=(0.0, 0.0, 0.0)):
    """``scene`` plus a box (a TriangleMesh placed by its transform) and two balls in a
    SphereSet, all at scale * (x + offset): the canonical frame must move them too."""
    base = scene(scale, offset, floor=True)
    corners = np.array([[x, y, z] for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (0, 0.6)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = np.array([tri for a, b, c, d in faces for tri in ((a, b, c), (a, c, d))])
    placement = np.eye(4)
    placement[:3, :3] *= scale
    placement[:3, 3] = scale * (np.array([0.6, -1.2, 0.0]) + offset)
    box = core.TriangleMesh(corners, triangles, None, np.zeros(12, int),
                            (core.Material(diffuse=(0.2, 0.9, 0.2), reflection=0.0),),
                            transforms=placement[None], name="box")
    balls = core.SphereSet(scale * (np.array([[-0.5, -1.5, 0.2], [0.2, -2.0, 0.15]]) + offset),
                           scale * np.array([0.2, 0.15]), np.zeros(2, int),
                           (core.Material(diffuse=(0.9, 0.1, 0.9)),), name="beads")
    return core.Scene(camera=base.camera, spheres=base.spheres, lights=base.lights,
                      background=base.background, ambient=base.ambient,
                      sphere_sets=(balls,), meshes=(box,))


@pytest.mark.parametrize("scale, offset", [(1e-150, (3e5, -1e6, 2e5)), (1.0, (1e6, 1e6, -1e6)),
                                           (1e20, (-7e5, 0, 1e3)), (1e155, (1e6, 0, 0))])
def test_meshes_and_sphere_sets_move_with_the_scene(scale, offset):
    reference = core.render(mixed_scene(), SETTINGS)
    result = core.render(mixed_scene(scale, offset), SETTINGS)

    # The green box is in both pictures (the reference goes through the frame too, so this is
    # what fails if the frame leaves meshes behind), and nothing moved.
    for image in (reference.image, result.image):
        red, green, blue = image[..., 0], image[..., 1], image[..., 2]
        assert ((green > 2 * red) & (green > 2 * blue)).sum() > 50
    moved = np.abs(result.image - reference.image).max(axis=2) > 1 / 255
    assert moved.mean() < 0.003, f"{moved.sum()} pixels differ"


def test_bounds_and_scale_ratio_cover_every_sphere_group_lights_meshes_and_the_eye():
    """``scene_bounds`` and ``precision.scale_ratio`` reduce each sphere group an axis at a
    time: the values of the formulas over all spheres at once (N, 3), for hand-made spheres,
    two sphere sets (the extremes in different ones, one set empty), a mesh, a light with a
    radius and the eye."""
    from core.frame import scene_bounds
    from core.precision import scale_ratio

    rng = np.random.default_rng(4)
    material = (core.Material(),)
    sets = [core.SphereSet(rng.uniform(-3, 3, (50, 3)) + shift, rng.uniform(0.1, 0.9, 50),
                           np.zeros(50, int), material) for shift in ((9, 0, 0), (0, -7, 4))]
    sets.append(core.SphereSet(np.zeros((0, 3)), np.zeros(0), np.zeros(0, int), material))
    spheres = (core.Sphere((0, 0, -20), 0.05), core.Sphere((1, 30, 0), 2.0))
    light = core.PointLight((-40, 2, 3), radius=1.5)
    camera = core.ScreenCamera(8, 8, eye=(0, 0, 12))
    scene = core.Scene(camera=camera, spheres=spheres, sphere_sets=tuple(sets),
                       lights=(light,))
    centres = np.concatenate([[s.center for s in spheres]] + [s.centers for s in sets])
    radii = np.concatenate([[s.radius for s in spheres]] + [s.radii for s in sets])
    every = np.concatenate([centres - radii[:, None], centres + radii[:, None],
                            [(-41.5, 0.5, 1.5), (-38.5, 3.5, 4.5), (0, 0, 12)]])
    lower, upper = scene_bounds(scene)
    assert np.array_equal(lower, every.min(axis=0)) and np.array_equal(upper, every.max(axis=0))
    extent = max((np.abs(centres).max(axis=1) + radii).max(), 12.0, 40 + 1.5)
    assert scale_ratio(scene) == extent / 0.05
    with_mesh = core.Scene(camera=camera, sphere_sets=tuple(sets), meshes=(cube(60, np.array),))
    from core.frame import _mesh_boxes
    mesh_low, mesh_high = _mesh_boxes(with_mesh)
    set_centres = np.concatenate([s.centers for s in sets])
    set_radii = np.concatenate([s.radii for s in sets])
    every = np.concatenate([set_centres - set_radii[:, None], set_centres + set_radii[:, None],
                            mesh_low, mesh_high, [(0, 0, 12)]])
    lower, upper = scene_bounds(with_mesh)
    assert np.array_equal(lower, every.min(axis=0)) and np.array_equal(upper, every.max(axis=0))
    assert upper[0] == mesh_high[:, 0].max() > set_centres[:, 0].max()   # a mesh's bound
    assert scale_ratio(with_mesh) == np.inf
