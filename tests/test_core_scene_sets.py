"""Array sets of the scene description: SphereSet and TriangleMesh, validated whole-array."""

from __future__ import annotations

import numpy as np
import pytest

import core

MATERIAL = core.Material()


def _spheres(n=20, **changes):
    rng = np.random.default_rng(0)
    fields = dict(centers=rng.normal(size=(n, 3)), radii=rng.uniform(0.1, 1, n),
                  material_indices=np.zeros(n, np.int64), materials=(MATERIAL,),
                  name="Points")
    fields.update(changes)
    return core.SphereSet(**fields)


def _cube_mesh(**changes):
    vertices = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    fields = dict(vertices=vertices, triangles=triangles, corner_normals=None,
                  material_indices=np.zeros(len(triangles), np.int64), materials=(MATERIAL,),
                  name="Cube")
    fields.update(changes)
    return core.TriangleMesh(**fields)


def test_sphere_set_keeps_read_only_float64_copies():
    centers = np.zeros((3, 3), np.float32)
    spheres = core.SphereSet(centers, [1, 2, 3], [0, 0, 1], (MATERIAL, core.Material()))
    assert spheres.centers.dtype == np.float64 and spheres.radii.dtype == np.float64
    assert spheres.material_indices.dtype == np.int64 and len(spheres) == 3
    centers[0, 0] = 5.0                       # the caller's array is not the set's
    assert spheres.centers[0, 0] == 0.0
    with pytest.raises(ValueError):
        spheres.radii[0] = 7.0


def test_empty_sphere_set_is_valid():
    assert len(core.SphereSet(np.zeros((0, 3)), [], [], (MATERIAL,))) == 0


@pytest.mark.parametrize("changes, message", [
    (dict(radii=np.r_[np.ones(17), -1.0, np.ones(2)]),
     "sphere set 'Points': 1 of 20 spheres draw nothing, as in Cycles (radii[17] is -1.0)"),
    (dict(radii=np.r_[np.ones(5), 0.0, np.ones(14)]),
     "sphere set 'Points': 1 of 20 spheres draw nothing, as in Cycles (radii[5] is 0.0)"),
    (dict(radii=np.r_[np.ones(3), np.inf, np.nan, np.ones(15)]),
     "sphere set 'Points': 2 of 20 spheres draw nothing, as in Cycles (radii[3] is inf)"),
    (dict(centers=np.where(np.arange(60).reshape(20, 3) == 31, np.nan, 0.0)),
     "sphere set 'Points': 1 of 20 spheres draw nothing, as in Cycles "
     "(centers[10] is [0.0, nan, 0.0])"),
])
def test_spheres_that_draw_nothing_are_left_out_with_one_warning(changes, message):
    """Cycles draws nothing for a point of radius <= 0 or a point or radius that is not finite
    (measured: a point cloud of radius -0.3 renders as none; a NaN point is missing)."""
    given = _spheres()
    spheres = _spheres(**changes)
    (warning,) = spheres.warnings
    assert warning == message
    kept = np.isfinite(spheres.centers).all() and (spheres.radii > 0).all()
    assert kept and len(spheres) == 20 - int(warning.split(": ")[1].split()[0])
    assert not spheres.radii.flags.writeable and not spheres.centers.flags.writeable
    assert not given.warnings


@pytest.mark.parametrize("changes, message", [
    (dict(material_indices=np.r_[np.zeros(9, int), 1, np.zeros(10, int)]),
     "material_indices[9] must be in [0, 1)"),
    (dict(material_indices=np.r_[np.zeros(2, int), -1, np.zeros(17, int)]),
     "material_indices[2] must be in [0, 1)"),
    (dict(material_indices=np.zeros(20)), "material_indices must hold integers"),
    (dict(radii=np.ones(19)), "radii must have shape (20), got (19,)"),
    (dict(centers=np.zeros((20, 2))), "centers must have shape (N x 3)"),
    (dict(materials=()), "materials must hold at least one material"),
    (dict(materials=("red",)), "materials[0] must be a material"),
])
def test_sphere_set_errors_name_set_field_and_first_index(changes, message):
    with pytest.raises(core.SceneError) as error:
        _spheres(**changes)
    assert message in str(error.value)


