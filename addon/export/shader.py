"""Blender node trees -> the core's shader programs (``core.shader.program``), once per
material or world at export.

The compiler walks back from the output's socket: each node the value depends on becomes
one instruction (``core.shader.registry.NODES`` says how to read its inputs and options),
through reroutes, muted nodes and node groups, which vanish; Blender's implicit conversions
between socket types become conversion nodes; a node whose inputs are all constants and
which reads nothing of the shading points is evaluated here, once (constant folding), so a
tree of constants compiles to constants and a material costs the renderer no more than its
constant table row.  A node Glint does not support passes the value of the socket it feeds
(that socket's own, unlinked value), as Cycles would show with the node muted, and is
named in one note.
"""

from __future__ import annotations

import inspect

import numpy as np

from ...core.closures import Closures
from ...core.materials import SurfaceMaterial
from ...core.shader.bsdf_nodes import LobeSum
from ...core.shader.program import (MAX_INSTRUCTIONS, Coordinate, Instruction, Register,
                                    ShaderProgram, constant_array, evaluate, run)
from ...core.shader.points import ShadingPoints
from ...core.shader.input_nodes import (ATTRIBUTE_ALPHA_PREFIX, ATTRIBUTE_PREFIX, RENDER_COLOR,
                                       RENDER_COLOR_ALPHA)
from ...core.shader.registry import CLOSURE, COLOR, FLOAT, NODES, VECTOR
from ...core.validation import MAX_COLOUR, value_text
from ..compat import absent_input_value
from .errors import ShaderCompileError
from .node_links import followed, linked_source
from .values import as_stored, counted

#: How Blender's socket types map to the registry's.
_SOCKET_KINDS = {"VALUE": FLOAT, "INT": FLOAT, "BOOLEAN": FLOAT, "RGBA": COLOR,
                 "VECTOR": VECTOR, "SHADER": CLOSURE}
def _tangent_names(node) -> set:
    name = f"tangent:{node.uv_map}" if node.uv_map else "tangent"
    return {name, f"{name}_sign"} if node.space == 'TANGENT' else set()


#: The coordinates a node reads of the shading points beyond its inputs' (so that the
#: exporter provides them: UV maps and tangents are read from meshes only when asked for).
NODE_COORDINATES = {
    "ShaderNodeNormalMap": _tangent_names,
    "ShaderNodeUVMap": lambda node: {f"uv:{node.uv_map}" if node.uv_map else "uv"},
    "ShaderNodeAttribute": lambda node: ({ATTRIBUTE_PREFIX + node.attribute_name,
                                          ATTRIBUTE_ALPHA_PREFIX + node.attribute_name}
                                         if node.attribute_type == 'GEOMETRY' else set()),
    "ShaderNodeVertexColor": lambda node: ({ATTRIBUTE_PREFIX + node.layer_name,
                                            ATTRIBUTE_ALPHA_PREFIX + node.layer_name}
                                           if node.layer_name else
                                           {RENDER_COLOR, RENDER_COLOR_ALPHA}),
    "ShaderNodeTexCoord": lambda node: {"uv", "generated", "object"},
    "ShaderNodeTangent": lambda node: ({f"tangent:{node.uv_map}" if node.uv_map else "tangent"}
                                       if node.direction_type == 'UV_MAP' else {"generated"}),
}

#: Inputs compiled as programs of their own, which the node evaluates where it needs them
#: (a Bump's height, at each point and at two neighbours): (node, input, option name).
SUBPROGRAM_INPUTS = {"ShaderNodeBump": (("Height", "height"),)}
#: Rec.709 luminance, Cycles' colour-to-float conversion in Blender's default config.
LUMINANCE = (0.2126, 0.7152, 0.0722)


def surface_socket(tree):
    """The Surface input of a node tree's active output (Cycles' or All: a material's, a
    world's or a light's), or None."""
    if tree is None:
        return None
    output = tree.get_output_node('CYCLES') or tree.get_output_node('ALL')
    return None if output is None else output.inputs.get("Surface")


def _point_at_rest(dtype=np.float64) -> ShadingPoints:
    """One shading point at the origin facing +Z, seen from above: where constant nodes
    are folded, and where a program's fallback constants are read."""
    up = np.array([[0.0], [0.0], [1.0]], dtype)
    return ShadingPoints(np.zeros((3, 1), dtype), up, up, up)


