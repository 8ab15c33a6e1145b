"""Export: Blender's evaluated scene -> a core Scene (``export_scene``), one pure step that
reads Blender data and changes nothing.  One module per kind of data, as in BlendLuxCore's
export/ and mitsuba-blender's io/exporter/, sharing one ``context.ExportContext``:
``scene`` (the depsgraph walk), ``meshes``, ``geometry`` (sphere or triangles),
``pointclouds``, ``instances`` (Geometry Nodes instances in bulk), ``lights``, ``materials``,
``camera``; and ``view``, a 3D View's region exported as a core camera (Rendered shading)."""

from .errors import ExportError
from .scene import export_scene

__all__ = ["ExportError", "export_scene"]
