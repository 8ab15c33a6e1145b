"""The World -> what escaping rays see: a constant radiance, or a program of the directions.

The active World Output's Surface is compiled like a material's (``shader``: reroutes,
groups, Mix and Add Shader, textures): a Background (or Emission) of constant Color x
Strength folds to that radiance W, what camera and reflection rays see where they escape;
one whose colour or strength comes from nodes (an Environment Texture, a Sky Texture, a
gradient) becomes a program the path integrator runs on the directions rays escape in, with
its value straight up as the constant the Whitted integrator uses.  A world without a node
tree uses its Viewport Display colour; no world, or an unconnected output, is black, as in
Blender.  Values that are NaN, infinite or past the core's colour limit count as
``values.counted`` counts them, with a note.
"""

from __future__ import annotations

import numpy as np

from ...core.shader.program import ShaderProgram, constant_array, run
from ...core.shader.world import world_points
from ...core.validation import MAX_COLOUR, value_text
from ..compat import node_tree_in_use
from .values import as_stored, counted
from .shader import ShaderCompiler, surface_socket


def export_world(world, context=None):
    """(scene-linear RGB at rest, the world's program or None, note or None)."""
    if world is None:
        return (0.0, 0.0, 0.0), None, None
    tree = node_tree_in_use(world)
    if tree is None:
        colour, fixed = tuple(world.color), counted(world.color)
        if fixed is None:
            return colour, None, None
        return tuple(float(c) for c in fixed), None, (
            f"world '{world.name}': its colour {value_text(as_stored(colour))} counts as "
            f"{value_text(as_stored(fixed))}")
    surface = surface_socket(tree)
    if surface is None or not surface.is_linked:
        return (0.0, 0.0, 0.0), None, None  # Blender renders an unconnected world black too
    compiler = ShaderCompiler(f"world '{world.name}'", context)
    value = compiler.compile(surface)
    if isinstance(value, ShaderProgram):
        up = world_points(np.array([[0.0], [0.0], [1.0]]))
        return _colour(run(value, up).emission), value, "; ".join(compiler.notes) or None
    emission = constant_array(value, np.float64).emission
    if np.max(emission) > MAX_COLOUR:
        compiler.note(f"world '{world.name}': its radiance "
                      f"{value_text(as_stored(np.ravel(emission)))} is clamped to "
                      f"{MAX_COLOUR:g} (Cycles' pixels are as blown out)")
    return _colour(emission), None, "; ".join(compiler.notes) or None


def world_colour(world, context=None) -> tuple[tuple[float, float, float], str | None]:
    """(scene-linear RGB the world shows at rest, note or None)."""
    colour, _, note = export_world(world, context)
    return colour, note


def _colour(emission) -> tuple[float, float, float]:
    values = np.asarray(emission, np.float64).reshape(3, -1)[:, 0]
    return tuple(float(min(max(c, 0.0), MAX_COLOUR)) for c in values)
