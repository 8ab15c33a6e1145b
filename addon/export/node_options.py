"""Readers of the shader nodes whose options are more than plain properties: what the core's
node functions (``core.shader.registry``) take by keyword, as plain Python values.
``OPTION_READERS[bl_idname](node)`` (or ``(node, context)``, for readers that need the
export context's caches) returns all the options of that node type; nodes without a reader
have their ``NodeSpec.options`` read with ``getattr``."""

OPTION_READERS: dict = {}
