"""The shader nodes Glint evaluates, defined once: each Blender node type that a material
or world program may use is registered here with the function that evaluates it.

A node function evaluates the node for n shading points at once, over arrays:

* floats arrive as arrays that broadcast to (n,) (a constant is a 0-d array),
* vectors and colours as arrays that broadcast to (3, n) (a constant is (3, 1)),
* options (the node's enum, boolean and number properties, and what the add-on reads of a
  ColorRamp, a curve, an image...) as plain Python values, by keyword,
* and the first argument is the ``ShadingPoints`` the program runs over
  (``core.shader.points``), for nodes that read the geometry (coordinates, normals).

It returns one array per output, in the order of ``outputs``, each broadcastable as above.
Colours are RGB (Blender's fourth, alpha, component of a colour socket is dropped).

The add-on's compiler (``addon.export.shader``) reads a node's linked and unlinked inputs
by socket identifier, its options by property name (``options``; a node whose options need
more than ``getattr`` has a reader in the add-on), inserts Blender's implicit conversions
between socket types, and emits one instruction per node.  A node type absent from
``NODES`` is not supported: its outputs take the unlinked value of the sockets they feed,
with one warning naming the node and the material.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

#: Socket types as the evaluator passes them.
FLOAT, VECTOR, COLOR, CLOSURE = "float", "vector", "color", "closure"
SOCKET_TYPES = (FLOAT, VECTOR, COLOR, CLOSURE)

#: What an unlinked Vector input of a texture means (Cycles' defaults): the name of a
#: ``ShadingPoints`` coordinate.
IMPLICIT_COORDINATES = ("generated", "uv", "normal", "position", "incoming", "object_incoming")


@dataclass(frozen=True)
class NodeSpec:
    """One supported node type.

    bl_idname: Blender's node type ("ShaderNodeTexNoise").
    function: evaluates it (module docstring).
    inputs: ((socket identifier, socket type), ...) in the order the function takes them.
    outputs: ((socket identifier, socket type), ...) in the order it returns them.
    options: property names passed by keyword.
    implicit: {input identifier: coordinate} for inputs whose unlinked value is a
        coordinate of the shading point rather than the socket's own value.
    note: how the node is approximated, where it is ("" for exact); the supported-nodes
        page lists it.
    reads_points: whether the node reads the shading points' geometry (coordinates,
        normals, the ray), so that its value varies over a surface even where every input
        is a constant: the compiler folds only nodes that do not.
    stand_in: the node is rendered as another (its note says which), so the export names it
        in a warning: its look differs from Cycles' as a whole, not in a detail.
    """

    bl_idname: str
    function: Callable
    inputs: tuple
    outputs: tuple
    options: tuple = ()
    implicit: dict = field(default_factory=dict)
    note: str = ""
    reads_points: bool = False
    stand_in: bool = False


NODES: dict[str, NodeSpec] = {}


def node(bl_idname: str, *, inputs=(), outputs=(), options=(), implicit=None, note: str = "",
         reads_points: bool = False, stand_in: bool = False):
    """Register the decorated function as the evaluation of ``bl_idname`` (``NodeSpec``).
    inputs and outputs: ((identifier, type), ...)."""
    for identifier, kind in tuple(inputs) + tuple(outputs):
        if kind not in SOCKET_TYPES:
            raise ValueError(f"{bl_idname}: socket {identifier!r} has unknown type {kind!r}")
    for identifier, coordinate in (implicit or {}).items():
        if coordinate not in IMPLICIT_COORDINATES:
            raise ValueError(f"{bl_idname}: implicit {identifier!r} -> unknown coordinate "
                             f"{coordinate!r}")

    def register(function):
        if bl_idname in NODES:
            raise ValueError(f"{bl_idname} is registered twice")
        NODES[bl_idname] = NodeSpec(bl_idname, function, tuple(inputs), tuple(outputs),
                                    tuple(options), dict(implicit or {}), note, reads_points,
                                    stand_in)
        return function
    return register
