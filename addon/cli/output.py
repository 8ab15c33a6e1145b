"""render.py's files: an 8-bit RGBA PNG of the frame through the scene's colour management
(``write_png``: the pixels F12 saves and the Render button's Image shows), or an OpenEXR of
Blender's render result (``write_exr``).  Both are written atomically: a failure never leaves
a partial file and never touches the previous one."""

from __future__ import annotations

import os

from .report import RenderScriptError

#: Rows converted at a time by ``_to_blender_rows``: bounds its temporaries (float64 for the
#: sRGB curve) to a block instead of the frame.
ROW_BLOCK = 256


def output_format(scene, args) -> str:
    if args.format is not None:
        return args.format
    if args.output.lower().endswith(".png"):
        return "png"
    settings = scene.render.image_settings
    multilayer = getattr(settings, "media_type", None) == 'MULTI_LAYER_IMAGE' or \
        settings.file_format == 'OPEN_EXR_MULTILAYER'
    return "multilayer-exr" if multilayer else "exr"


def write_png(path: str, image, scene, job) -> None:
    """Write the frame as an 8-bit RGBA PNG, atomically: what Blender's colour management makes
    of the render result, as F12 saves it and as the Render button's Image shows it (one
    pipeline).  The ``job``'s image (row 0 = top), turned into its scene-linear pixels
    (``RenderJob.scene_linear``), goes into a temporary float Image in the working space with
    *View as Render* on, which ``Image.save_render`` writes through the ``scene``'s view
    transform, look, exposure, gamma and dither; the scene's output format is left as it
    was."""
    from ...core.png import write_atomically

    try:
        write_atomically(path, _colour_managed_png(scene, _to_blender_rows(image, job)))
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None


def _to_blender_rows(image, job):
    """The job's (H, W, 4) float32 image (row 0 = top) turned, in place and a block of rows at
    a time, into what Blender's render result holds (``RenderJob.scene_linear``), rows from
    the bottom; returns it.  In place because at 8K or 16K every full-frame copy is another
    0.5 or 4.3 GB (the image is not used after it is written)."""
    import numpy as np

    height = image.shape[0]
    for start in range(0, height, ROW_BLOCK):
        rows = slice(start, min(start + ROW_BLOCK, height))
        image[rows] = job.scene_linear(image[rows])
    half = height // 2
    for start in range(0, half, ROW_BLOCK):   # flip the rows, swapping blocks
        end = min(start + ROW_BLOCK, half)
        top = image[start:end].copy()
        image[start:end] = image[height - end:height - start][::-1]
        image[height - end:height - start] = top[::-1]
    return np.ascontiguousarray(image, np.float32)   # no copy for the job's float32 image


def _colour_managed_png(scene, blender_rows) -> bytes:
    """PNG bytes of premultiplied scene-linear (H, W, 4) pixels (row 0 = bottom, as
    ``_to_blender_rows`` gives them) saved by Blender with ``scene``'s colour management
    (``write_png``)."""
    import tempfile

    import bpy

    from ..utils.image import COLOUR_SPACE

    height, width = blender_rows.shape[:2]
    image = bpy.data.images.new(".glint render.py output", width, height, alpha=True,
                                float_buffer=True)
    settings = scene.render.image_settings
    names = [name for name in ("media_type", "file_format", "color_mode", "color_depth")
             if hasattr(settings, name)]
    previous = {name: getattr(settings, name) for name in names}
    handle, temporary = tempfile.mkstemp(prefix=".glint-", suffix=".png")
    os.close(handle)
    try:
        image.colorspace_settings.name = COLOUR_SPACE
        image.alpha_mode = 'PREMUL'
        image.use_view_as_render = True
        image.pixels.foreach_set(blender_rows.reshape(-1))
        if "media_type" in previous:
            settings.media_type = 'IMAGE'
        settings.file_format, settings.color_mode, settings.color_depth = 'PNG', 'RGBA', '8'
        try:
            image.save_render(temporary, scene=scene)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise OSError(reason) from None
        with open(temporary, "rb") as stream:
            return stream.read()
    finally:
        for name, value in previous.items():
            setattr(settings, name, value)
        bpy.data.images.remove(image)
        os.unlink(temporary)


def write_exr(scene, path: str, multilayer: bool) -> None:
    """Blender's render result as an OpenEXR file (scene-linear float, what Blender's own EXR
    output holds): single-layer RGBA of the Combined pass, or multilayer with every view layer
    and pass.  Written to a temporary file beside the target and renamed over it, so a failure
    leaves no partial file.  The .blend's EXR codec is kept."""
    import bpy

    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5.0
        settings.media_type = 'MULTI_LAYER_IMAGE' if multilayer else 'IMAGE'
    if not multilayer:
        settings.file_format = 'OPEN_EXR'
        settings.color_mode = 'RGBA'
    settings.color_depth = '32'
    target = os.path.realpath(path)
    folder, name = os.path.split(target)
    temporary = os.path.join(folder, f".{name}.{os.getpid()}.tmp.exr")
    try:
        bpy.data.images["Render Result"].save_render(filepath=temporary, scene=scene)
        os.replace(temporary, target)
    except (OSError, RuntimeError) as error:
        if os.path.exists(temporary):
            os.remove(temporary)
        reason = getattr(error, "strerror", None) or str(error).strip().splitlines()[-1]
        raise RenderScriptError(f"cannot write {path}: {reason}") from None
