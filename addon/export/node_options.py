"""Options of shader nodes that need more than ``getattr(node, name)``.

``OPTION_READERS[bl_idname](node, context)`` returns the node's options as its registered
function takes them (``core.shader.registry``), by keyword.  ``context`` is the export's
``ExportContext``: image nodes take their ``core.shader.images.ImageData`` from its image
exporter (``ExportContext.image_exporter``: each image read once per export), and warnings
go to it.  A context may name what is being compiled in ``owner`` ("material 'Wood'");
without it the owner is found from the node's tree.
"""

from __future__ import annotations

import bpy


def owner_name(node, context=None) -> str:
    """How warnings name what uses ``node``: the context's owner, else the material, world
    or light whose node tree holds it, else its node group."""
    owner = getattr(context, "owner", None)
    if owner:
        return owner
    tree = node.id_data
    for kind, collection in (("material", bpy.data.materials), ("world", bpy.data.worlds),
                             ("light", bpy.data.lights)):
        for item in collection:
            if item.node_tree is not None and item.node_tree == tree:
                return f"{kind} '{item.name}'"
    return f"node group '{tree.name}'"


def _image(node, context):
    return context.image_exporter().image(node.image, node.image_user,
                                          owner_name(node, context))


def image_texture_options(node, context) -> dict:
    """Image Texture: its image as ImageData, and whether its Alpha output is used (Cycles
    then divides Color by alpha)."""
    return dict(image=_image(node, context), interpolation=node.interpolation,
                projection=node.projection, projection_blend=node.projection_blend,
                extension=node.extension, alpha_used=node.outputs["Alpha"].is_linked)


def environment_texture_options(node, context) -> dict:
    """Environment Texture: its image as ImageData."""
    return dict(image=_image(node, context), interpolation=node.interpolation,
                projection=node.projection)


OPTION_READERS = {
    "ShaderNodeTexImage": image_texture_options,
    "ShaderNodeTexEnvironment": environment_texture_options,
}
