"""render.py's job: open the .blend (or build the article's scene), apply the options, and
render the frame or frames through Glint's render engine exactly as F12 renders them, each
written by ``output``.  Blender is imported when it is needed, after the arguments are
checked."""

from __future__ import annotations

import sys
import time

from .arguments import parse_args, running_in_blender, script_arguments
from .frames import FrameClaim, animation_frames, frame_path
from .interruption import EXIT_SIGNAL_BASE, Interrupted, Interruption
from .report import PROGRAM, ProgressLine, RenderScriptError, fail

#: The extension's id (``blender_manifest.toml``): an installed Glint is enabled under a name
#: ending in it (``bl_ext.<repository>.glint``).
EXTENSION_ID = "glint"


def register_addon() -> None:
    """Register this package's add-on unless it already is; an installed Glint extension, if
    enabled, is disabled for the session first so the two do not clash."""
    import addon_utils
    import bpy

    from ... import register
    from ..engine.base import GlintRenderEngine

    if GlintRenderEngine.is_registered:
        return
    for name in list(bpy.context.preferences.addons.keys()):
        if name.rsplit(".", 1)[-1] == EXTENSION_ID:
            addon_utils.disable(name, default_set=False)
    register()


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
    if args.parallelism is not None:
        settings.parallelism = args.parallelism.upper()
    if args.frame is not None:
        frame = type(scene).bl_rna.properties["frame_current"]
        if not frame.hard_min <= args.frame <= frame.hard_max:
            raise RenderScriptError(f"--frame {args.frame} is outside Blender's frame range "
                                    f"{frame.hard_min} to {frame.hard_max}")
        scene.frame_set(args.frame)
    render.engine = "GLINT"
    # One view layer, and no compositing or sequencer work whose result is not written.
    render.use_single_layer = True
    render.use_compositing = False
    render.use_sequencer = False


def render_scene(scene, interruption: Interruption, progress=None, fill_render_result=False):
    """(RenderJob, JobResult) of the current frame, rendered by Glint's engine exactly as F12
    renders it; the engine hands the core's image over through a FrameRequest and leaves
    Blender's render result empty (``output.write_png`` writes the PNG itself) unless
    ``fill_render_result`` (EXR output, which Blender writes from its render result).
    progress(job, fraction): as tiles land."""
    import bpy

    from ..engine.final import FrameRequest, requesting_frames

    if scene.camera is None:  # Blender refuses before the engine runs, less clearly
        raise RenderScriptError(f"scene '{scene.name}' has no camera: add one and make it the "
                                f"scene camera")
    request = FrameRequest(should_cancel=interruption.requested,
                           fill_render_result=fill_render_result, progress=progress)
    with requesting_frames(request):
        try:
            bpy.ops.render.render(scene=scene.name)
        except RuntimeError as error:
            interruption.check()
            reason = str(error).strip().splitlines()[-1].removeprefix("Error: ")
            raise RenderScriptError(reason) from None
    interruption.check()
    if not request.frames:
        raise RenderScriptError("render failed: Glint's engine produced no image")
    return request.frames[-1]


def render_frame(scene, args, interruption: Interruption, path: str, label: str = ""):
    """Render the scene's current frame and write it to ``path`` in the output format, with a
    progress line; (RenderJob, JobResult)."""
    from .output import output_format, write_exr, write_png

    fmt = output_format(scene, args)
    if fmt == "multilayer-exr":
        scene.render.use_single_layer = False  # every view layer goes into the file
    progress = ProgressLine(sys.stderr, quiet=args.quiet, label=label)
    try:
        job, result = render_scene(scene, interruption, progress=progress,
                                   fill_render_result=fmt != "png")
    finally:
        progress.end()
    if fmt == "png":
        write_png(path, result.image, scene, job)
    else:
        write_exr(scene, path, multilayer=fmt == "multilayer-exr")
    return job, result


def render_animation(scene, args, interruption: Interruption) -> int:
    """--frames: every frame of the range not skipped by FrameClaim, each written to its
    frame_path; one line per frame on stdout and a summary."""
    frames = animation_frames(scene, args)
    overwrite = scene.render.use_overwrite if args.overwrite is None else args.overwrite
    placeholder = scene.render.use_placeholder if args.placeholder is None else args.placeholder
    start = time.perf_counter()
    rendered, skipped = [], []
    for index, frame in enumerate(frames, 1):
        interruption.check()
        path = frame_path(args.output, frame, animation=True)
        claim = FrameClaim(path, overwrite, placeholder)
        if not claim.claimed:
            skipped.append(frame)
            print(f"{PROGRAM}: skipped frame {frame}: {path} exists (overwrite is off)")
            continue
        began = time.perf_counter()
        try:
            scene.frame_set(frame)
            job, result = render_frame(scene, args, interruption, path,
                                       label=f"frame {frame} ({index}/{len(frames)})")
        except BaseException:
            claim.release()
            raise
        rendered.append(frame)
        width, height = job.size
        print(f"{PROGRAM}: wrote {path} (frame {frame}, {width}x{height}, {result.precision}) "
              f"in {time.perf_counter() - began:.2f} s", flush=True)
    print(f"{PROGRAM}: rendered {len(rendered)} of {len(frames)} frames, skipped "
          f"{len(skipped)}, in {time.perf_counter() - start:.2f} s")
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
            from ..utils.article_scene import build_article_scene

            scene = build_article_scene()
        apply_options(scene, args)
        interruption.check()
        start = time.perf_counter()
        if args.frames is not None:
            return render_animation(scene, args, interruption)
        job, result = render_frame(scene, args, interruption, frame_path(args.output,
                                                                         scene.frame_current))
    except Interrupted as interrupted:
        return fail(str(interrupted), interrupted.exit_code)
    except RenderScriptError as error:
        return fail(str(error))
    except Exception as error:
        if interruption.requested():  # e.g. the PNG writer stopped between row blocks
            return fail(str(Interrupted(interruption.signal_number)),
                        EXIT_SIGNAL_BASE + interruption.signal_number)
        from ..engine.job import failure_message

        return fail(failure_message(error))
    elapsed = time.perf_counter() - start
    width, height = job.size
    print(f"{PROGRAM}: wrote {frame_path(args.output, scene.frame_current)} "
          f"({width}x{height}, {result.precision}, "
          f"{job.settings.semantics} semantics) in {elapsed:.2f} s")
    return 0
