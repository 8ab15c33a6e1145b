"""Rendering: ``job`` (export + trace + finish, shared by everyone who renders) and ``final``
(the RenderEngine in Blender's engine list)."""
