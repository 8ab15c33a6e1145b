"""Render a .blend (or the article's scene) with Glint to an 8-bit RGBA PNG or an OpenEXR.

    blender -b scene.blend --python render.py -- --output OUT.png [options]
    python render.py [scene.blend] --output OUT.png [options]        (pip bpy)
    python render.py scene.blend --output "out/frame_####.png" --frames 1-250 \\
        --no-overwrite --placeholder                  (an animation several processes share)
    python render.py scene.blend --frame 3            (as blender -b scene.blend -f 3)

Both do the same job.  Without a .blend, the article's scene is built in Blender
(``addon.utils.article_scene``).  Options override the scene's settings; everything else
(camera, objects, materials, world, Film > Transparent, ...) comes from the .blend.  The
frame is rendered by Glint's render engine exactly as ``blender -b scene.blend -f N`` renders
and saves it (compositor and sequencer included), and the PNG is what Blender's colour
management (view transform, look, exposure) makes of it: the pixels F12 saves and the Render
button's Image shows.  Without --output, the file goes to the .blend's own output path, in
its format.  With Film > Transparent, alpha is the coverage (less holdouts and what
Transparent BSDFs let through) and the background is transparent.

This file only loads the add-on: the program is ``addon/cli/`` (``run.main``; the options in
``arguments``, animations and frame claiming in ``frames``, the files in ``output``, Ctrl-C
and SIGTERM in ``interruption``).  This file sits in the repository root, which is the
extension package itself (``__init__.py``, ``addon/``, ``core/``).  ``import_glint`` loads
that directory as the package ``glint`` (``importlib.util.spec_from_file_location`` with
``submodule_search_locations``), whatever the checkout's directory is called, so the add-on's
relative imports work; it is then registered for this session (``register_glint``: an
installed Glint extension, if enabled, is disabled for the session so the two do not clash).
Tests and benchmarks use the same two functions.

Errors (missing or unreadable .blend, no camera, unwritable or write-protected output, bad
option, invalid values, a render that cannot fit in memory) print one line and exit non-zero;
a failure never leaves a partial file and never touches the previous one.  Ctrl-C (SIGINT) or
SIGTERM cancels the render within about a tile's time, writes nothing and exits 128 + the
signal's number (130, 143), with one line saying so.
"""

from __future__ import annotations

import importlib.util
import os
import sys

REPOSITORY = os.path.dirname(os.path.abspath(__file__))
PACKAGE_NAME = "glint"


class PackageClash(Exception):
    """Another package named ``glint`` is imported already."""


def import_glint():
    """The repository as the package ``glint`` (see the module docstring)."""
    module = sys.modules.get(PACKAGE_NAME)
    if module is not None:
        if os.path.realpath(os.path.dirname(module.__file__)) != os.path.realpath(REPOSITORY):
            raise PackageClash(f"another package named '{PACKAGE_NAME}' is already imported "
                               f"from {module.__file__}")
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
    """Register this checkout's add-on (``glint``, what ``import_glint`` returned) unless it
    already is; disable another Glint first (``addon.cli.run.register_addon``)."""
    from glint.addon.cli.run import register_addon

    register_addon()


def main(argv: list[str] | None = None, own_process: bool = False) -> int:
    """The program (``addon.cli.run.main``); argv: ``sys.argv`` by default."""
    try:
        import_glint()
    except PackageClash as error:
        print(f"render.py: error: {error}", file=sys.stderr)
        return 1
    from glint.addon.cli.run import main as run

    return run(sys.argv if argv is None else argv, own_process=own_process)


if __name__ == "__main__":
    sys.exit(main(own_process=True))
