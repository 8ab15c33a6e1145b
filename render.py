"""Render a .blend (or the article's scene) with Glint to an 8-bit RGBA PNG.

    blender -b scene.blend --python render.py -- --output OUT.png [options]
    python render.py [scene.blend] --output OUT.png [options]        (pip bpy)

Both do the same job.  Without a .blend, the article's scene is built in Blender
(``addon.utils.article_scene``).  Options override the scene's settings; everything else
(camera, objects, materials, world, Film > Transparent, ...) comes from the .blend.  The
frame is rendered by Glint's render engine, exactly as F12 would render it, and the PNG is
Blender's render result saved through the scene's colour management (view transform, look,
exposure), the pixels F12 saves.  With Film > Transparent, alpha is the spheres' coverage and
the background is transparent.

How the add-on is loaded: this file sits in the repository root, which is the extension
package itself (``__init__.py``, ``addon/``, ``core/``).  ``import_glint`` loads that directory
as the package ``glint`` (``importlib.util.spec_from_file_location`` with
``submodule_search_locations``), whatever the checkout's directory is called, so the
add-on's relative imports work; it is then registered for this session (an installed Glint
extension, if enabled, is disabled for the session so the two do not clash).  Tests use the
same function.

Errors (missing or unreadable .blend, no camera, unwritable output, bad option) print one
line and exit non-zero; the PNG is written through a temporary file in the output folder and
renamed, so a failure never leaves a partial file.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

REPOSITORY = os.path.dirname(os.path.abspath(__file__))
PACKAGE_NAME = "glint"
PROGRAM = "render.py"

EXIT_USAGE = 2   # bad option (argparse's convention)
EXIT_FAILURE = 1  # the render could not be made


class RenderScriptError(Exception):
    """A problem reported to the user as one line."""


def import_glint():
    """The repository as the package ``glint`` (see the module docstring)."""
    module = sys.modules.get(PACKAGE_NAME)
    if module is not None:
        if os.path.realpath(os.path.dirname(module.__file__)) != os.path.realpath(REPOSITORY):
            raise RenderScriptError(f"another package named '{PACKAGE_NAME}' is already "
                                    f"imported from {module.__file__}")
        return module
    spec = importlib.util.spec_from_file_location(
        PACKAGE_NAME, os.path.join(REPOSITORY, "__init__.py"),
        submodule_search_locations=[REPOSITORY])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE_NAME] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[PACKAGE_NAME]
        raise
    return module


def register_glint(glint) -> None:
    """Register this checkout's add-on unless it already is; disable another Glint first."""
    import addon_utils
    import bpy

    from glint.addon.engine.final import GlintRenderEngine

    if GlintRenderEngine.is_registered:
        return
    for name in list(bpy.context.preferences.addons.keys()):
        if name.rsplit(".", 1)[-1] == PACKAGE_NAME:
            addon_utils.disable(name, default_set=False)
    glint.register()


# --------------------------------------------------------------------------------------------
# Arguments

class _OneLineParser(argparse.ArgumentParser):
    def error(self, message):
        raise SystemExit(_fail(message, EXIT_USAGE))


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _percentage(text: str) -> int:
    value = _positive_int(text)
    if value > 10000:  # Blender's own limit for resolution_percentage
        raise argparse.ArgumentTypeError(f"must be at most 10000, got {value}")
    return value


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = _OneLineParser(prog=PROGRAM, description=__doc__.split("\n\n")[0])
    parser.add_argument("blend", nargs="?", help="scene .blend (default: the article's scene, "
                                                 "or the .blend Blender opened)")
    parser.add_argument("--output", required=True, help="PNG file to write")
    parser.add_argument("--width", type=_positive_int, help="resolution X in pixels")
    parser.add_argument("--height", type=_positive_int, help="resolution Y in pixels")
    parser.add_argument("--percentage", type=_percentage, help="resolution percentage")
    parser.add_argument("--samples", type=_positive_int,
                        help="rays per anti-aliased pixel; turns Fixed anti-aliasing on if the "
                             "scene has it off")
    parser.add_argument("--max-depth", type=_positive_int, help="bounces per path")
    parser.add_argument("--frame", type=_integer, help="frame to render")
    parser.add_argument("--semantics", choices=["default", "article"])
    parser.add_argument("--precision", choices=["auto", "float64", "float32"])
    args = parser.parse_args(argv)

    if not args.output.lower().endswith(".png"):
        parser.error(f"--output must name a .png file, got {args.output!r}")
    output = os.path.abspath(args.output)
    folder = os.path.dirname(output)
    if os.path.isdir(output):
        parser.error(f"--output {args.output!r} is a directory")
    if not os.path.isdir(folder):
        parser.error(f"--output folder does not exist: {folder}")
    if not os.access(folder, os.W_OK):
        parser.error(f"--output folder is not writable: {folder}")
    args.output = output
    if args.blend is not None:
        args.blend = os.path.abspath(args.blend)
        if not os.path.isfile(args.blend):
            parser.error(f"no such .blend file: {args.blend}")
    return args


def script_arguments(argv: list[str]) -> list[str]:
    """The script's own arguments: after '--' if present (required under Blender, whose own
    arguments come first), else everything after the script name (``python render.py ...``).
    """
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return [] if running_in_blender() else argv[1:]


