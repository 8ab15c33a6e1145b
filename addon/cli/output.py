"""render.py's files: what a frame becomes and how it is written.

``OutputPlan`` decides once per run, from the options and the .blend, what Blender must make
of a frame for the file: which view layers to render (only those the file shows), and whether
the file is Blender's render result after its compositor or sequencer, exactly as
``blender -b FILE -f N`` saves it (``write_render_result``), or, for a PNG of a file with
neither, the engine's frame handed over directly (``write_png``: the same pixels, without
Blender keeping a frame-sized render result).

Every file goes through Blender's colour management and image writer (``save_image``) into a
temporary file beside the target that is renamed over it only when complete
(``core.png.atomic_path``): a failure never leaves a partial file and never touches the
previous one.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Optional

from ..compat import all_strips, compositor_trees
from .report import RenderScriptError

#: Rows converted at a time by ``_to_blender_rows``: bounds its temporaries (float64 for the
#: sRGB curve) to a block instead of the frame.
ROW_BLOCK = 256

#: The image settings each output format saves with, in the order they are set (Blender 5.0
#: chooses the media type before the file format); the scene's own ('scene') are left as
#: they are.  Settings this Blender lacks (``media_type`` before 5.0) are skipped.
FORMAT_SETTINGS = {
    "png": (("media_type", 'IMAGE'), ("file_format", 'PNG'), ("color_mode", 'RGBA'),
            ("color_depth", '8')),
    "exr": (("media_type", 'IMAGE'), ("file_format", 'OPEN_EXR'), ("color_mode", 'RGBA'),
            ("color_depth", '32')),
    "multilayer-exr": (("media_type", 'MULTI_LAYER_IMAGE'), ("file_format", 'OPEN_EXR_MULTILAYER'),
                       ("color_depth", '32')),
    "scene": (),
}


@dataclass(frozen=True)
class OutputPlan:
    """fmt: 'png' (8-bit RGBA), 'exr' (single layer), 'multilayer-exr', or 'scene' (no
    --output: the .blend's own output format and settings).  from_render_result: the file is
    Blender's render result (after the compositor or sequencer, when the file uses them)
    rather than the engine's frame.  view_layers: the names of the view layers the file
    needs, or None for every one Blender would render."""

    fmt: str
    from_render_result: bool
    view_layers: Optional[tuple] = None

    @classmethod
    def choose(cls, scene, args) -> "OutputPlan":
        fmt = output_format(scene, args)
        if fmt == "scene" and is_video(scene):
            raise RenderScriptError(
                f"scene '{scene.name}' writes a video ({scene.render.image_settings.file_format})"
                f": render.py writes images; give --output FILE.png or FILE.exr")
        sequencer = uses_sequencer(scene)
        compositor = compositor_trees(scene) if scene.render.use_compositing else ()
        multilayer = fmt == "multilayer-exr" or (fmt == "scene" and is_multilayer(scene))
        if multilayer or sequencer:
            # Every layer goes into the file; a sequencer strip may show any of them.
            layers = None
        elif compositor:
            layers = compositor_layers(scene, compositor)
        else:
            # Blender's file of a frame (not a multilayer one) shows its first view layer.
            layers = tuple(layer.name for layer in scene.view_layers if layer.use)[:1] or None
        return cls(fmt, fmt != "png" or sequencer or bool(compositor), layers)

    def select_view_layers(self, scene) -> None:
        """Turn off (for this session) the view layers the file does not need, so that
        Blender does not render them; a layer already off stays off."""
        if self.view_layers is None:
            return
        for layer in scene.view_layers:
            layer.use = layer.use and layer.name in self.view_layers


def output_format(scene, args) -> str:
    if args.output is None:
        return "scene"
    if args.format is not None:
        return args.format
    if args.output.lower().endswith(".png"):
        return "png"
    return "multilayer-exr" if is_multilayer(scene) else "exr"


def is_multilayer(scene) -> bool:
    """Whether the scene's output format is a multilayer image (every view layer and pass)."""
    settings = scene.render.image_settings
    return getattr(settings, "media_type", None) == 'MULTI_LAYER_IMAGE' or \
        settings.file_format == 'OPEN_EXR_MULTILAYER'


def is_video(scene) -> bool:
    settings = scene.render.image_settings
    return getattr(settings, "media_type", None) == 'VIDEO' or settings.file_format == 'FFMPEG'


def uses_sequencer(scene) -> bool:
    """Whether Blender's output is the sequencer's (Post Processing > Sequencer on and the
    scene has strips)."""
    editor = scene.sequence_editor
    return scene.render.use_sequencer and editor is not None and len(all_strips(editor)) > 0


def compositor_layers(scene, trees) -> Optional[tuple]:
    """The names of ``scene``'s enabled view layers the compositor's node ``trees`` read
    (their Render Layers nodes, inside node groups too), or None when that cannot be told
    (a Cryptomatte node reading the render) or they read none of them: then every layer is
    rendered, as F12 does."""
    layers, seen = set(), set()

    def visit(nodes) -> bool:
        for node in nodes:
            if node.bl_idname == 'CompositorNodeCryptomatteV2' and node.source == 'RENDER':
                return False
            if node.bl_idname == 'CompositorNodeRLayers':
                if node.scene is None or node.scene == scene:
                    layers.add(node.layer)
            group = getattr(node, "node_tree", None)
            if group is not None and group.name not in seen:
                seen.add(group.name)
                if not visit(group.nodes):
                    return False
        return True

    if not all(visit(tree.nodes) for tree in trees):
        return None
    layers &= {layer.name for layer in scene.view_layers if layer.use}
    return tuple(sorted(layers)) or None


def scene_output_path(scene, frame: int) -> str:
    """Where ``blender -b FILE -f frame`` writes the frame: the scene's output path with
    Blender's frame numbering and file extension, relative paths from the .blend's folder
    (or the working folder for an unsaved file)."""
    return os.path.abspath(scene.render.frame_path(frame=frame))


def make_folder(path: str) -> None:
    """Make ``path``'s folder if it is missing, as Blender does for its output path."""
    try:
        os.makedirs(os.path.dirname(os.path.realpath(path)), exist_ok=True)
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None


def refuse_write_protected(path: str) -> None:
    """One line before anything is rendered for a file that cannot be replaced."""
    from ...core.png import write_protected

    if write_protected(os.path.realpath(path)):
        raise RenderScriptError(f"cannot write {path}: the file is write-protected")


def save_image(image, scene, path: str, settings=()) -> None:
    """Blender writes ``image`` (the Render Result, or a float Image) to ``path`` through the
    ``scene``'s colour management and output settings, with ``settings`` ((name, value) pairs
    of ImageFormatSettings, ``FORMAT_SETTINGS``) in place of the scene's for this save;
    atomically (``core.png.atomic_path``)."""
    from ...core.png import atomic_path

    image_settings = scene.render.image_settings
    settings = [(name, value) for name, value in settings if hasattr(image_settings, name)]
    previous = [(name, getattr(image_settings, name)) for name, _ in settings]
    try:
        for name, value in settings:
            setattr(image_settings, name, value)
        with atomic_path(path, suffix=os.path.splitext(path)[1] or ".tmp") as temporary:
            try:
                image.save_render(temporary, scene=scene)
            except RuntimeError as error:
                raise OSError(blender_reason(error)) from None
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None
    finally:
        for name, value in previous:
            setattr(image_settings, name, value)


def blender_reason(error: RuntimeError) -> str:
    """The message of an error a Blender operator or function raised, without its
    "Error: " prefix."""
    return str(error).strip().splitlines()[-1].removeprefix("Error: ")


def write_render_result(scene, path: str, fmt: str) -> None:
    """Blender's render result, as F12 shows it (after the compositor or sequencer), saved as
    ``fmt`` (``FORMAT_SETTINGS``; an EXR holds scene-linear float, the .blend's EXR codec
    kept)."""
    import bpy

    save_image(bpy.data.images["Render Result"], scene, path, FORMAT_SETTINGS[fmt])


def write_png(path: str, image, scene, job) -> None:
    """The engine's frame as an 8-bit RGBA PNG: what Blender's colour management makes of the
    render result, as F12 saves it and as the Render button's Image shows it (one pipeline).
    The ``job``'s image (row 0 = top), turned in place into its scene-linear pixels
    (``RenderJob.scene_linear``), goes into a temporary float Image in the working space with
    *View as Render* on, which Blender saves through the ``scene``'s view transform, look,
    exposure, gamma and dither."""
    import bpy

    from ..utils.image import COLOUR_SPACE

    blender_rows = _to_blender_rows(image, job)
    height, width = blender_rows.shape[:2]
    frame = bpy.data.images.new(".glint render.py output", width, height, alpha=True,
                                float_buffer=True)
    try:
        frame.colorspace_settings.name = COLOUR_SPACE
        frame.alpha_mode = 'PREMUL'
        frame.use_view_as_render = True
        frame.pixels.foreach_set(blender_rows.reshape(-1))
        save_image(frame, scene, path, FORMAT_SETTINGS["png"])
    finally:
        bpy.data.images.remove(frame)


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
