"""Soft lights and the world spread over a pixel's anti-aliasing samples (``core.lights``
sample shares), and adaptive AA's edge test (``core.tiles.EDGE_CONTRAST``): a supersampled
pixel traces about as many shadow rays per light as its centre alone, every stratum of a
light still counts once per pixel, and a surface of many flat facets of one colour is not an
"edge" everywhere.  All of it is the Whitted integrator's (``WHITTED``); the path
integrator samples lights and the world per path (``core.path``)."""

from __future__ import annotations

import numpy as np
import pytest

import core
from core.sampler import diagonal_grid, fibonacci_sphere, pixel_shares, share_weights

GREY = core.SurfaceMaterial(diffuse=(0.5, 0.5, 0.5))
WHITTED = dict(integrator="whitted")


def top_camera(size, height=3.0, lens=50.0):
    """A camera at (0, 0, height) looking straight down at the floor z = 0."""
    return core.BlenderCamera(matrix_world=((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, height),
                                            (0, 0, 0, 1)),
                              resolution_x=size, resolution_y=size, lens=lens)


def grid_floor(cells: int, half: float = 4.0, material=GREY, bend: float = 0.0):
    """A flat-shaded square of cells x cells quads (2 cells^2 facets) over z = 0, raised to
    z = bend (x^2 + y^2): a shallow bowl whose facets' normals differ by small angles, as
    CLEVR's subdivided backdrop's do (coplanar facets are one surface, ``core.arrays``)."""
    u = np.linspace(-half, half, cells + 1)
    x, y = np.meshgrid(u, u, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), bend * (x * x + y * y).ravel()], axis=1)
    index = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return core.TriangleMesh(vertices, triangles, None, np.zeros(len(triangles), int),
                             (material,))


def square_light(z=4.0, size=2.0, power=2000.0):
    return core.AreaLight((0, 0, z), (0, 0, -1), (1, 0, 0), (0, 1, 0), size_x=size,
                          power=power)


@pytest.mark.parametrize("aa, samples, per_pixel", [("off", 1, 16), ("fixed", 4, 16),
                                                    ("fixed", 16, 16), ("fixed", 64, 64)])
def test_a_pixel_traces_max_of_light_and_aa_samples_shadow_rays(aa, samples, per_pixel):
    # Every pixel sees the lit floor, so every sample it traces is one shadow ray: S AA
    # samples would trace 16 S each without the shares (1,024 at S = 64).
    scene = core.Scene(camera=top_camera(8), meshes=(grid_floor(1),), lights=(square_light(),))
    settings = core.RenderSettings(**WHITTED, anti_aliasing=aa, samples=samples,
                                   light_samples=16, world_samples=0)
    stats = core.render(scene, settings).stats
    assert stats.shadow_rays == 64 * per_pixel


@pytest.mark.parametrize("samples, per_pixel", [(1, 9), (4, 9), (16, 16), (36, 36)])
def test_world_directions_are_max_of_world_and_aa_samples_per_pixel(samples, per_pixel):
    # A small ball out of view makes the world's occlusion rays worth tracing.
    ball = core.Sphere((20, 0, 0), 0.5, GREY)
    scene = core.Scene(camera=top_camera(8), spheres=(ball,), meshes=(grid_floor(1),),
                       background=(0.2, 0.3, 0.5), ambient=(0.2, 0.3, 0.5))
    settings = core.RenderSettings(**WHITTED, anti_aliasing="fixed" if samples > 1 else "off",
                                   samples=samples, world_samples=9)
    assert core.render(scene, settings).stats.shadow_rays == 64 * per_pixel


@pytest.mark.parametrize("samples, count", [(16, 16), (4, 16), (5, 16), (64, 16), (16, 9),
                                            (16, 32), (7, 3)])
