"""The world's occlusion directions: a stratified grid of cosine-weighted directions per
point, shifted per pixel (``core.lights.shifted_cosine_direction``, ``pixel_shifts``).

With one grid for every point, a flat surface's points all traced the same 9 lines, and an
occluder cast 9 sharp copies of its shadow on it (the corpus' basic-visibility plane showed
a pattern of squares Cycles does not have).  Shifted per pixel, the same count of rays
gives noise that averages out instead, and the estimate stays unbiased."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import core
from core.sampler import cosine_directions, pixel_shifts, shifted_cosine_direction

WHITE_WORLD = dict(background=(1, 1, 1), ambient=(1, 1, 1))
#: World Samples and adaptive AA are the Whitted integrator's.
WHITTED = dict(integrator="whitted")


def test_an_unshifted_grid_is_the_cell_centres_and_any_shift_keeps_the_cosine_spread():
    for count in (1, 4, 9, 16):
        centres = cosine_directions(count)
        for sample in range(len(centres)):
            middle = shifted_cosine_direction(count, sample, np.full((1, 2), 0.5))
            np.testing.assert_allclose(middle[:, 0], centres[sample], atol=1e-12)
    shifts = np.random.default_rng(7).random((20_000, 2))
    directions = np.concatenate([shifted_cosine_direction(9, j, shifts) for j in range(9)],
                                axis=1)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=0), 1.0, atol=1e-12)
    assert (directions[2] >= 0).all()
    # Density cos(theta) / pi over the hemisphere: E[cos] = 2/3, E[cos^2] = 1/2, no side.
    z = directions[2]
    assert abs(z.mean() - 2 / 3) < 3e-3 and abs((z * z).mean() - 0.5) < 3e-3
    assert abs(directions[0].mean()) < 5e-3 and abs(directions[1].mean()) < 5e-3


def _square_of(direction):
    """The point of [-1, 1]^2 that Shirley & Chiu's concentric map and the lift onto the
    hemisphere take to unit ``direction`` (3, m): that map undone."""
    x, y = direction[0], direction[1]
    r = np.hypot(x, y)
    phi = np.arctan2(y, x)
    phi = np.where(phi < -np.pi / 4, phi + 2 * np.pi, phi)
    quarter = np.pi / 4
    a = np.select([phi < quarter, phi < 3 * quarter, phi < 5 * quarter],
                  [r, (np.pi / 2 - phi) * r / quarter, -r], (phi - 3 * np.pi / 2) * r / quarter)
    b = np.select([phi < quarter, phi < 3 * quarter, phi < 5 * quarter],
                  [phi * r / quarter, r, -(phi - np.pi) * r / quarter], -r)
    return np.stack([a, b])


def test_one_shift_moves_every_direction_within_its_own_cell():
    # A point's k x k directions stay one in each cell of the grid, each in the cell of its
    # unshifted direction, so a shifted grid is as stratified as the centred one (checked
    # in the square, the concentric map undone).
    shifts = np.random.default_rng(3).random((500, 2))
    cell = lambda square: np.floor((square + 1) * 1.5).astype(int).clip(0, 2)   # 3 x 3 cells
    centres = _square_of(cosine_directions(9).T)
    for sample in range(9):
        moved = _square_of(shifted_cosine_direction(9, sample, shifts))
        assert (cell(moved) == cell(centres[:, sample:sample + 1])).all()
    assert len({tuple(c) for c in cell(centres).T}) == 9


def test_pixel_shifts_are_deterministic_spread_and_unrelated_between_neighbours():
    rows, cols = np.mgrid[0:64, 0:64]
    shifts = pixel_shifts(cols.ravel(), rows.ravel())
    assert shifts.shape == (4096, 2) and (shifts >= 0).all() and (shifts < 1).all()
    np.testing.assert_array_equal(shifts, pixel_shifts(cols.ravel(), rows.ravel()))
    # Uniform on the square (each quarter about a quarter), and no lattice between
    # neighbours: an additive recurrence over the pixels (R2) drew a hatching.
    quarters = np.bincount((shifts[:, 0] >= 0.5) * 2 + (shifts[:, 1] >= 0.5), minlength=4)
    assert (np.abs(quarters / 4096 - 0.25) < 0.03).all()
    grid = shifts.reshape(64, 64, 2)
    for axis in (0, 1):
        step = np.diff(grid, axis=axis).reshape(-1, 2) % 1.0
        assert len(np.unique(np.round(step, 3), axis=0)) > 1000
        for channel in (0, 1):
            a = np.take(grid[..., channel], np.arange(63), axis=axis).ravel()
            b = np.take(grid[..., channel], np.arange(1, 64), axis=axis).ravel()
            assert abs(np.corrcoef(a, b)[0, 1]) < 0.06


def _ball_on_a_floor(size=96):
    matte = core.SurfaceMaterial(diffuse=(0.8, 0.8, 0.8))
    floor = core.TriangleMesh(np.array([[-6.0, -6, 0], [6, -6, 0], [6, 6, 0], [-6, 6, 0]]),
                              np.array([[0, 1, 2], [0, 2, 3]]), None, np.zeros(2, int),
                              (matte,))
    above = core.BlenderCamera(((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 12), (0, 0, 0, 1)),
                               resolution_x=size, resolution_y=size, lens=35)
    return core.Scene(above, (core.Sphere((0, 0, 1.0), 1.0, matte),), meshes=(floor,),
                      **WHITE_WORLD)


@pytest.mark.slow
def test_a_ball_on_a_floor_darkens_it_with_noise_not_with_copies_of_its_shadow():
    """A white world, no light: the floor around the ball sees less of the sky.  Against 256
    world samples, 9 samples' error over 8 x 8 boxes of floor is 0.13 of its error per pixel
    (noise, averaging out; the same 9 directions everywhere gave 0.87: copies of the ball's
    shadow, whole shapes wrong), and the means of floor and ball agree within 0.1 and 1 %
    (the fixed grid: 1.0 and 3.7 % too bright).  The image does not depend on the tiles."""
    scene = _ball_on_a_floor()
    nine, converged = (core.render(scene, core.RenderSettings(**WHITTED, world_samples=count,
                                                               anti_aliasing="off"))
                       .image[..., :3] for count in (9, 256))
    primitive = core.render(scene, core.RenderSettings(**WHITTED, world_samples=0,
                                                       anti_aliasing="off"),
                            passes=True).passes.primitive
    floor, ball = primitive >= 1, primitive == 0
    error = (nine - converged).sum(axis=-1)
    blocks = lambda a: a.reshape(12, 8, 12, 8).transpose(0, 2, 1, 3).reshape(144, 64)
    whole = blocks(floor).all(axis=1)
    box_error = blocks(error)[whole].mean(axis=1)
    per_pixel = np.sqrt(np.mean(error[floor] ** 2))
    assert per_pixel > 0.02                     # the floor does see the ball (noise to average)
    assert np.sqrt(np.mean(box_error ** 2)) < 0.3 * per_pixel
    for where, tolerance in ((floor, 0.01), (ball, 0.02)):
        assert abs(nine[where].mean() / converged[where].mean() - 1) < tolerance
    tiled = core.render(scene, core.RenderSettings(**WHITTED, world_samples=9,
                                                   anti_aliasing="off",
                                                   tile_size=16)).image[..., :3]
    np.testing.assert_array_equal(tiled, nine)


def _faceted_ball_on_a_floor(size=96):
    """A flat-shaded 24 x 12 UV sphere (every facet its own surface to adaptive AA's
    signatures) on a floor, seen from the side against the sky, lit by a white world alone."""
    matte = core.SurfaceMaterial(diffuse=(0.8, 0.8, 0.8))
    theta = np.linspace(0, np.pi, 13)[:, None]
    phi = np.linspace(0, 2 * np.pi, 25)[None, :-1]
    ring = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                     np.cos(theta) * np.ones_like(phi)], axis=-1).reshape(-1, 3)
    index = np.arange(13 * 24).reshape(13, 24)
    a, b = index[:-1], np.roll(index, -1, axis=1)[:-1]
    c, d = index[1:], np.roll(index, -1, axis=1)[1:]
    triangles = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3),
                                np.stack([b, c, d], -1).reshape(-1, 3)])
    triangles = triangles[(triangles[:, 0] != triangles[:, 1])
                          & (triangles[:, 1] != triangles[:, 2])
                          & (triangles[:, 0] != triangles[:, 2])]
    ball = core.TriangleMesh(ring + [0, 0, 1.0], triangles, None,
                             np.zeros(len(triangles), int), (matte,))
    floor = core.TriangleMesh(np.array([[-6.0, -6, 0], [6, -6, 0], [6, 6, 0], [-6, 6, 0]]),
                              np.array([[0, 1, 2], [0, 2, 3]]), None, np.zeros(2, int),
                              (matte,))
    side = core.BlenderCamera(((1, 0, 0, 0), (0, 0, -1, -7), (0, 1, 0, 1.2), (0, 0, 0, 1)),
                              resolution_x=size, resolution_y=size, lens=50)
    return core.Scene(side, (), meshes=(ball, floor), background=(0.3, 0.3, 0.3),
                      ambient=(1, 1, 1))


@pytest.mark.slow
def test_adaptive_aa_allows_for_the_worlds_noise_and_still_finds_silhouettes(monkeypatch):
    """Per pixel, the world's occlusion is noise; with no allowance for it, most facet
    creases of the ball (and of the floor's two triangles) step past EDGE_CONTRAST
    somewhere, and adaptive AA supersampled them: at least twice as many pixels as with
    NOISE_ALLOWANCE's 2 standard deviations.  The silhouettes against the sky still are:
    alpha along them is fixed 16's."""
    tiles_module = importlib.import_module("core.tiles")
    scene = _faceted_ball_on_a_floor()
    # (threads: the patched constant must reach the tiles)
    adaptive = core.RenderSettings(**WHITTED, anti_aliasing="adaptive", samples=16,
                                   parallelism="threads")
    allowed = core.render(scene, adaptive)
    monkeypatch.setattr(tiles_module, "NOISE_ALLOWANCE", 0.0)
    bare = core.render(scene, adaptive)
    assert allowed.stats.supersampled_pixels * 2 <= bare.stats.supersampled_pixels
    fixed = core.render(scene, core.RenderSettings(**WHITTED, anti_aliasing="fixed", samples=16))
    silhouette = (fixed.image[..., 3] > 0.05) & (fixed.image[..., 3] < 0.95)
    assert silhouette.sum() > 40
    np.testing.assert_allclose(allowed.image[silhouette, 3], fixed.image[silhouette, 3],
                               atol=0.13)
