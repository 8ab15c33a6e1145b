"""Glint's choice lists, defined once: the values the core accepts and what each means.

``core.settings`` validates against these, and every front end builds its choices from them:
``python -m core`` and ``render.py`` (argparse ``choices``) and the add-on's EnumProperty items
(identifier ``value.upper()``, so .blend files keep their stored identifiers).  This module
imports nothing, so render.py can read it before loading the package (``load_choices``).

Each list is a tuple of (value, label, description).
"""

SEMANTICS_CHOICES = (
    ("default", "Default", "The article's model with its quirks fixed: clamped shading, ambient "
                           "light in shadow, soft shadows, world background"),
    ("article", "Article", "Every quirk of the article's tracer, kept exactly"),
)
PRECISION_CHOICES = (
    ("auto", "Auto", "Float32 when the scene's size-to-detail ratio allows it, else float64"),
    ("float64", "Float64", "Double precision"),
    ("float32", "Float32", "Single precision: faster, may show shadow acne on huge spheres"),
)
ANTI_ALIASING_CHOICES = (
    ("off", "Off", "One ray through each pixel centre, as the article does"),
    ("fixed", "Fixed", "Samples rays in every pixel"),
    ("adaptive", "Adaptive", "One ray per pixel, then Samples rays in pixels on an edge"),
)

#: How tiles run in parallel (``core.render``, ``core.workers``).
PARALLELISM_CHOICES = (
    ("auto", "Auto", "Worker processes for renders large enough that their start-up pays "
                     "(more than one tile and thread, at least 0.3 Mpixel; in a process that "
                     "renders once, workers already running or 8 M camera samples), threads "
                     "otherwise"),
    ("threads", "Threads", "Tiles on a thread pool in this process"),
    ("processes", "Processes", "Tiles in worker processes (both cores busy despite the GIL); "
                               "falls back to threads where processes cannot start"),
)

#: What the image's alpha and background are (``core.trace``): Blender's Film > Transparent
#: off ('opaque') and on ('transparent'), and the core's own image ('coverage').
FILM_CHOICES = (
    ("coverage", "Coverage", "The background where camera rays escape; alpha = the share of "
                             "the pixel neither escaped nor held out"),
    ("opaque", "Opaque", "Blender's Film > Transparent off: the background where camera rays "
                         "escape; alpha 1 except where holdouts cut it"),
    ("transparent", "Transparent", "Blender's Film > Transparent on: escaped camera rays add "
                                   "nothing; alpha as for coverage"),
)


#: How light is followed (default semantics): a path tracer in Cycles' units, or the
#: Whitted tracer the article's semantics always uses.
INTEGRATOR_CHOICES = (
    ("path", "Path Tracing", "Light that bounces, as Cycles traces it: every light and the "
                             "world sampled at every bounce, Light Paths limits"),
    ("whitted", "Direct", "Direct light with mirrors and glass traced exactly and the world's "
                          "occlusion; no bounced light"),
)

#: Cycles' pixel filters (Film > Pixel Filter).
PIXEL_FILTER_CHOICES = (
    ("BLACKMAN_HARRIS", "Blackman-Harris", "Cycles' default: sharp, little ringing"),
    ("GAUSSIAN", "Gaussian", "Softer"),
    ("BOX", "Box", "Each sample counts only inside its pixel"),
)


def help_text(choices) -> str:
    """A command-line option's help: each value with its description."""
    return "; ".join(f"{value}: {description}" for value, _, description in choices)


def values(choices) -> tuple:
    """The values of a choice list, in order."""
    return tuple(value for value, _, _ in choices)


SEMANTICS = values(SEMANTICS_CHOICES)
PRECISIONS = values(PRECISION_CHOICES)
ANTI_ALIASING = values(ANTI_ALIASING_CHOICES)
PARALLELISM = values(PARALLELISM_CHOICES)
FILMS = values(FILM_CHOICES)
INTEGRATORS = values(INTEGRATOR_CHOICES)
PIXEL_FILTERS = values(PIXEL_FILTER_CHOICES)