def test_a_pixels_samples_weigh_every_light_sample_once(samples, count):
    cols, rows = np.arange(50) * 37 % 101, np.arange(50) * 11 % 53
    weights = share_weights(pixel_shares(cols, rows, samples), count)
    per_pixel = weights.reshape(count, len(cols), samples)
    # The mean over a pixel's samples weighs every light sample exactly 1, as a centre does.
    assert np.allclose(per_pixel.mean(axis=2), 1.0)
    # Each AA sample traces about count / samples of them, at least one.
    traced = (per_pixel > 0).sum(axis=0)
    assert traced.min() >= max(1, count // samples)
    assert traced.max() <= max(1, -(-count // samples))


def test_which_sample_sees_which_stratum_differs_from_pixel_to_pixel():
    cols, rows = np.meshgrid(np.arange(16), np.arange(16))
    slots = pixel_shares(cols.ravel(), rows.ravel(), 16).slot.reshape(-1, 16)
    first = slots[:, 0]                  # the stratum class of each pixel's sample 0
    assert len(np.unique(first)) == 16
    assert not np.array_equal(first[:16], first[16:32])


def test_a_penumbra_seen_by_half_the_light_gets_every_stratum():
    # A plate over x < 0 at half the light's height hides exactly the light's x < 0 half
    # (8 of its 16 strata) from floor points with |x| < 0.5: visibility 1/2 everywhere there.
    # One stratum per AA sample must still add up to it, not to 0 or 1.
    plate = core.TriangleMesh(np.array([[-9.0, -9, 2], [-0.0, -9, 2], [-0.0, 9, 2],
                                        [-9, 9, 2]]), np.array([[0, 1, 2], [0, 2, 3]]), None,
                              np.zeros(2, int), (GREY,))
    camera = top_camera(16, height=0.5, lens=50.0)   # sees |x| < 0.18 of the floor
    scene = core.Scene(camera=camera, meshes=(grid_floor(1), plate),
                       lights=(square_light(z=4.0, size=2.0),))
    settings = dict(WHITTED, light_samples=16, world_samples=0, max_depth=1)
    centre = core.render(scene, core.RenderSettings(**settings)).image[..., :3]
    fixed = core.render(scene, core.RenderSettings(anti_aliasing="fixed", samples=16,
                                                   **settings))
    unblocked = core.render(core.Scene(camera=camera, meshes=(grid_floor(1),),
                                       lights=(square_light(z=4.0, size=2.0),)),
                            core.RenderSettings(**settings)).image[..., :3]
    # Half the light: about half the light of the unblocked floor at pixel centres (the
    # halves deliver a little differently off the light's axis) ...
    assert np.allclose(centre / unblocked, 0.5, atol=0.08)
    # ... and the shared samples agree with the centres' full estimate within the light's
    # change across a pixel (1 %), where a sample's one stratum is all (0) or nothing (2x).
    assert np.allclose(fixed.image[..., :3], centre, rtol=0.01)
    assert fixed.stats.shadow_rays == 16 * 16 * 16


@pytest.mark.slow
def test_flat_facets_of_one_colour_are_not_edges_but_shadows_and_silhouettes_are():
    ball = core.Sphere((0.3, 0.2, 0.6), 0.5, core.SurfaceMaterial(diffuse=(0.8, 0.2, 0.2)))
    scene = core.Scene(camera=top_camera(64, height=6.0, lens=35.0), spheres=(ball,),
                       meshes=(grid_floor(40, bend=0.02),),  # 2 pixels a cell
                       lights=(core.SphereLight((2.0, 1.0, 4.0), power=3000.0),))
    adaptive = core.render(scene, core.RenderSettings(**WHITTED, anti_aliasing="adaptive",
                                                      samples=16))
    fixed = core.render(scene, core.RenderSettings(**WHITTED, anti_aliasing="fixed",
                                                   samples=16)).image
    reference = core.render(scene, core.RenderSettings(**WHITTED, anti_aliasing="fixed",
                                                       samples=64))
    plain = core.render(scene, core.RenderSettings(**WHITTED)).image

    def rms(image):
        return float(np.sqrt(np.mean((image - reference.image) ** 2)))

    # Without the colour test every pixel is an "edge" (each facet its own surface: 3,784 of
    # 4,096 pixels); the ball's silhouette and its hard shadow's edge are a few hundred.
    assert 0 < adaptive.stats.supersampled_pixels < 0.15 * 64 * 64
    # They are found: the error is fixed 16's, not the centres'.
    assert rms(adaptive.image) < 1.3 * rms(fixed)
    assert rms(adaptive.image) < 0.5 * rms(plain)


@pytest.mark.slow
def test_soft_lights_with_adaptive_aa_do_not_depend_on_tiles_or_threads():
    ball = core.Sphere((0.3, 0.2, 0.6), 0.5, core.SurfaceMaterial(diffuse=(0.8, 0.2, 0.2)))
    scene = core.Scene(camera=top_camera(24, height=6.0, lens=35.0), spheres=(ball,),
                       meshes=(grid_floor(4),),
                       lights=(square_light(), core.SphereLight((2, 1, 4), power=500.0, radius=0.5),
                               core.SunLight((-0.3, 0.2, -1), strength=2.0, angle=0.2)),
                       background=(0.1, 0.1, 0.2), ambient=(0.1, 0.1, 0.2))
    images = [core.render(scene, core.RenderSettings(**WHITTED, anti_aliasing=aa, samples=8,
                                                     tile_size=tile, threads=threads)).image
              for aa in ("adaptive", "fixed") for tile, threads in ((8, 1), (128, 1), (16, 2))]
    for first in (0, 3):
        for other in (1, 2):
            assert np.array_equal(images[first], images[first + other])


def test_a_colour_step_is_an_edge_and_a_gradient_is_not():
    from core.tiles import EDGE_CONTRAST, _edges

    width = 12
    ramp = np.linspace(0.2, 0.8, width)                  # 0.055 a pixel: 14 8-bit levels
    display = np.zeros((3, width, 4))
    display[..., :3] = ramp[None, :, None]
    display[..., 3] = 1
    signature = np.tile(np.arange(width, dtype=np.uint64), (3, 1))  # every pixel a facet
    assert not _edges(signature, display)[0].any()
    stepped = display.copy()
    stepped[:, 6:, 0] += 3 * EDGE_CONTRAST               # a step between columns 5 and 6
    edge, _ = _edges(signature, stepped)
    assert edge[:, 5:7].all() and edge.sum() == 6
    line = display.copy()
    line[:, 3, 3] = 0                                     # a one-pixel gap in alpha
    assert _edges(signature, line)[0][:, 2:5].all()
    # A step the signatures do not see (one surface) is left alone.
    assert not _edges(np.zeros((3, width), np.uint64), stepped)[0].any()


def _prefix_estimates(visible, samples, first):
    """(pixels,) each pixel's estimate of the share of a light's samples that are visible
    (visible (F,) 0 or 1) from its first ``first`` AA samples of ``samples``, through the
    sample shares (``share_weights``), for pixels of every hash rotation."""
    cols, rows = np.meshgrid(np.arange(16), np.arange(16))
    shares = pixel_shares(cols.ravel(), rows.ravel(), samples)
    weights = share_weights(shares, len(visible)).reshape(len(visible), -1, samples)
    # Each AA sample's estimate (its weighted visible samples over F), averaged over the
    # pixel's first samples, as adaptive AA averages a pixel stopped there.
    per_sample = (weights * visible[:, None, None]).sum(axis=0) / len(visible)
    return per_sample[:, :first].mean(axis=1)


@pytest.mark.parametrize("first", [4, 8])
def test_the_first_samples_of_a_pixel_see_a_sphere_light_evenly(first):
    # A sphere light (S Fibonacci points and their antipodes, as ``prepare_light`` makes)
    # seen only through its equatorial band, |z| < 0.5 (a blocker above and one below): a
    # pixel that stops after its first 4 or 8 AA samples (adaptive AA's rounds) must not see
    # only the poles.  (Consecutive slots gave the first 4 samples of some pixels the 8
    # points of both polar caps: an estimate of 0 where half the light is seen; such pixels
    # came out black along edges lit by small sphere lights.)
    normals = fibonacci_sphere(16)
    normals = np.concatenate([normals, -normals])
    visible = (np.abs(normals[:, 2]) < 0.5).astype(float)
    estimates = _prefix_estimates(visible, 16, first)
    assert np.allclose(_prefix_estimates(visible, 16, 16), visible.mean())
    assert np.abs(estimates - visible.mean()).max() <= 0.5 / first + 1e-9


@pytest.mark.parametrize("axis", [0, 1])
def test_the_first_samples_of_a_pixel_see_every_row_and_column_of_a_grid(axis):
    # A square light (or the world's directions) half hidden by an edge along either axis of
    # its 4 x 4 grid: the first 4 AA samples of every pixel see exactly half of it.
    visible = (diagonal_grid(16)[:, axis] < 0).astype(float)
    assert visible.mean() == 0.5
    assert np.allclose(_prefix_estimates(visible, 16, 4), 0.5)


@pytest.mark.parametrize("count", [4, 9])
def test_the_first_samples_of_a_pixel_trace_different_samples_of_a_small_light(count):
    # Fewer light samples than AA samples: the first 4 AA samples of a pixel trace 4
    # different light samples (and all of them when the light has 4).
    cols, rows = np.meshgrid(np.arange(16), np.arange(16))
    weights = share_weights(pixel_shares(cols.ravel(), rows.ravel(), 16), count)
    traced = weights.reshape(count, -1, 16)[:, :, :4] > 0       # (count, pixels, 4)
    assert (traced.sum(axis=0) == 1).all()                      # one light sample each
    assert (traced.any(axis=2).sum(axis=0) == 4).all()          # four different ones
