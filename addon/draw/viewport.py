"""The viewport's picture: a ``ViewportFrame`` (``addon.engine.viewport``) drawn as a texture
over the region rectangle it covers, the way Blender's custom render engine template does
(``bind_display_space_shader`` so Blender's colour management applies to the scene-linear
values, premultiplied alpha blending over the viewport's background).  A coarse pass's small
texture is stretched over the whole rectangle."""

from __future__ import annotations

import numpy as np

from ..utils.colour import render_result_pixels


def texture_pixels(image: np.ndarray, semantics: str = "article") -> np.ndarray:
    """(h, w, 4) job values of ``semantics`` (article: display values; default: scene-linear
    radiance), row 0 = top -> the texture's (h * w * 4,) float32: scene-linear premultiplied
    (what render results hold), row 0 = bottom (GPU textures', like Blender's images)."""
    return np.ascontiguousarray(render_result_pixels(image[::-1], semantics),
                                np.float32).ravel()


class FrameDrawer:
    """Holds the texture of the frame last uploaded, so a redraw of the same frame (a region
    redrawn for an overlay) costs no upload."""

    def __init__(self):
        self._frame = None
        self._texture = None

    def draw(self, engine, scene, frame) -> None:
        import gpu
        from gpu_extras.presets import draw_texture_2d

        if frame is not self._frame:
            height, width = frame.image.shape[:2]
            pixels = texture_pixels(frame.image, frame.semantics)
            buffer = gpu.types.Buffer('FLOAT', pixels.size, pixels)
            self._texture = gpu.types.GPUTexture((width, height), format='RGBA16F', data=buffer)
            self._frame = frame
        x0, y0, x1, y1 = frame.rect
        gpu.state.blend_set('ALPHA_PREMULT')
        engine.bind_display_space_shader(scene)
        draw_texture_2d(self._texture, (x0, y0), x1 - x0, y1 - y0)
        engine.unbind_display_space_shader()
        gpu.state.blend_set('NONE')
