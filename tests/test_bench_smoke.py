"""The bench's two reference implementations compute the article's image (correctness only:
the bench times them, tests never do)."""

import os

import numpy as np

from bench import baseline, per_pixel
from core import article_scene

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The image the article's own program produces (a copy of shared/reference/article_300x200.npy).
REFERENCE = os.path.join(REPOSITORY, "tests", "data", "article_300x200.npy")
#: A 30 x 20 crop holding the red and green spheres' edge, shadow and floor.
ROWS, COLUMNS = range(110, 130), range(100, 130)


def test_baseline_reproduces_the_article_image():
    reference = np.load(REFERENCE)
    image = baseline.render(article_scene(300, 200), max_depth=3)
    assert image.shape == (200, 300, 4)
    assert np.abs(image[..., :3] - reference).max() <= 1e-9
    # alpha is the camera ray's coverage: every lit pixel is covered.
    assert np.all(image[..., 3][reference.sum(axis=-1) > 0] == 1.0)


def test_baseline_in_bands_equals_one_broadcast():
    scene = article_scene(60, 40)
    whole = baseline.render(scene)
    assert np.array_equal(baseline.render_in_chunks(scene, max_elements=60 * 4 * 7), whole)


def test_per_pixel_program_matches_the_article_image_on_a_crop():
    reference = np.load(REFERENCE)[ROWS.start:ROWS.stop, COLUMNS.start:COLUMNS.stop]
    crop = per_pixel.render(article_scene(300, 200), max_depth=3, rows=ROWS, columns=COLUMNS)
    assert crop.shape == (20, 30, 3)
    # The crop is not trivial: shadowed (black) pixels and both spheres' colours.
    assert (reference.sum(axis=-1) == 0).any()
    assert (reference[..., 1] > reference[..., 0] + 0.1).any()
    assert (reference[..., 0] > reference[..., 1] + 0.1).any()
    assert np.abs(crop - reference).max() <= 1e-9
