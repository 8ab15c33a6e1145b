"""render.py's job: open the .blend (or build the article's scene), apply the options, and
render the frame or frames through Glint's render engine exactly as F12 renders them, each
written by ``output`` (to --output, or where ``blender -b FILE -f N`` would write it).
Blender is imported when it is needed, after the arguments are checked."""

from __future__ import annotations

import contextlib
import io
import sys
import time

from .arguments import NO_OUTPUT_PATH, parse_args, running_in_blender, script_arguments
from .frames import FrameClaim, animation_frames, frame_path
from .interruption import Interrupted, Interruption
from .report import EXIT_USAGE, PROGRAM, ProgressLine, RenderScriptError, fail

#: The extension's id (``blender_manifest.toml``): an installed Glint is enabled under a name
#: ending in it (``bl_ext.<repository>.glint``).
EXTENSION_ID = "glint"


def register_addon() -> None:
    """Register this package's add-on unless it already is; an installed Glint extension, if
    enabled, is disabled for the session first so the two do not clash."""
    import addon_utils
    import bpy

    from ... import register, unregister
    from ..compat import unregister_at_exit
    from ..engine.base import GlintRenderEngine

    if GlintRenderEngine.is_registered:
        return
    for name in list(bpy.context.preferences.addons.keys()):
        if name.rsplit(".", 1)[-1] == EXTENSION_ID:
            addon_utils.disable(name, default_set=False)
    register()
    unregister_at_exit(lambda: GlintRenderEngine.is_registered and unregister())


@contextlib.contextmanager
def errors_said_once():
    """Around a Blender operator: Blender prints its reports on stdout ("Error: ...",
    "Warning: ...") and raises its errors as a RuntimeError too, which render.py reports as
    its one line; so the errors are kept from stdout, the other reports printed as Blender
    prints them."""
    reports = io.StringIO()
    try:
        with contextlib.redirect_stdout(reports):
            yield
    finally:
        for line in reports.getvalue().splitlines(keepends=True):
            if not line.startswith("Error: "):
                sys.stdout.write(line)


def open_scene(blend):
    """The scene to render: ``blend`` opened, the .blend Blender already opened, or None when
    the article's scene must be built (the file is reset to an empty one first)."""
    import bpy

    from .output import blender_reason

    if blend is not None:
        try:
            with errors_said_once():
                bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
        except RuntimeError as error:
            raise RenderScriptError(f"cannot open {blend}: {blender_reason(error)}") from None
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
    if args.parallelism is not None:
        settings.parallelism = args.parallelism.upper()
    if args.cluster is not None:
        settings.cluster_address = args.cluster
    if args.frame is not None:
        scene.frame_set(args.frame)   # within Blender's range (``arguments``)
    render.engine = "GLINT"


def render_scene(scene, interruption: Interruption, progress=None,
                 fill_render_result=False) -> list:
    """Render the current frame with Glint's engine exactly as F12 renders it (the view
    layers that are on, then Blender's compositor and sequencer when the file uses them);
    [(RenderJob, JobResult)], one per view layer the engine rendered.  The engine hands the
    core's image over through a FrameRequest and leaves Blender's render result empty unless
    ``fill_render_result`` (when the file is Blender's render result).  progress(job,
    fraction): as tiles land."""
    import bpy

    from ..engine.final import FrameRequest, requesting_frames
    from .output import blender_reason

    if scene.camera is None:  # Blender refuses before the engine runs, less clearly
        raise RenderScriptError(f"scene '{scene.name}' has no camera: add one and make it the "
                                f"scene camera")
    request = FrameRequest(should_cancel=interruption.requested,
                           fill_render_result=fill_render_result, progress=progress)
    with requesting_frames(request):
        try:
            with errors_said_once():
                bpy.ops.render.render(scene=scene.name)
        except RuntimeError as error:
            interruption.check()
            raise RenderScriptError(request.failure or blender_reason(error)) from None
    interruption.check()
    if request.failure is not None:
        raise RenderScriptError(request.failure)
    return request.frames


def render_frame(scene, plan, interruption: Interruption, path: str, quiet: bool,
                 label: str = "") -> str:
    """Render the scene's current frame and write it to ``path`` as ``plan`` says
    (``output.OutputPlan``), with a progress line; what was rendered, for the user
    ("64x48, float32, default semantics")."""
    from .output import refuse_write_protected, write_png, write_render_result

    refuse_write_protected(path)
    progress = ProgressLine(sys.stderr, quiet=quiet, label=label)
    try:
        frames = render_scene(scene, interruption, progress=progress,
                              fill_render_result=plan.from_render_result)
    finally:
        progress.end()
    if plan.from_render_result:
        write_render_result(scene, path, plan.fmt)
    elif not frames:
        raise RenderScriptError("render failed: Glint's engine produced no image")
    else:
        job, result = frames[0]   # the one view layer the file shows (plan.view_layers)
        write_png(path, result.image, scene, job)
    render = scene.render
    if not frames:   # the sequencer's picture, which Glint did not render
        scale = render.resolution_percentage / 100
        return f"{int(render.resolution_x * scale)}x{int(render.resolution_y * scale)}"
    job, result = frames[0]
    width, height = job.size
    return f"{width}x{height}, {result.precision}, {job.settings.semantics} semantics"