def running_in_blender() -> bool:
    """True inside the Blender program (``blender --python``), False with the pip module,
    whose ``bpy.app.binary_path`` is empty."""
    bpy = sys.modules.get("bpy")
    return bpy is not None and bool(bpy.app.binary_path)


# --------------------------------------------------------------------------------------------
# The job

def open_scene(blend):
    """The scene to render: ``blend`` opened, the .blend Blender already opened, or None when
    the article's scene must be built (the file is reset to an empty one first)."""
    import bpy

    if blend is not None:
        try:
            bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(f"cannot open {blend}: {reason}") from None
        return bpy.context.scene
    if bpy.data.filepath:
        return bpy.context.scene
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return None


def apply_options(scene, args) -> None:
    render, settings = scene.render, scene.glint
    if args.width is not None:
        render.resolution_x = args.width
    if args.height is not None:
        render.resolution_y = args.height
    if args.percentage is not None:
        render.resolution_percentage = args.percentage
    if args.samples is not None:
        settings.samples = args.samples
        if settings.anti_aliasing == 'OFF':
            settings.anti_aliasing = 'FIXED'
    if args.max_depth is not None:
        settings.max_depth = args.max_depth
    if args.semantics is not None:
        settings.semantics = args.semantics.upper()
    if args.precision is not None:
        settings.precision = args.precision.upper()
    if args.frame is not None:
        scene.frame_set(args.frame)
    render.engine = "GLINT"
    # One view layer, and no compositing or sequencer work whose result is not written.
    render.use_single_layer = True
    render.use_compositing = False
    render.use_sequencer = False


def make_current(scene):
    """Make ``scene`` the context's scene and return its evaluated (viewport) depsgraph."""
    import bpy

    window = bpy.context.window
    if window is not None and window.scene != scene:
        window.scene = scene
    if bpy.context.scene == scene:
        return bpy.context.evaluated_depsgraph_get()
    depsgraph = scene.view_layers[0].depsgraph
    depsgraph.update()
    return depsgraph


def render_scene(scene):
    """(RenderJob, image) of the current frame, rendered by Glint's engine."""
    import bpy

    from glint.addon.engine.final import captured_images
    from glint.addon.export import ExportError, export_scene

    try:
        # Fails early, with Glint's own message, on what the engine would refuse.
        export_scene(make_current(scene))
    except ExportError as error:
        raise RenderScriptError(str(error)) from None
    with captured_images() as frames:
        try:
            bpy.ops.render.render(scene=scene.name)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(f"render failed: {reason}") from None
    if not frames:
        raise RenderScriptError("render failed: Glint's engine produced no image")
    return frames[-1]


def write_output(path: str, image) -> None:
    """Write the frame just rendered as Blender writes its render result (F12, then Save):
    the Render Result through the scene's colour management (view transform, look, exposure,
    gamma, dither), so ``render.py``, F12 and the Render button's image give the same pixels.
    Always an 8-bit RGBA PNG (the scene's output format is left untouched), written to a
    temporary file in the output folder and renamed.  image: the job's image of that frame
    (row 0 = top), whose size the render result must have."""
    import tempfile

    import bpy

    from glint.core.png import write_atomically

    result = bpy.data.images.get("Render Result")
    if result is None or tuple(result.size) not in ((0, 0), (image.shape[1], image.shape[0])):
        raise RenderScriptError("render failed: Blender holds no render result of this frame")
    scene = bpy.context.scene
    settings = scene.render.image_settings
    names = [name for name in ("media_type", "file_format", "color_mode", "color_depth")
             if hasattr(settings, name)]
    previous = {name: getattr(settings, name) for name in names}
    folder = os.path.dirname(os.path.abspath(path))
    try:
        handle, temporary = tempfile.mkstemp(prefix=".glint-", suffix=".png", dir=folder)
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None
    os.close(handle)
    try:
        if "media_type" in previous:
            settings.media_type = 'IMAGE'
        settings.file_format, settings.color_mode, settings.color_depth = 'PNG', 'RGBA', '8'
        try:
            result.save_render(temporary, scene=scene)
        except RuntimeError as error:
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(f"cannot write {path}: {reason}") from None
        with open(temporary, "rb") as stream:
            data = stream.read()
        write_atomically(path, data)
    except OSError as error:
        raise RenderScriptError(f"cannot write {path}: {error.strerror or error}") from None
    finally:
        for name, value in previous.items():
            setattr(settings, name, value)
        if os.path.exists(temporary):
            os.unlink(temporary)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv if argv is None else argv
    args = parse_args(script_arguments(argv))
    try:
        import bpy  # noqa: F401  (the pip module, or Blender's own)
    except ImportError:
        return _fail("needs Blender's Python or the bpy module (pip install bpy)")
    try:
        glint = import_glint()
        scene = open_scene(args.blend)
        register_glint(glint)
        if scene is None:
            from glint.addon.utils.article_scene import build_article_scene

            scene = build_article_scene()
        apply_options(scene, args)
        start = time.perf_counter()
        job, image = render_scene(scene)
        write_output(args.output, image)
    except RenderScriptError as error:
        return _fail(str(error))
    elapsed = time.perf_counter() - start
    width, height = job.size
    print(f"{PROGRAM}: wrote {args.output} ({width}x{height}, {job.precision}, "
          f"{job.settings.semantics} semantics) in {elapsed:.2f} s")
    return 0


def _fail(message: str, code: int = EXIT_FAILURE) -> int:
    print(f"{PROGRAM}: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
