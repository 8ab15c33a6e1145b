"""Helpers: colour transfer functions, Image datablock I/O, the article's scene in bpy."""
