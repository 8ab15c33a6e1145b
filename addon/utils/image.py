"""Writing a render into an Image datablock.

The Image is a generated float image holding the render result's scene-linear pixels
(``RenderJob.scene_linear``), in the working colour space ('Linear Rec.709'), with *View as
Render* on: the Image Editor shows it through the scene's view transform, look and exposure,
and ``Image.save_render`` writes it through them, exactly as Blender shows and saves its own
render result (one pipeline for F12, the Render button and render.py).  The alpha mode is
premultiplied, like render results.
"""

from __future__ import annotations

import bpy
import numpy as np

COLOUR_SPACE = 'Linear Rec.709'
#: Blender's datablock names: MAX_ID_NAME (66) minus the 2-byte type code and the final NUL.
MAX_NAME_BYTES = 63


class ImageError(Exception):
    """The named image exists and is not one Glint may overwrite."""


def check_image_name(name: str) -> None:
    """Raise ImageError unless ``name`` is free or names an image Glint may overwrite (a
    generated one), so a render never starts only to be thrown away, and never overwrites
    an image loaded from a file."""
    if not name.strip():
        raise ImageError("the Glint image name is empty: type the name of the image to render "
                         "into")
    size = len(name.encode("utf-8"))
    if size > MAX_NAME_BYTES:
        # Blender would cut the name short, so the image would never be found again under
        # it: every render would make a new one.
        raise ImageError(f"the Glint image name '{name[:20]}...' is {size} bytes long; "
                         f"Blender names hold at most {MAX_NAME_BYTES}: shorten it")
    image = bpy.data.images.get(name)
    if image is not None and image.source != 'GENERATED':
        raise ImageError(f"image '{name}' is a {image.source.lower()} image, which Glint does "
                         f"not overwrite: choose another image name")


def _target_image(name: str, width: int, height: int):
    """The image to write, created or reconfigured (float, size, colour space).

    A generated image rebuilds its buffer from these settings whenever one changes, so
    they are all set before any pixel is written.
    """
    check_image_name(name)
    image = bpy.data.images.get(name)
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    if not image.use_generated_float:
        image.use_generated_float = True
    if (image.generated_width, image.generated_height) != (width, height):
        image.generated_width, image.generated_height = width, height
    if tuple(image.size) != (width, height):
        image.scale(width, height)
    if image.colorspace_settings.name != COLOUR_SPACE:
        image.colorspace_settings.name = COLOUR_SPACE
    if image.alpha_mode != 'PREMUL':
        image.alpha_mode = 'PREMUL'
    if not image.use_view_as_render:
        image.use_view_as_render = True
    return image


def write_image(name: str, rgba: np.ndarray):
    """Write (H, W, 4) scene-linear premultiplied floats (row 0 = top) into the Image ``name``
    and return it.

    Created if missing, resized if needed, updated in place otherwise (so editors and
    materials using it keep their reference), and shown in an open Image Editor.
    """
    height, width = rgba.shape[:2]
    image = _target_image(name, width, height)
    # Blender's row 0 is the bottom row.
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], np.float32).ravel())
    image.update()
    show_in_image_editor(image)
    return image


def read_image(image) -> np.ndarray:
    """An Image's pixels as (H, W, 4) float32, row 0 = top (the inverse of write_image)."""
    width, height = image.size
    pixels = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[::-1].copy()


def show_in_image_editor(image) -> None:
    """Show the image in an Image Editor already showing it, else in the first unpinned one."""
    window_manager = bpy.context.window_manager
    if window_manager is None:
        return
    editors = [area for window in window_manager.windows for area in window.screen.areas
               if area.type == 'IMAGE_EDITOR']
    for area in editors:
        if area.spaces.active.image == image:
            area.tag_redraw()
            return
    for area in editors:
        space = area.spaces.active
        if not space.use_image_pin:
            space.image = image
            area.tag_redraw()
            return
