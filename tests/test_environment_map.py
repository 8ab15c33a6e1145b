"""The environment map the integrator samples the world with (``core.environment``): its
radiance against Cycles (with the Mapping node's rotation), its density (integrates to one,
matches what ``sample`` draws), and what importance sampling buys for irradiance against
uniform sampling at equal sample counts, on Blender's studio-light HDRIs."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest
from mathutils import Euler

from addon_support import glint  # noqa: F401  (registers the add-on)
from test_shader_images import (STUDIO_LIGHTS, add_camera, cycles_file, environment_world,
                                glint_node, pixel_rays, points_for, render_cycles)

from glint.addon.export.context import ExportContext
from glint.addon.export.node_options import OPTION_READERS
from glint.core.environment import EnvironmentMap, equirectangular_directions
from glint.core.shader.images import equirectangular_uv

ROTATION = (0.3, -0.2, 1.1)


def studio_map(name: str, rotation=None, **settings) -> EnvironmentMap:
    """The map of a studio light, its ImageData exported as an Environment Texture's."""
    cycles_file()
    texture = environment_world(os.path.join(STUDIO_LIGHTS, name))
    image = OPTION_READERS[texture.bl_idname](
        texture, ExportContext.for_camera(None, judged_from=None))["image"]
    matrix = None if rotation is None else np.array(Euler(rotation, 'XYZ').to_matrix())
    return EnvironmentMap(image, rotation=matrix, **settings)


def uniform_directions(rng, n):
    z = rng.uniform(-1, 1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z])


@pytest.mark.slow
@pytest.mark.cycles
def test_radiance_with_rotation_matches_cycles():
    """The map's radiance of a direction is the world's, rotated by the Mapping node in front
    of the Environment Texture, as Cycles shows it."""
    environment = studio_map("courtyard.exr", rotation=ROTATION)
    cycles_file(48)
    add_camera(location=(0.0, 0.0, 0.0), target=(-0.3, 1.0, 0.2), lens=18.0)
    texture = environment_world(os.path.join(STUDIO_LIGHTS, "courtyard.exr"),
                                rotation=ROTATION)
    _, directions = pixel_rays()
    glint_image = environment.radiance(directions).T.reshape(48, 48, 3)
    cycles = render_cycles()[..., :3]
    # Cycles' 0.01-pixel filter moves a sample up to 0.005 pixel: allow how much the
    # radiance changes over that (test_shader_images' environment test), plus float32.
    moved = [environment.radiance(pixel_rays(dx, dy)[1]).T.reshape(48, 48, 3)
             for dx in (-0.005, 0.005) for dy in (-0.005, 0.005)]
    spread = np.max([np.abs(image - glint_image) for image in moved], axis=0)
    assert np.all(np.abs(glint_image - cycles) <= 1e-4 + 1e-4 * np.abs(cycles) + spread)
    (unrotated,), _ = glint_node(texture, points_for(directions))
    assert np.abs(unrotated.T.reshape(48, 48, 3) - cycles).max() > 0.1   # rotation matters


@pytest.mark.slow
def test_map_cells_sit_on_the_texels():
    """At the image's own resolution (Cycles' Auto), each cell's centre is its texel's centre:
    the weights are the texels' mean |RGB| times sin(theta), as Cycles' background_cdf."""
    environment = studio_map("sunrise.exr")
    texels = environment.image.tile_texels().astype(np.float64)[..., :3]   # row 0: bottom
    theta = np.pi * (1 - (np.arange(environment.res_y) + 0.5) / environment.res_y)
    expected = np.abs(texels).mean(axis=-1) * np.sin(theta)[:, None]
    assert environment.weights.shape == (512, 1024)
    assert np.allclose(environment.weights, expected, rtol=1e-5, atol=1e-9)


def cell_directions(environment, rng=None):
    """(3, cells) directions and (cells,) solid angles of the map's cells: their centres, or
    with ``rng`` one direction uniformly distributed (by solid angle) in each cell."""
    res_x, res_y = environment.res_x, environment.res_y
    rows, columns = np.divmod(np.arange(res_x * res_y), res_x)
    low = np.cos(np.pi * (1 - rows / res_y))            # cos(theta) at each cell's bottom
    high = np.cos(np.pi * (1 - (rows + 1) / res_y))
    if rng is None:
        u, v = (columns + 0.5) / res_x, (rows + 0.5) / res_y
    else:
        u = (columns + rng.random(len(rows))) / res_x
        v = 1 - np.arccos(low + (high - low) * rng.random(len(rows))) / np.pi
    return equirectangular_directions(u, v), (high - low) * 2 * np.pi / res_x


@pytest.mark.slow
@pytest.mark.parametrize("name, rotation", [("sunrise.exr", None), ("forest.exr", ROTATION)])
def test_pdf_integrates_to_one(name, rotation):
    """Monte Carlo over the sphere, stratified by the map's cells (one direction uniform in
    each, 524,288 in all: a uniform estimate would see the sun's few cells a handful of
    times), four independent runs: the integral of the pdf is 1 within four standard errors
    of their mean, which is below 1e-3."""
    environment = studio_map(name, rotation)
    rng = np.random.default_rng(1)
    runs = []
    for _ in range(4):
        directions, solid_angle = cell_directions(environment, rng)
        runs.append((environment.pdf(directions) * solid_angle).sum())
    error = np.std(runs, ddof=1) / 2
    assert abs(np.mean(runs) - 1) < 4 * error + 1e-9
    assert error < 1e-3


