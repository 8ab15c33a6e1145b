"""Node options that ``getattr(node, name)`` does not give as plain values: a reader per
node type returns {option name: plain Python value} for the options it knows, to be passed to
the node's function (``core.shader.registry``) in place of getattr's.

Every procedural texture but White Noise has a Texture Mapping (``node.texture_mapping``, a
``TexMapping`` struct, set in the node's sidebar) that Cycles applies to the Vector before
the texture; ``texture_mapping`` reads the parts Cycles reads (not Min/Max, and not the
node's Color Mapping, which Cycles ignores).
"""

from __future__ import annotations


def texture_mapping(node) -> dict:
    """{'texture_mapping': {translation, rotation, scale (3-tuples of floats), vector_type,
    mapping_x, mapping_y, mapping_z (enum identifiers)}}."""
    mapping = node.texture_mapping
    return {"texture_mapping": {
        "translation": tuple(mapping.translation), "rotation": tuple(mapping.rotation),
        "scale": tuple(mapping.scale), "vector_type": mapping.vector_type,
        "mapping_x": mapping.mapping_x, "mapping_y": mapping.mapping_y,
        "mapping_z": mapping.mapping_z}}


OPTION_READERS = {node_type: texture_mapping for node_type in (
    "ShaderNodeTexNoise", "ShaderNodeTexVoronoi", "ShaderNodeTexWave", "ShaderNodeTexMagic",
    "ShaderNodeTexGradient", "ShaderNodeTexChecker", "ShaderNodeTexBrick")}