def test_sphere_set_validates_a_million_spheres_as_arrays():
    n = 1_000_000
    spheres = core.SphereSet(np.zeros((n, 3)), np.ones(n), np.zeros(n, np.int64), (MATERIAL,))
    assert len(spheres) == n
    radii = np.ones(n)
    radii[n - 2] = -3.0
    spheres = core.SphereSet(np.zeros((n, 3)), radii, np.zeros(n, np.int64), (MATERIAL,))
    assert len(spheres) == n - 1
    assert spheres.warnings == (f"sphere set: 1 of {n} spheres draw nothing, as in Cycles "
                                f"(radii[{n - 2}] is -3.0)",)


def test_triangle_mesh_defaults_to_one_identity_instance_and_normalises_normals():
    mesh = _cube_mesh()
    assert mesh.transforms.shape == (1, 4, 4) and (mesh.transforms[0] == np.eye(4)).all()
    assert len(mesh) == 12
    normals = np.tile([[0.0, 0.0, 2.0]], (12, 3, 1))
    smooth = _cube_mesh(corner_normals=normals, transforms=np.stack([np.eye(4)] * 3))
    assert np.allclose(smooth.corner_normals[..., 2], 1.0) and len(smooth) == 36


def _shifted(matrix_changes):
    transforms = np.stack([np.eye(4)] * 4)
    for (k, r, c), value in matrix_changes.items():
        transforms[k, r, c] = value
    return transforms


@pytest.mark.parametrize("changes, message", [
    (dict(triangles=np.r_[np.zeros((4, 3), int), [[0, 1, 8]], np.zeros((7, 3), int)]),
     "mesh 'Cube': triangles[4][2] must be in [0, 8) (vertices), got 8"),
    (dict(material_indices=np.r_[np.zeros(11, int), 3]), "material_indices[11] must be in [0, 1)"),
    (dict(corner_normals=np.zeros((12, 3, 3))), "corner_normals[0][0] must not be zero"),
    (dict(corner_normals=np.ones((11, 3, 3))), "corner_normals must have shape (12 x 3 x 3)"),
    (dict(transforms=_shifted({(2, 3, 0): 1.0})), "transforms[2] must be affine"),
    (dict(transforms=_shifted({(1, 2, 2): 0.0})), "transforms[1] is singular"),
    (dict(transforms=_shifted({(3, 0, 3): np.nan})), "transforms[3][0][3] must be finite"),
    (dict(transforms=np.zeros((0, 4, 4))), "transforms must hold at least one"),
    (dict(triangles=np.zeros((12, 3))), "triangles must hold integers"),
])
def test_triangle_mesh_errors_name_mesh_field_and_first_index(changes, message):
    with pytest.raises(core.SceneError) as error:
        _cube_mesh(**changes)
    assert message in str(error.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 2e300])
def test_triangles_touching_a_vertex_that_is_not_finite_are_left_out_with_one_warning(bad):
    """As Cycles leaves them out (measured: a UV sphere with one NaN vertex renders with a
    hole where the triangles around it were); the other triangles, their normals and
    materials stay in step."""
    vertices = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    vertices[4, 1] = bad
    normals = np.zeros((12, 3, 3))
    normals[:, :, 0], normals[:, :, 1] = 1.0, np.arange(12.0)[:, None]  # y / x: the index
    materials = (MATERIAL, core.Material(diffuse=(1.0, 0.0, 0.0)))
    mesh = _cube_mesh(vertices=vertices, corner_normals=normals, materials=materials,
                      material_indices=np.arange(12) % 2)
    touching = (_cube_mesh().triangles == 4).any(axis=1)
    (warning,) = mesh.warnings
    assert warning == (f"mesh 'Cube': {touching.sum()} of 12 triangles dropped: they touch a "
                       f"vertex not finite or past 1e+300 in size (vertices[4] is [1.0, "
                       f"{bad!r}, -1.0])")
    assert np.array_equal(mesh.triangles, _cube_mesh().triangles[~touching])
    assert np.array_equal(mesh.material_indices, (np.arange(12) % 2)[~touching])
    assert np.allclose(mesh.corner_normals[:, 0, 1] / mesh.corner_normals[:, 0, 0],
                       np.arange(12.0)[~touching])
    assert np.isfinite(mesh.vertices).all() and len(mesh) == 12 - touching.sum()
    assert not mesh.triangles.flags.writeable and not mesh.vertices.flags.writeable
    assert not _cube_mesh().warnings


