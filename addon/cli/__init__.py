"""The command line: render.py's modules (render.py itself only loads this checkout as the
package ``glint`` and calls ``run.main``).

``arguments`` (the options, checked before Blender is loaded), ``run`` (the job: open the
.blend, apply the options, render each frame through the engine as F12 does), ``frames``
(frame numbers in output paths, Blender's frame claiming), ``output`` (the PNG and EXR files,
written atomically), ``report`` (one-line errors, the progress line) and ``interruption``
(Ctrl-C and SIGTERM).  Only ``run`` and ``output`` use Blender, and import it when called.
"""