def _with_needed(instructions, result) -> tuple:
    """The instructions, those of nodes that can skip outputs nobody reads (their function
    takes ``needed``: a Noise's colour costs 4x its Fac) told which outputs are read."""
    read = {result.index} if isinstance(result, Register) else set()
    for instruction in instructions:
        read |= {a.index for a in instruction.arguments if isinstance(a, Register)}
    done = []
    for instruction in instructions:
        spec = NODES[instruction.node]
        if "needed" in inspect.signature(spec.function).parameters:
            needed = tuple(identifier for (identifier, _), register
                           in zip(spec.outputs, instruction.outputs) if register in read)
            options = tuple(sorted(dict(instruction.options, needed=needed).items()))
            instruction = Instruction(instruction.node, instruction.arguments, options,
                                      instruction.outputs)
        done.append(instruction)
    return tuple(done)


def _nan_alpha(node, sockets) -> bool:
    alpha = sockets.get("Alpha")
    return (node.bl_idname == "ShaderNodeBsdfPrincipled" and alpha is not None
            and not alpha.is_linked and np.isnan(alpha.default_value))


def _is_constant(value) -> bool:
    return not isinstance(value, (Register, Coordinate))


def _read_option(node, name):
    value = getattr(node, name)
    if isinstance(value, (bool, int, float, str)):
        return value
    try:
        return tuple(float(v) for v in value)
    except TypeError:
        return value


def node_options(node, spec, context=None) -> dict:
    """A node's options: each of ``spec.options`` Blender's node has, read as it is, then
    what its reader in ``node_options.OPTION_READERS`` adds or replaces (a Texture
    Mapping, a Color Ramp's stops, an image)."""
    from .node_options import OPTION_READERS   # (the readers import the node modules)

    values = {name: _read_option(node, name) for name in spec.options if hasattr(node, name)}
    reader = OPTION_READERS.get(node.bl_idname)
    if reader is not None:
        takes_context = "context" in inspect.signature(reader).parameters
        values.update(reader(node, context) if takes_context else reader(node))
    return values


