"""What the benchmark's Blender scenes (``bench.readme_picture``, ``bench.textured_scenes``)
build alike, with bpy imported only when called."""

from __future__ import annotations


def principled_material(name: str, colour, roughness: float, metallic: float = 0.0):
    """A new material whose Principled BSDF has ``colour`` (RGB), ``roughness`` and
    ``metallic``."""
    import bpy

    material = bpy.data.materials.new(name)
    principled = material.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (*colour, 1.0)
    principled.inputs["Roughness"].default_value = roughness
    principled.inputs["Metallic"].default_value = metallic
    return material
