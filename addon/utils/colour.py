"""Where Glint's colours meet Blender's.

Default semantics: the core works in Blender's scene-linear colours and radiance, so
nothing is converted either way; Blender's colour management (view transform, look,
exposure) turns the render result into display values.

Article semantics: the core works in the article's numbers, sRGB-encoded display values.
The sRGB transfer function (``core.colour``) converts, so that:

* a colour picked in Blender keeps its look: a swatch Blender shows as 0.7 red becomes the
  core's 0.7 red (``colour_from_blender``);
* a render result handed to Blender as ``srgb_to_linear(core value)`` is displayed and saved,
  with view transform Standard, as the core's value again.
"""

from __future__ import annotations

import numpy as np

from ...core.colour import linear_to_srgb, srgb_to_linear  # noqa: F401  (re-exported)


def colour_from_blender(rgb) -> tuple[float, float, float]:
    """A Blender (scene-linear) colour as a core colour: sRGB-encoded, negatives clamped to 0."""
    encoded = linear_to_srgb(np.maximum(np.asarray(rgb, np.float64)[:3], 0.0))
    return tuple(float(c) for c in encoded)


def premultiplied_to_scene_linear(rgba: np.ndarray) -> np.ndarray:
    """(..., 4) premultiplied display values -> premultiplied scene-linear values (a copy).

    The transfer function applies to the unpremultiplied colour; a pixel with alpha 0 stays
    (0, 0, 0, 0).
    """
    out = np.array(rgba, np.float32, copy=True)
    alpha = out[..., 3:4]
    covered = alpha > 0
    straight = np.divide(out[..., :3], alpha, out=np.zeros_like(out[..., :3]), where=covered)
    out[..., :3] = np.where(covered, srgb_to_linear(straight) * alpha, 0.0)
    return out


def render_result_pixels(rgba: np.ndarray, semantics: str) -> np.ndarray:
    """A job's (..., 4) premultiplied image as Blender's render results hold it, float32 (a
    copy): the default semantics' scene-linear radiance unchanged, the article semantics'
    display values through the inverse sRGB curve (``premultiplied_to_scene_linear``)."""
    if semantics == "article":
        return premultiplied_to_scene_linear(rgba)
    return np.array(rgba, np.float32, copy=True)


def unpremultiply(rgba: np.ndarray) -> np.ndarray:
    """(..., 4) premultiplied -> straight alpha (PNG's convention), a copy; alpha 0 gives 0."""
    out = np.array(rgba, np.float64, copy=True)
    alpha = out[..., 3:4]
    out[..., :3] = np.divide(out[..., :3], alpha, out=np.zeros_like(out[..., :3]),
                             where=alpha > 0)
    return out
