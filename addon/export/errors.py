class ExportError(Exception):
    """The scene cannot be rendered (no camera, a panoramic camera, ...); the message says why
    and names the object, and is meant for the user as is."""


class ShaderCompileError(ExportError):
    """A node tree the compiler cannot turn into a program (too deep, too large)."""