def failure(error: Exception, interruption: Interruption) -> RenderScriptError:
    """Any error that ended the run, as the one line (and exit status) to report."""
    if isinstance(error, RenderScriptError):
        return error
    if interruption.requested():  # e.g. Blender's writer stopped by the signal
        return Interrupted(interruption.signal_number)
    from ..engine.job import failure_message

    return RenderScriptError(failure_message(error))


def render_animation(scene, args, plan, frames: range, path_of,
                     interruption: Interruption) -> int:
    """Every frame of ``frames`` not skipped by FrameClaim, each written to ``path_of(frame)``;
    one line per frame on stdout and a summary of how many were written.  A failure or a
    signal ends the run with one line that says it too."""
    from .output import make_folder

    overwrite = scene.render.use_overwrite if args.overwrite is None else args.overwrite
    placeholder = scene.render.use_placeholder if args.placeholder is None else args.placeholder
    start = time.perf_counter()
    written = skipped = 0

    def tally() -> str:
        return f"wrote {written} of {len(frames)} frames, skipped {skipped}"

    for index, frame in enumerate(frames, 1):
        try:
            interruption.check()
            path = path_of(frame)
            make_folder(path)   # before a placeholder goes into it
            claim = FrameClaim(path, overwrite, placeholder)
            if not claim.claimed:
                skipped += 1
                print(f"{PROGRAM}: skipped frame {frame}: {path} exists (overwrite is off)")
                continue
            began = time.perf_counter()
            try:
                scene.frame_set(frame)
                what = render_frame(scene, plan, interruption, path, args.quiet,
                                    label=f"frame {frame} ({index}/{len(frames)})")
            except BaseException:
                claim.release()
                raise
        except Exception as error:
            error = failure(error, interruption)
            if isinstance(error, Interrupted):
                raise Interrupted(error.signal_number,
                                  f"frame {frame} not written; {tally()}") from None
            raise RenderScriptError(f"frame {frame}: {error}; {tally()}",
                                    error.exit_code) from None
        written += 1
        print(f"{PROGRAM}: wrote {path} (frame {frame}, {what}) in "
              f"{time.perf_counter() - began:.2f} s", flush=True)
    print(f"{PROGRAM}: {tally()}, in {time.perf_counter() - start:.2f} s")
    return 0


def main(argv: list[str], own_process: bool = False) -> int:
    """render.py's program (argv: ``sys.argv``, script name first).  own_process: run as the
    program; with pip bpy the process is then Glint's own and gets its malloc settings
    (``core.allocator``), never inside Blender's (``running_in_blender``), where they would
    change the allocator of Blender and every add-on."""
    args = parse_args(script_arguments(argv))
    interruption = Interruption()
    interruption.install()
    try:
        import bpy  # noqa: F401  (the pip module, or Blender's own)
    except ImportError:
        return fail("needs Blender's Python or the bpy module (pip install bpy)")
    try:
        from .output import OutputPlan, scene_output_path

        if own_process and not running_in_blender():
            from ...core import allocator

            allocator.configure()
        if own_process and args.frames is None:
            # One frame, then exit: 'auto' weighs the workers' start-up (core.workers).
            from ...core import workers

            workers.expect_one_render()
        if args.blend is not None:
            # Before the file loads, so that its render engine GLINT is known (Blender reports
            # "Engine 'GLINT' not available" otherwise); the article's scene is built after a
            # factory reset, which the registration must follow.
            register_addon()
        scene = open_scene(args.blend)
        register_addon()
        interruption.check()
        if scene is None:
            if args.output is None:   # Blender started without a file
                raise RenderScriptError(NO_OUTPUT_PATH, EXIT_USAGE)
            from ..utils.article_scene import build_article_scene

            scene = build_article_scene()
        apply_options(scene, args)
        plan = OutputPlan.choose(scene, args)
        plan.select_view_layers(scene)
        interruption.check()
        if args.output is None:
            # As 'blender -b FILE -f N' (or -a): the scene's path, format and numbering, and
            # its Overwrite and Placeholders.
            frames = animation_frames(scene, args) if args.frames is not None else \
                range(scene.frame_current, scene.frame_current + 1)
            return render_animation(scene, args, plan, frames,
                                    lambda frame: scene_output_path(scene, frame), interruption)
        if args.frames is not None:
            return render_animation(scene, args, plan, animation_frames(scene, args),
                                    lambda frame: frame_path(args.output, frame, animation=True),
                                    interruption)
        start = time.perf_counter()
        path = frame_path(args.output, scene.frame_current)
        what = render_frame(scene, plan, interruption, path, args.quiet)
    except Exception as error:
        error = failure(error, interruption)
        return fail(str(error), error.exit_code)
    print(f"{PROGRAM}: wrote {path} ({what}) in {time.perf_counter() - start:.2f} s")
    return 0