def test_scene_holds_sets_and_rejects_other_things():
    camera = core.ScreenCamera(4, 4)
    scene = core.Scene(camera=camera, sphere_sets=[_spheres()], meshes=[_cube_mesh()])
    assert isinstance(scene.sphere_sets, tuple) and isinstance(scene.meshes, tuple)
    with pytest.raises(core.SceneError, match=r"scene.sphere_sets\[0\] must be a SphereSet"):
        core.Scene(camera=camera, sphere_sets=[_cube_mesh()])
    with pytest.raises(core.SceneError, match=r"scene.meshes\[1\] must be a TriangleMesh"):
        core.Scene(camera=camera, meshes=[_cube_mesh(), _spheres()])


def test_sphere_set_renders_like_the_same_spheres_listed_one_by_one():
    """Default semantics moves the scene into its canonical frame (core.frame): sets must
    move with everything else, so a set and the same spheres as core.Sphere objects give the
    same image."""
    rng = np.random.default_rng(4)
    centers = np.column_stack([rng.uniform(-1, 1, 40), rng.uniform(-0.5, 0.5, 40),
                               rng.uniform(-4, -2, 40)])
    radii = rng.uniform(0.05, 0.2, 40)
    materials = (core.Material(diffuse=(0.8, 0.2, 0.2)), core.Material(reflection=0.0))
    indices = rng.integers(0, 2, 40)
    camera = core.ScreenCamera(48, 32)
    lights = (core.PointLight((3, 4, 2)),)
    listed = core.Scene(camera=camera, lights=lights, spheres=tuple(
        core.Sphere(tuple(c), r, materials[i]) for c, r, i in zip(centers, radii, indices)))
    as_set = core.Scene(camera=camera, lights=lights,
                        sphere_sets=(core.SphereSet(centers, radii, indices, materials),))
    for semantics in ("default", "article"):
        settings = core.RenderSettings(semantics=semantics, precision="float64")
        a = core.render(listed, settings).image
        b = core.render(as_set, settings).image
        assert np.array_equal(a, b)
        assert (a[..., 3] == 1).sum() > 30


def _mesh_of(corner_normals):
    """A mesh of len(corner_normals) copies of one triangle, with those normals."""
    count = len(corner_normals)
    return core.TriangleMesh(vertices=np.eye(3), triangles=np.tile([0, 1, 2], (count, 1)),
                             corner_normals=corner_normals,
                             material_indices=np.zeros(count, np.int64), materials=(MATERIAL,),
                             name="Blocks")


def test_corner_normals_are_normalised_block_by_block_as_whole():
    """Normalised in blocks of BLOCK_ROWS triangles (their temporaries stay small): the same
    bits as the whole-array formula, a new read-only array, the caller's left as it was."""
    from core.validation import BLOCK_ROWS

    count = 2 * BLOCK_ROWS + 5
    normals = np.random.default_rng(3).normal(size=(count, 3, 3))
    given = normals.copy()
    mesh = _mesh_of(normals)
    whole = normals / np.sqrt((normals * normals).sum(axis=2))[:, :, None]
    assert np.array_equal(mesh.corner_normals, whole)
    assert not mesh.corner_normals.flags.writeable and not np.shares_memory(mesh.corner_normals,
                                                                             normals)
    assert np.array_equal(normals, given) and normals.flags.writeable


def test_a_zero_corner_normal_past_the_first_block_is_named_by_its_own_index():
    from core.validation import BLOCK_ROWS

    normals = np.ones((BLOCK_ROWS + 10, 3, 3))
    normals[BLOCK_ROWS + 7, 1] = 0.0
    with pytest.raises(core.SceneError,
                       match=rf"corner_normals\[{BLOCK_ROWS + 7}\]\[1\] must not be zero"):
        _mesh_of(normals)
    float32 = np.ones((4, 3, 3), np.float32)
    assert _mesh_of(float32).corner_normals.dtype == np.float64  # converted, not refused