class ShaderCompiler:
    """Compiles one node tree (``compile``); owner names it in notes ("material 'Wood'")."""

    def __init__(self, owner: str, context=None, user: str = ""):
        self.owner = owner
        self.context = context
        self.user = user     # "object 'X', " : who uses the tree, for notes on its values
        self.notes: list[str] = []
        self.instructions: list[Instruction] = []
        self.registers = 0
        self.coordinates: set[str] = set()
        self._memo: dict = {}
        #: The normal shaders with an unlinked Normal use (a Register), or None: the hit's.
        self.shading_normal = None

    def note(self, text: str | None) -> None:
        if text and text not in self.notes:
            self.notes.append(text)

    # --- values ---------------------------------------------------------------------------

    def argument(self, socket, groups, kind: str, implicit: str | None = None,
                 closures_only: bool = False):
        """The value an input socket of ``kind`` receives: a Register, a Coordinate (an
        unlinked socket Cycles reads a coordinate for), or a constant.  closures_only: the
        socket is a shader node's, whose unlinked Normal is None (the hit's own normal)."""
        output, where = linked_source(socket, groups, self.owner)
        if output is None:
            if implicit == "normal" and closures_only:
                # A shader's own normal: the hit's (and foldable), or the displaced one.
                return self.shading_normal
            if implicit is not None and not followed(where):
                self.coordinates.add(implicit)
                return Coordinate(implicit)
            return self._default(where, kind)
        value = self._output(output, where)
        if value is None:      # an unsupported node: the socket's own value
            if kind == CLOSURE:
                return _default_surface()
            return self._default(socket, kind)
        return self._convert(value, _SOCKET_KINDS.get(output.type, FLOAT), kind)

    def _default(self, socket, kind: str):
        if kind == CLOSURE:
            return LobeSum.none()
        value = getattr(socket, "default_value", 0.0)
        fixed = counted(value)
        if fixed is not None:
            # NaN as 0 and infinities at the colour limit, as Cycles' clamps count them
            # (docs/invalid-data.md).
            node = getattr(socket, "node", None)
            raw = tuple(value) if hasattr(value, "__len__") else value
            # (A colour's RGB: its alpha is not what is read.)
            shown, fixed_shown = (raw[:3], fixed[:3]) if np.ndim(fixed) else (raw, fixed)
            self.note(f"{self.user}{self.owner}: '{socket.name}' of "
                      f"'{getattr(node, 'name', '?')}' is {value_text(as_stored(shown))}: "
                      f"it counts as {value_text(as_stored(fixed_shown))}")
            value = fixed
        try:
            values = tuple(float(v) for v in value)
        except TypeError:
            number = float(value)
            return number if kind == FLOAT else (number,) * 3
        if kind == FLOAT:
            return values[0] if len(values) == 1 else float(np.dot(values[:3], LUMINANCE))
        return values[:3]

    def _convert(self, value, source: str, kind: str):
        """Blender's implicit conversion of a ``source``-typed value to ``kind`` (Cycles'
        ``svm_node_convert``): float to colour or vector repeats it, a colour to float is
        its luminance, a vector to float its components' mean, a colour or vector into a
        shader socket emits it."""
        if source == kind or {source, kind} == {COLOR, VECTOR}:
            return value
        names = {(FLOAT, COLOR): "GlintFloatToColor", (FLOAT, VECTOR): "GlintFloatToColor",
                 (COLOR, FLOAT): "GlintColorToFloat", (VECTOR, FLOAT): "GlintVectorToFloat",
                 (COLOR, CLOSURE): "GlintColorToEmission",
                 (VECTOR, CLOSURE): "GlintColorToEmission",
                 (FLOAT, CLOSURE): "GlintFloatToEmission"}
        name = names.get((source, kind))
        if name is None:       # a shader into a value socket: Cycles reads nothing there
            return 0.0 if kind == FLOAT else (0.0, 0.0, 0.0)
        return self._emit(name, (value,), (), 1)[0]

    def _output(self, output, groups):
        """The value of a node's output socket, compiled once (memoised)."""
        node = output.node
        key = (node.as_pointer(), output.identifier, tuple(g.as_pointer() for g in groups))
        if key in self._memo:
            return self._memo[key]
        spec = NODES.get(node.bl_idname)
        if spec is None:
            self._unsupported(node, output)
            self._memo[key] = None
            return None
        sockets = {socket.identifier: socket for socket in node.inputs}
        if _nan_alpha(node, sockets):
            # Measured: Cycles renders a Principled BSDF of NaN Alpha black and opaque.
            self.note(f"{self.user}{self.owner}: 'Alpha' of '{node.name}' is nan: the "
                      f"Principled BSDF renders black and opaque, as in Cycles")
            self._memo[key] = LobeSum.none()
            return self._memo[key]
        shader = all(kind == CLOSURE for _, kind in spec.outputs)
        arguments = []
        for identifier, kind in spec.inputs:
            socket = sockets.get(identifier)
            if socket is None and absent_input_value(node.bl_idname, identifier) is not None:
                # An input newer than this Blender: the value compat stands in for it.
                arguments.append(absent_input_value(node.bl_idname, identifier))
                continue
            if socket is None:
                raise ShaderCompileError(f"{self.owner}: node '{node.name}' has no input "
                                         f"'{identifier}' in this Blender")
            arguments.append(self.argument(socket, groups, kind, spec.implicit.get(identifier),
                                           shader))
        options = self._options(node, spec)
        if spec.stand_in:
            self.note(f"{self.owner}: node '{node.name}' ({node.bl_label}) is {spec.note}")
        reads = NODE_COORDINATES.get(node.bl_idname)
        if reads is not None:
            self.coordinates |= reads(node)
        for identifier, option in SUBPROGRAM_INPUTS.get(node.bl_idname, ()):
            options = tuple(sorted(dict(options, **{option: self._subprogram(
                sockets[identifier], groups)}).items()))
        values = self._emit(node.bl_idname, tuple(arguments), options, len(spec.outputs))
        identifiers = [identifier for identifier, _ in spec.outputs]
        for identifier, value in zip(identifiers, values):
            self._memo[(key[0], identifier, key[2])] = value
        if output.identifier not in identifiers:
            self._unsupported(node, output)
            self._memo[key] = None
        return self._memo[key]

    def displace(self, socket) -> None:
        """Make the material output's Displacement ``socket`` bump the normal every shader
        with an unlinked Normal reads, as Cycles' Bump Only displacement does."""
        program = self._subprogram(socket, (), VECTOR)
        if not isinstance(program, ShaderProgram):
            return      # a constant displacement tilts nothing
        self.coordinates.add("normal")
        self.shading_normal = self._emit("GlintDisplacementBump", (Coordinate("normal"),),
                                         (("displacement", program),), 1)[0]

    def _subprogram(self, socket, groups, kind: str = FLOAT):
        """The program (or constant) computing an input of ``kind`` on its own."""
        child = ShaderCompiler(self.owner, self.context)
        value = child.argument(socket, groups, kind)
        self.notes += [note for note in child.notes if note not in self.notes]
        self.coordinates |= child.coordinates
        if _is_constant(value):
            return value
        return ShaderProgram(_with_needed(child.instructions, value), value, child.registers,
                             self.owner, frozenset(child.coordinates))

    def _options(self, node, spec) -> tuple:
        return tuple(sorted(node_options(node, spec, self.context).items()))

    def _emit(self, name: str, arguments: tuple, options: tuple, outputs: int) -> list:
        """The outputs of node ``name`` on ``arguments``: folded to constants where every
        argument is one and the node reads nothing of the points, else an instruction."""
        spec = NODES[name]
        if all(_is_constant(a) for a in arguments) and not spec.reads_points:
            registers = [None] * outputs
            instruction = Instruction(name, arguments, options, tuple(range(outputs)))
            evaluate(instruction, registers, _point_at_rest(), np.float64)
            return [_constant(value) for value in registers]
        if len(self.instructions) >= MAX_INSTRUCTIONS:
            raise ShaderCompileError(f"{self.owner}: its node tree is larger than "
                                     f"{MAX_INSTRUCTIONS} nodes")
        first = self.registers
        self.registers += outputs
        self.instructions.append(Instruction(name, arguments, options,
                                             tuple(range(first, first + outputs))))
        return [Register(first + i) for i in range(outputs)]

    def _unsupported(self, node, output) -> None:
        if node.bl_idname == "NodeUndefined":
            self.note(f"{self.owner}: node '{node.name}' is undefined (an add-on's that is "
                      f"not installed); what it feeds takes its own value")
            return
        self.note(f"{self.owner}: node '{node.name}' ({node.bl_label}) is not supported; "
                  f"what it feeds takes its own value")

    # --- whole trees --------------------------------------------------------------------

    def compile(self, socket, kind: str = CLOSURE):
        """The program computing ``socket``'s value, or the constant it folds to."""
        value = self.argument(socket, (), kind)
        if _is_constant(value):
            return value
        return ShaderProgram(_with_needed(self.instructions, value), value, self.registers,
                             self.owner, frozenset(self.coordinates))


