"""Blender materials -> core materials.

Default semantics (``export_material``): the material's shader nodes are evaluated into a
``core.SurfaceMaterial`` (``NodeEvaluator`` below; docs/user-guide.md's table lists what each
node becomes); Viewport Display is the fallback for a material without a usable node tree.

Article semantics (``export_article_material``): the article's five Blinn-Phong parameters.
Three sources, in order:

1. The material's Glint section with "Custom" on: ambient, diffuse, specular, shininess and
   reflection exactly as typed (the colours are display values, like the article's numbers).
2. A Principled BSDF plugged into the material output's Surface: its Base Color, Metallic,
   Roughness and Specular IOR Level (unlinked values; a linked input such as a texture
   counts as its unlinked value and is reported).
3. Otherwise the material's Viewport Display colour, metallic, roughness and specular
   intensity.  An object with no material gets Blender's default surface (base colour 0.8,
   metallic 0, roughness 0.5, specular 0.5).

Mapping from (base colour, metallic m, roughness rho, specular level s), with c the base
colour sRGB-encoded (``addon.utils.colour``: the colour as Blender displays it):

* diffuse  = c (1 - m): metals have no diffuse lobe;
* ambient  = 0.1 (1 - m) c / max(c): a tenth of the colour's hue at full value, the article's
  ambient (0.7, 0, 0) red -> (0.1, 0, 0), (0.6, 0.6, 0.6) grey -> (0.1, 0.1, 0.1);
* shininess = 4 n with n = 2 / alpha^2 - 2, alpha = rho^2 (Blender's roughness convention):
  the Blinn-Phong exponent matching a Beckmann lobe (Walter et al. 2007); the core shades
  with (N.H)^(shininess / 4), the article's Phong-to-Blinn factor.  rho = 0.5 gives 120,
  the article uses 100;
* specular = mix(white, c, m) * 2 s * min(1, (n + 2) / 32): white highlights for dielectrics,
  tinted for metals, scaled by the specular level (default 0.5 -> 1) and dimmed as the lobe
  widens following Blinn-Phong's (n + 2) normalisation relative to the default roughness
  (n = 30), so a rough material does not get a full-strength highlight over its whole face;
* reflection = 1 - rho: a smooth surface is a mirror; the default 0.5 is the article's 0.5.

So Blender's default material maps to ambient 0.1, diffuse 0.91, specular 1, shininess 120,
reflection 0.5: the article's look in grey.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...core import Material, SceneError, SurfaceMaterial
from ..utils.colour import colour_from_blender
from .shader import ShaderCompiler, surface_material

AMBIENT_FRACTION = 0.1
#: alpha = roughness^2 is clamped here so a roughness of 0 gives a finite exponent.
MIN_ALPHA = 1e-3
#: Blinn exponent of the default roughness 0.5 (alpha 0.25): 2 / 0.25^2 - 2.
REFERENCE_EXPONENT = 30.0

DEFAULT_SURFACE = dict(base_colour=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5,
                       specular_level=0.5)


@dataclass(frozen=True)
class SurfaceValues:
    """The Blender-side inputs of the mapping (base colour scene-linear)."""

    base_colour: tuple[float, float, float]
    metallic: float
    roughness: float
    specular_level: float


def blinn_exponent(roughness: float) -> float:
    alpha = max(float(roughness) ** 2, MIN_ALPHA)
    return 2.0 / alpha ** 2 - 2.0


def material_from_surface(values: SurfaceValues) -> Material:
    """The article's parameters for a Principled-style surface (mapping in the module doc)."""
    colour = np.asarray(colour_from_blender(values.base_colour))
    metallic = float(np.clip(values.metallic, 0.0, 1.0))
    roughness = float(np.clip(values.roughness, 0.0, 1.0))
    level = max(float(values.specular_level), 0.0)
    brightest = colour.max()
    hue = colour / brightest if brightest > 0 else colour
    exponent = blinn_exponent(roughness)
    lobe = min(1.0, (exponent + 2.0) / (REFERENCE_EXPONENT + 2.0))
    specular = ((1.0 - metallic) + metallic * colour) * 2.0 * level * lobe
    return Material(
        ambient=tuple(AMBIENT_FRACTION * (1.0 - metallic) * hue),
        diffuse=tuple(colour * (1.0 - metallic)),
        specular=tuple(specular),
        shininess=4.0 * exponent,
        reflection=1.0 - roughness,
    )


def _surface_node(material):
    """The shader node plugged into the active material output's Surface, or None."""
    tree = material.node_tree
    if tree is None:
        return None
    output = tree.get_output_node('CYCLES') or tree.get_output_node('ALL')
    if output is None:
        return None
    surface = output.inputs.get("Surface")
    if surface is None or not surface.is_linked:
        return None
    return surface.links[0].from_node