@pytest.mark.slow
def test_samples_follow_the_pdf():
    """200,000 directions drawn from the map: their pdf and radiance are the map's at those
    directions, and their counts over 32 x 16 blocks of cells match the cells' probabilities
    (chi-square below its mean + 6 standard deviations)."""
    environment = studio_map("sunrise.exr")
    rng = np.random.default_rng(2)
    n = 200_000
    directions, pdf, radiance = environment.sample(rng.random(n), rng.random(n))
    assert np.allclose(np.linalg.norm(directions, axis=0), 1)
    assert np.allclose(pdf, environment.pdf(directions), rtol=1e-9)
    assert np.allclose(radiance, environment.radiance(directions), rtol=1e-6)
    assert np.all(pdf > 0)
    u, v = equirectangular_uv(directions)
    bins_x, bins_y = 32, 16
    column = np.clip((u * bins_x).astype(int), 0, bins_x - 1)
    row = np.clip((v * bins_y).astype(int), 0, bins_y - 1)
    observed = np.bincount(row * bins_x + column, minlength=bins_x * bins_y)
    weights = environment.weights.astype(np.float64)
    probability = weights.reshape(bins_y, 512 // bins_y, bins_x, 1024 // bins_x).sum(
        axis=(1, 3)).ravel() / weights.sum()
    expected = probability * n
    used = expected >= 5
    chi2 = ((observed[used] - expected[used]) ** 2 / expected[used]).sum()
    dof = used.sum() - 1
    assert chi2 < dof + 6 * np.sqrt(2 * dof), (chi2, dof)
    assert observed[~used].sum() <= 5 * max(1, (~used).sum())


def irradiance_estimates(environment, normal, rng, n):
    """(importance, uniform) per-sample estimates of the irradiance (mean RGB) on a surface
    of unit ``normal``: L cos+ / pdf with directions drawn from the map, and L cos+ 4 pi with
    uniform directions."""
    normal = np.asarray(normal, np.float64)[:, None]
    directions, pdf, radiance = environment.sample(rng.random(n), rng.random(n))
    cosine = np.maximum((directions * normal).sum(axis=0), 0)
    importance = radiance.mean(axis=0) * cosine / pdf
    directions = uniform_directions(rng, n)
    cosine = np.maximum((directions * normal).sum(axis=0), 0)
    uniform = environment.radiance(directions).mean(axis=0) * cosine * 4 * np.pi
    return importance, uniform


def irradiance_quadrature(environment, normal):
    """(irradiance, variance of one uniform sample's estimate) on a surface of unit
    ``normal``, summed over the map's cells at their centres (a uniform estimate's variance
    cannot be measured by sampling when a small sun holds much of the light: 200,000
    directions meet its few cells a handful of times)."""
    directions, solid_angle = cell_directions(environment)
    value = environment.radiance(directions).mean(axis=0) * np.maximum(
        (directions * np.asarray(normal, np.float64)[:, None]).sum(axis=0), 0)
    irradiance = (value * solid_angle).sum()
    return irradiance, 4 * np.pi * (value ** 2 * solid_angle).sum() - irradiance ** 2


def sun_direction(environment):
    row, column = np.unravel_index(environment.weights.argmax(), environment.weights.shape)
    return equirectangular_directions([(column + 0.5) / environment.res_x],
                                      [(row + 0.5) / environment.res_y])[:, 0]


def normals(sun):
    """Four surface normals: up, towards the sun, horizontal across it, down."""
    across = np.array([sun[1], -sun[0], 0.0]) / np.hypot(sun[0], sun[1])
    return (("up", (0, 0, 1)), ("towards the sun", sun), ("horizontal", across),
            ("down", (0, 0, -1)))


@pytest.mark.slow
def test_importance_sampling_has_uniform_samplings_mean():
    """Irradiance on four normals under sunset.exr (a broad sun: uniform sampling converges),
    200,000 samples each way: the importance-sampled estimate has the uniform one's mean,
    within four standard errors of their difference."""
    environment = studio_map("sunset.exr")
    rng = np.random.default_rng(3)
    n = 200_000
    for label, normal in normals(sun_direction(environment)):
        importance, uniform = irradiance_estimates(environment, normal, rng, n)
        error = np.sqrt(importance.var() / n + uniform.var() / n)
        assert abs(importance.mean() - uniform.mean()) < 4 * error, label


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sunset.exr", "sunrise.exr"])
def test_importance_sampling_cuts_the_variance(name):
    """Irradiance on four normals: the importance-sampled mean of 200,000 samples is the
    cells' sum within four standard errors, and where the sun lights the surface its
    variance is a small fraction of uniform sampling's at equal sample counts (sunrise.exr:
    a small sun holding half the light).  The ratios are printed (pytest -s)."""
    environment = studio_map(name)
    rng = np.random.default_rng(4)
    n = 200_000
    for label, normal in normals(sun_direction(environment)):
        importance, _ = irradiance_estimates(environment, normal, rng, n)
        irradiance, uniform_variance = irradiance_quadrature(environment, normal)
        error = importance.std() / np.sqrt(n)
        ratio = importance.var() / uniform_variance
        print(f"{name}, normal {label}: irradiance {importance.mean():.4g} +- {error:.2g} "
              f"(importance), {irradiance:.4g} (cells); variance ratio to uniform sampling "
              f"{ratio:.3g}")
        assert abs(importance.mean() - irradiance) < 4 * error + 2e-3 * irradiance, label
        if label in ("up", "towards the sun"):
            assert ratio < 0.25, label
