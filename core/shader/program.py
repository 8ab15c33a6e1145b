"""A shader program: a node tree compiled to a flat list of node evaluations over registers
(Cycles' SVM: a graph compiled once into a list of operations over a stack).

Each instruction names a registered node (``core.shader.registry.NODES``), where each of
its inputs comes from (a register an earlier instruction wrote, a constant, or a coordinate
of the shading points where the socket is unlinked and Cycles reads one), its options, and
the registers its outputs go to.  ``run`` evaluates the list once per batch of shading
points, every node over the whole batch; nothing runs per point in Python.  Programs are
plain data (node names, numbers, strings, arrays), so they pickle to worker processes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .points import ShadingPoints
from .registry import NODES

#: Deeper node graphs than this are refused at compile time: a bound on the program's
#: length, for trees that nest groups without end.
MAX_INSTRUCTIONS = 4096


@dataclass(frozen=True)
class Register:
    """An input read from register ``index``."""

    index: int


@dataclass(frozen=True)
class Coordinate:
    """An input read from the shading points' coordinate ``name`` (``ShadingPoints``)."""

    name: str


@dataclass(frozen=True)
class Instruction:
    """One node evaluation: node (a ``NODES`` key), arguments (per input: a Register, a
    Coordinate, or a constant: a float, a tuple of 3 floats, or a closure value), options
    ((name, value) pairs), outputs (per output, the register it goes to, -1: unused)."""

    node: str
    arguments: tuple
    options: tuple
    outputs: tuple

    def argument(self, name: str):
        """The argument of input ``name`` (its identifier in the node's ``NODES`` entry)."""
        names = [identifier for identifier, _ in NODES[self.node].inputs]
        return self.arguments[names.index(name)]


@dataclass(frozen=True)
class ShaderProgram:
    """instructions in order; result: the Register (or constant) holding the program's
    value (a surface's closures, a world's radiance); registers: how many there are;
    name: what it was compiled from (messages); coordinates: the names of the shading
    points' coordinates it reads (``ShadingPoints.coordinate``), so the exporter and the
    integrator provide only those."""

    instructions: tuple
    result: object
    registers: int
    name: str = ""
    coordinates: frozenset = frozenset()

    def __len__(self) -> int:
        return len(self.instructions)


def constant_array(value, dtype):
    """A constant input as the evaluator passes it: a float as a 0-d array, a colour or
    vector as (3, 1); anything else (a closure) as it is."""
    if isinstance(value, (int, float, np.floating, np.integer)):
        return np.asarray(value, dtype)
    if isinstance(value, tuple) and all(isinstance(v, (int, float, np.floating))
                                        for v in value):
        return np.asarray(value[:3], dtype).reshape(3, 1)
    return value


def _value(argument, registers, points, dtype):
    if isinstance(argument, Register):
        return registers[argument.index]
    if isinstance(argument, Coordinate):
        return points.coordinate(argument.name)
    return constant_array(argument, dtype)


def evaluate(instruction: Instruction, registers, points: ShadingPoints, dtype):
    """Run one instruction, writing its outputs into ``registers``."""
    spec = NODES[instruction.node]
    arguments = [_value(a, registers, points, dtype) for a in instruction.arguments]
    outputs = spec.function(points, *arguments, **dict(instruction.options))
    if not isinstance(outputs, tuple):
        outputs = (outputs,)
    for index, value in zip(instruction.outputs, outputs):
        if index >= 0:
            registers[index] = value


def run(program: ShaderProgram, points: ShadingPoints):
    """The program's value at ``points``."""
    dtype = points.dtype
    registers = [None] * program.registers
    for instruction in program.instructions:
        evaluate(instruction, registers, points, dtype)
    return _value(program.result, registers, points, dtype)