def _principled_values(node) -> tuple[SurfaceValues, list[str]]:
    linked = [name for name in ("Base Color", "Metallic", "Roughness", "Specular IOR Level")
              if node.inputs[name].is_linked]
    values = SurfaceValues(
        base_colour=tuple(node.inputs["Base Color"].default_value[:3]),
        metallic=node.inputs["Metallic"].default_value,
        roughness=node.inputs["Roughness"].default_value,
        specular_level=node.inputs["Specular IOR Level"].default_value,
    )
    return values, linked


def surface_values(material) -> tuple[SurfaceValues, Optional[str]]:
    """(the mapping's inputs, a note for the user or None) for a bpy Material (not custom)."""
    node = _surface_node(material)
    if node is not None and node.bl_idname == "ShaderNodeBsdfPrincipled":
        values, linked = _principled_values(node)
        note = (f"material '{material.name}': linked inputs ({', '.join(linked)}) count as "
                f"their unlinked values") if linked else None
        return values, note
    values = SurfaceValues(
        base_colour=tuple(material.diffuse_color[:3]),
        metallic=material.metallic,
        roughness=material.roughness,
        specular_level=material.specular_intensity,
    )
    return values, (f"material '{material.name}': its Surface is not a Principled BSDF, "
                    f"its Viewport Display values are used")


def custom_material(settings) -> Material:
    """The material's Glint section (``Material.glint``) as a core Material."""
    return Material(ambient=tuple(settings.ambient), diffuse=tuple(settings.diffuse),
                    specular=tuple(settings.specular), shininess=settings.shininess,
                    reflection=settings.reflection)


def export_article_material(material) -> tuple[Material, Optional[str]]:
    """(core Material, note or None) for a bpy Material or None (Blender's default surface),
    article semantics."""
    if material is None:
        return material_from_surface(SurfaceValues(**DEFAULT_SURFACE)), None
    settings = getattr(material, "glint", None)
    if settings is not None and settings.use_custom:
        return custom_material(settings), None
    values, note = surface_values(material)
    check_finite(values)
    return material_from_surface(values), note


def check_finite(values: SurfaceValues) -> None:
    """Raise SceneError naming the first input that is NaN or infinite (the mapping would
    otherwise hide which one it was behind a derived field)."""
    for name in ("base_colour", "metallic", "roughness", "specular_level"):
        value = getattr(values, name)
        if not np.all(np.isfinite(value)):
            raise SceneError(f"{name.replace('_', ' ')} must be finite, got {value!r}")


# --------------------------------------------------------------------------------------------
# Default semantics: the shader nodes as a program (``shader``).

def surface_socket(tree):
    """The Surface input of the active Material Output (Cycles' or All), or None."""
    if tree is None:
        return None
    output = tree.get_output_node('CYCLES') or tree.get_output_node('ALL')
    return None if output is None else output.inputs.get("Surface")


def _viewport_display(material) -> SurfaceMaterial:
    return SurfaceMaterial.principled(base_color=tuple(material.diffuse_color[:3]),
                                      metallic=material.metallic, roughness=material.roughness)


def export_material(material, context=None) -> tuple[SurfaceMaterial | Material, Optional[str]]:
    """(core material, note or None) for a bpy Material or None, default semantics.

    None gets Blender's default surface (a default Principled BSDF).  The Glint section with
    "Custom" on gives the article's Material as typed.  A material without a node tree uses
    its Viewport Display colour, metallic and roughness; one whose tree has no Material
    Output for Cycles (another engine's, say) or nothing plugged into its Surface renders
    black, as in Cycles, with a note.  Otherwise its Surface is compiled (``shader``):
    constants where the tree folds to them, else a program the path integrator runs per
    hit.  context: the export context (its image cache)."""
    if material is None:
        return SurfaceMaterial.principled(), None
    settings = getattr(material, "glint", None)
    if settings is not None and settings.use_custom:
        return custom_material(settings), None
    if material.node_tree is None:
        return _viewport_display(material), None
    surface = surface_socket(material.node_tree)
    if surface is None or not surface.is_linked:
        return SurfaceMaterial(diffuse=(0.0, 0.0, 0.0)), (
            f"material '{material.name}': no shader reaches a Cycles Material Output; it "
            f"renders black, as in Cycles")
    compiler = ShaderCompiler(f"material '{material.name}'", context)
    value = compiler.compile(surface)
    return surface_material(value), ("; ".join(compiler.notes) or None)
