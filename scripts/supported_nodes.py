"""Write docs/supported-nodes.md: every shader node of the running Blender, supported,
approximated (how) or ignored, from Glint's node registry (``core.shader.registry``).

    .venv/bin/python scripts/supported_nodes.py          # rewrites docs/supported-nodes.md
    .venv/bin/python scripts/supported_nodes.py --check  # exit 1 if the page is stale

The page is generated so that it cannot drift from the code: tests/test_supported_nodes.py
checks the file against ``page()``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGE = os.path.join(REPOSITORY, "docs", "supported-nodes.md")

#: Blender's Add menu categories, in its order, with the registry module each one's
#: supported nodes come from.
CATEGORIES = ("Input", "Shader", "Texture", "Color", "Vector", "Converter")
_MODULE_CATEGORIES = {"input_nodes": "Input", "bsdf_nodes": "Shader", "textures": "Texture",
                      "images": "Texture", "ies": "Texture", "sky": "Texture",
                      "colour_nodes": "Color", "vector_nodes": "Vector",
                      "converter_nodes": "Converter"}
#: Nodes Glint does not evaluate, by category (the rest by name: Tex* are textures, BSDFs
#: and volumes are shaders, anything else a converter).
_INPUTS = {"ShaderNodeAmbientOcclusion", "ShaderNodeBevel", "ShaderNodeCameraData",
           "ShaderNodeHairInfo", "ShaderNodeLightFalloff", "ShaderNodeParticleInfo",
           "ShaderNodePointInfo", "ShaderNodeTangent", "ShaderNodeUVAlongStroke",
           "ShaderNodeWireframe", "ShaderNodeVolumeInfo", "ShaderNodeRaycast"}
_VECTORS = {"ShaderNodeDisplacement", "ShaderNodeVectorDisplacement", "ShaderNodeNormal"}
#: Nodes the compiler walks through rather than evaluates.
STRUCTURE = (
    ("Material Output, World Output, Light Output", "the active output's Surface (Cycles' "
     "or All) is what renders; a material's Displacement bumps its normal (Cycles' Bump "
     "Only method, whatever the material's method, with a note otherwise); a light's "
     "Surface multiplies its colour (Use Nodes on: an Emission's constant colour x strength, "
     "or a program evaluated where each light sample leaves a point, spot or area light; a "
     "sun takes its value at rest); Volume is not read"),
    ("Group, Group Input, Group Output", "flattened: a group renders as its nodes"),
    ("Reroute", "passed through"),
    ("a muted node", "passes its first input of the output's kind through, as Blender "
     "does"),
    ("Frame", "ignored (layout only)"),
)
#: Node classes that are not nodes a user adds to a shader tree.
_NOT_NODES = {"ShaderNode", "ShaderNodeTree", "ShaderNodeCustomGroup", "ShaderNodeGroup",
              "ShaderNodeOutputMaterial", "ShaderNodeOutputWorld", "ShaderNodeOutputLight",
              "ShaderNodeOutputAOV", "ShaderNodeOutputLineStyle"}


def _glint():
    """This checkout's package, as render.py imports it (``glint``)."""
    if "glint" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "glint", os.path.join(REPOSITORY, "__init__.py"),
            submodule_search_locations=[REPOSITORY])
        module = importlib.util.module_from_spec(spec)
        sys.modules["glint"] = module
        spec.loader.exec_module(module)
    return sys.modules["glint"]


def _category(bl_idname: str, spec) -> str:
    if spec is not None:
        return _MODULE_CATEGORIES.get(spec.function.__module__.rsplit(".", 1)[-1], "Converter")
    name = bl_idname[len("ShaderNode"):]
    if bl_idname in _INPUTS:
        return "Input"
    if bl_idname in _VECTORS:
        return "Vector"
    if name.startswith("Tex"):
        return "Texture"
    if any(word in name for word in ("Bsdf", "Shader", "Volume", "Eevee", "Emission",
                                     "Holdout", "Background", "Subsurface")):
        return "Shader"
    return "Converter"


def rows():
    """(category, label, status, how) for every shader node type of the running Blender."""
    import bpy

    _glint()
    importlib.import_module("glint.core.shader")      # (registers every node)
    registry = importlib.import_module("glint.core.shader.registry").NODES
    found = []
    for name in sorted(dir(bpy.types)):
        if not name.startswith("ShaderNode") or name in _NOT_NODES:
            continue
        cls = getattr(bpy.types, name)
        if not isinstance(cls, type) or not issubclass(cls, bpy.types.ShaderNode):
            continue
        label = cls.bl_rna.name
        spec = registry.get(name)
        category = _category(name, spec)
        if spec is None:
            status = "ignored"
            how = ("named in a note; renders as Blender's default grey diffuse"
                   if category == "Shader" else
                   "named in a note; what it feeds takes its own value")
        elif spec.stand_in:
            status, how = "stand-in", f"{spec.note}, named in a warning"
        elif spec.note:
            status, how = "approximated", spec.note
        else:
            status, how = "supported", "as Cycles evaluates it, per hit"
        found.append((category, label, status, how))
    return found


def page() -> str:
    import bpy

    table = rows()
    counts = {status: sum(1 for row in table if row[2] == status)
              for status in ("supported", "approximated", "stand-in", "ignored")}
    lines = [
        "# Supported nodes",
        "",
        "Glint compiles each material's and world's node tree once, at export, into a small "
        "program",
        "that the core evaluates over arrays of hits (as Cycles' SVM does): textures, "
        "coordinates",
        "and utility nodes are computed per hit with Cycles' own formulas, so the same "
        "coordinates",
        "give the same values (within float32 rounding). A tree of constants is folded into "
        "constants.",
        "",
        "- **supported**: evaluated per hit as Cycles evaluates it;",
        "- **approximated**: evaluated, with the difference said;",
        "- **stand-in**: rendered as another node (said), and named in a warning at render "
        "time;",
        "- **ignored**: named in a note; the input it feeds takes its own unlinked value (a "
        "shader:",
        "  Blender's default grey diffuse).",
        "",
        f"Of Blender {bpy.app.version_string}'s shader nodes: {counts['supported']} supported, "
        f"{counts['approximated']} approximated, {counts['stand-in']} stand-ins, "
        f"{counts['ignored']} ignored.",
        "This page is generated from the code (`scripts/supported_nodes.py`); the accuracy "
        "of each",
        "family against Cycles is in [accuracy.md](accuracy.md).",
        "",
        "## Structure",
        "",
        "| node | how |",
        "|---|---|",
    ]
    lines += [f"| {label} | {how} |" for label, how in STRUCTURE]
    for category in CATEGORIES:
        lines += ["", f"## {category}", "", "| node | status | how |", "|---|---|---|"]
        lines += [f"| {label} | {status} | {how} |"
                  for cat, label, status, how in sorted(table, key=lambda r: r[1])
                  if cat == category]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if docs/supported-nodes.md differs from the code")
    args = parser.parse_args(argv)
    text = page()
    if args.check:
        with open(PAGE, encoding="utf-8") as current:
            stale = current.read() != text
        if stale:
            print(f"{PAGE} is stale: run scripts/supported_nodes.py", file=sys.stderr)
        return int(stale)
    with open(PAGE, "w", encoding="utf-8") as out:
        out.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