def _constant(value):
    """A folded value as a constant argument: a float, a tuple of 3 floats, or a closure."""
    if isinstance(value, LobeSum):
        return value
    array = np.asarray(value, np.float64)
    if array.size == 1:
        return float(array.reshape(-1)[0])
    return tuple(float(v) for v in array.reshape(-1)[:3])


def _default_surface() -> LobeSum:
    """Blender's default grey diffuse, for a shader node Glint does not support."""
    lobes = LobeSum.none()
    lobes.diffuse = np.full((3, 1), 0.8)
    return lobes


def surface_material(value, compiler: "ShaderCompiler | None" = None) -> SurfaceMaterial:
    """The SurfaceMaterial of a compiled Surface: the constants it folded to, or for a
    program its value at a point at rest (what the Whitted integrator and the passes use)
    with the program attached (the path integrator's).  Colours past the core's limit are
    clamped to it, with a note to ``compiler`` (Cycles' pixels are as blown out)."""
    program = None
    if isinstance(value, ShaderProgram):
        program = value
        closures = run(program, _point_at_rest()).closures(1, np.float64)
    else:
        closures = constant_array(value, np.float64).closures(1, np.float64)
    beyond = [name for name in ("diffuse", "f0", "f90", "transmission", "emission",
                                "transparency", "translucency")
              if np.max(np.abs(getattr(closures, name))) > MAX_COLOUR]
    for name in beyond:
        setattr(closures, name, np.clip(getattr(closures, name), -MAX_COLOUR, MAX_COLOUR))
    if beyond and compiler is not None:
        compiler.note(f"{compiler.user}{compiler.owner}: {', '.join(beyond)} past "
                      f"{MAX_COLOUR:g} is clamped to it (Cycles' pixels are as blown out)")
    return closures_material(closures, program)


def closures_material(closures: Closures, program=None) -> SurfaceMaterial:
    """A SurfaceMaterial of one hit's closures (``Closures`` of length 1)."""
    first = lambda a: tuple(float(v) for v in np.asarray(a)[:, 0])  # noqa: E731
    return SurfaceMaterial(
        diffuse=first(closures.diffuse), layer=float(closures.layer[0]),
        layer_f0=float(closures.layer_f0[0]), specular_f0=first(closures.f0),
        specular_f90=first(closures.f90), specular_dielectric=float(closures.dielectric[0]),
        specular_ior=float(closures.specular_ior[0]),
        roughness=float(np.sqrt(closures.alpha[0])),
        transmission=first(closures.transmission),
        transmission_fresnel=float(closures.transmission_fresnel[0]),
        ior=float(closures.ior[0]), emission=first(closures.emission),
        transparency=first(closures.transparency), translucency=first(closures.translucency),
        holdout=float(closures.holdout[0]), program=program)
