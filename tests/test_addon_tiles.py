"""F12 shows tiles as they land: each finished tile is merged into Blender's render result
(``begin_result`` / ``end_result`` per tile, as Cycles does), so a cancelled render keeps
what finished.  Headless Blender has no render window to watch, so the tiles are observed
through a cancel: the render result saved after it holds exactly the tiles that landed."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from addon_support import read_png, simple_scene
from glint.addon.engine.final import FrameRequest, requesting_frames
from glint.core.settings import RenderSettings

TILE = RenderSettings().tile_size


def saved_render_result(path):
    bpy.data.images["Render Result"].save_render(str(path))
    return read_png(str(path))


def rgba_f12(scene, tmp_path, name):
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    bpy.ops.render.render()
    return saved_render_result(tmp_path / name)


@pytest.mark.slow
def test_a_cancelled_f12_keeps_the_tiles_that_finished(tmp_path):
    scene = simple_scene()
    scene.render.engine = 'GLINT'
    scene.render.resolution_x, scene.render.resolution_y = 5 * TILE, 4 * TILE
    full = rgba_f12(scene, tmp_path, "full.png")
    landed = []

    def tile_landed(job, fraction):   # called as each tile lands
        landed.append(fraction)

    def cancel_after_two_tiles():
        return len(landed) >= 2

    with requesting_frames(FrameRequest(should_cancel=cancel_after_two_tiles,
                                        progress=tile_landed)) as request:
        partial = rgba_f12(scene, tmp_path, "partial.png")

    assert request.frames == []      # the frame never finished
    finished = 0
    for row in range(4):
        for col in range(5):
            block = (slice(row * TILE, (row + 1) * TILE), slice(col * TILE, (col + 1) * TILE))
            if (partial[block][..., 3] == 0).all():
                continue              # not rendered: the result's initial transparent black
            finished += 1
            # A finished tile holds the full render's pixels (8-bit, dithering off).
            assert np.abs(partial[block].astype(int) - full[block].astype(int)).max() <= 1
    assert 2 <= finished < 20
