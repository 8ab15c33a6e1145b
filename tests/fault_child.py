"""Run render.py or ``python -m core`` with a fault injected at one stage (for
tests/test_faults.py, in a child process):

    python tests/fault_child.py STAGE render.py ARGS...
    python tests/fault_child.py STAGE core ARGS...

STAGE: export, tile, hand-over or write (see test_faults.py for what each one breaks).
"""

from __future__ import annotations

import contextlib
import os
import sys

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPOSITORY)


def fail(message, error=RuntimeError):
    def broken(*args, **kwargs):
        raise error(f"injected fault: {message}")
    return broken


def fail_on_second_call(function, message):
    """The first call runs (so a partial file exists), the second raises."""
    calls = []

    def broken(*args, **kwargs):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(28, f"injected fault: {message}")  # ENOSPC, as a full disk
        return function(*args, **kwargs)
    return broken


def disk_fills_up(atomic_path):
    """``core.png.atomic_path`` whose writer (Blender, for render.py's files) runs, after which
    the disk is full: the temporary file is cut to half its length and the rename never
    happens."""
    @contextlib.contextmanager
    def broken(path, *args, **kwargs):
        with atomic_path(path, *args, **kwargs) as temporary:
            yield temporary
            os.truncate(temporary, os.path.getsize(temporary) // 2)
            raise OSError(28, "injected fault: disk full")
    return broken


def inject(stage: str, core, job=None) -> None:
    # The modules by name (``core.render`` is also the function the package exports); a
    # frame's tiles run here on threads (``core.threads``).
    threads_module = sys.modules[core.__name__ + ".threads"]
    png_module = sys.modules[core.__name__ + ".png"]
    if stage == "export":
        job.export_scene = fail("export")
    elif stage == "tile":
        threads_module.render_tile = fail("a tile ran out of memory", MemoryError)
    elif stage == "hand-over":
        job.JobResult = fail("hand-over")
    elif stage == "write" and job is None:
        # python -m core streams its PNG a block of rows at a time: the disk fills up on the
        # second block.
        png_module.ROW_BLOCK = 4  # several blocks even for a small image
        png_module._filtered = fail_on_second_call(png_module._filtered, "disk full")
    elif stage == "write":
        png_module.atomic_path = disk_fills_up(png_module.atomic_path)
    else:
        raise SystemExit(f"unknown stage {stage!r}")


def main() -> int:
    stage, entry, *arguments = sys.argv[1:]
    if entry == "render.py":
        import render as script

        glint = script.import_glint()
        import glint.addon.engine.job as job  # noqa: F401 (bpy is importable: pip bpy)
        import glint.core.png  # noqa: F401
        import glint.core.render  # noqa: F401

        inject(stage, glint.core, job)
        return script.main([script.__file__, *arguments])
    import core
    import core.__main__ as command
    import core.png  # noqa: F401
    import core.render  # noqa: F401

    if stage == "export":
        command.SCENES["article"] = fail("building the scene")
    else:
        inject(stage, core)
    return command.main(arguments)


if __name__ == "__main__":
    sys.exit(main())
