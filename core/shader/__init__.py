"""Shader programs: Blender's node trees, compiled by the add-on into flat lists of node
evaluations (``core.shader.registry``) that the core runs over arrays of shading points,
as Cycles' SVM runs a node graph compiled to a list of operations over a stack."""

# Importing the node modules registers their nodes in ``registry.NODES``.
from . import (bsdf_nodes, colour_nodes, conversions, converter_nodes,  # noqa: E402,F401
               ies, images, input_nodes, sky, textures, vector_nodes)
