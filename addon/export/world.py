"""The World -> the scene-linear radiance Glint's constant environment has.

The active World Output's Surface is evaluated like a material (``materials.NodeEvaluator``:
reroutes, groups, Mix and Add Shader), and its Background (or Emission) nodes' Color x
Strength is the world's radiance W: what camera and reflection rays see where they escape, and
the light a diffuse albedo a reflects as a x W (``core.bsdf``).  An Environment Texture counts
as its image's average colour, a Sky Texture or anything else not evaluated as the socket's
own colour, each with a note.  A world without a node tree uses its Viewport Display colour;
no world, or an unconnected output, is black, as in Blender.  Values that are NaN, infinite or
past the core's colour limit count as ``NodeEvaluator`` counts them, with a note.
"""

from __future__ import annotations

import bpy
import numpy as np

from ...core.validation import MAX_COLOUR, value_text
from .materials import NodeEvaluator, as_stored, counted


def world_colour(world) -> tuple[tuple[float, float, float], str | None]:
    """(scene-linear RGB the world shows, note or None)."""
    if world is None:
        return (0.0, 0.0, 0.0), None
    tree = world.node_tree
    uses_nodes = tree is not None and (bpy.app.version >= (5, 0, 0) or world.use_nodes)
    if not uses_nodes:
        colour, fixed = tuple(world.color), counted(world.color)
        if fixed is None:
            return colour, None
        return tuple(float(c) for c in fixed), (f"world '{world.name}': its colour "
                                                f"{value_text(as_stored(colour))} counts as "
                                                f"{value_text(as_stored(fixed))}")
    output = tree.get_output_node('CYCLES') or tree.get_output_node('ALL')
    surface = output.inputs.get("Surface") if output is not None else None
    if surface is None or not surface.is_linked:
        return (0.0, 0.0, 0.0), None  # Blender renders an unconnected world black too
    evaluator = NodeEvaluator(f"world '{world.name}'")
    lobes = evaluator.shader(surface)
    if np.max(lobes.emission) > MAX_COLOUR:
        evaluator.note(f"world '{world.name}': its radiance "
                       f"{value_text(as_stored(lobes.emission))} is "
                       f"clamped to {MAX_COLOUR:g} (Cycles' pixels are as blown out)")
    radiance = tuple(float(min(max(c, 0.0), MAX_COLOUR)) for c in lobes.emission)
    return radiance, ("; ".join(evaluator.notes) or None)
