"""Blender materials -> core materials.

Default semantics (``export_material``): the material's shader nodes are evaluated into a
``core.SurfaceMaterial`` (``NodeEvaluator`` below; README's table lists what each node
becomes); Viewport Display is the fallback for a material without a usable node tree.

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
from ...core.reflectance import blinn_exponent
from ...core.validation import value_text
from ..compat import node_tree_in_use
from ..utils.colour import colour_from_blender
from .shader import ShaderCompiler, surface_material, surface_socket
from .values import as_stored, counted

AMBIENT_FRACTION = 0.1
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
    surface = surface_socket(node_tree_in_use(material))
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


def usable_custom_material(material, where: str) -> tuple[Optional[Material], Optional[str]]:
    """(the Glint section as a core Material, None) when "Custom" is on and its values are
    valid; (None, a note) when they are not (a script can set them past the panel's limits):
    the material's own surface is used then, which is all Cycles reads; (None, None) when
    "Custom" is off."""
    settings = getattr(material, "glint", None)
    if settings is None or not settings.use_custom:
        return None, None
    try:
        return custom_material(settings), None
    except SceneError as error:
        return None, f"{where}: its Glint Custom values are invalid ({error}): its surface " \
                     f"is used, as Cycles uses it"


def export_article_material(material, owner: str = "") -> tuple[Material, Optional[str]]:
    """(core Material, note or None) for a bpy Material or None (Blender's default surface),
    article semantics; owner: the object using it, named in notes about invalid values."""
    if material is None:
        return material_from_surface(SurfaceValues(**DEFAULT_SURFACE)), None
    where = _where(material, owner)
    custom, custom_note = usable_custom_material(material, where)
    if custom is not None:
        return custom, None
    values, note = surface_values(material)
    values, value_note = usable_values(values, where)
    notes = [text for text in (custom_note, note, value_note) if text]
    return material_from_surface(values), ("; ".join(notes) or None)


def _where(material, owner: str) -> str:
    return f"object '{owner}', material '{material.name}'" if owner else \
        f"material '{material.name}'"


def usable_values(values: SurfaceValues, where: str) -> tuple[SurfaceValues, Optional[str]]:
    """``values`` with NaN counted as 0 and what is infinite or past MAX_COLOUR in size
    clamped to +-MAX_COLOUR (as ``NodeEvaluator.usable``), and a note naming the fields, or
    None."""
    fields, named = {}, []
    for name in ("base_colour", "metallic", "roughness", "specular_level"):
        value = getattr(values, name)
        fixed = counted(value)
        if fixed is not None:
            named.append(f"{name.replace('_', ' ')} {value_text(as_stored(value))} counts "
                         f"as {value_text(as_stored(fixed))}")
            value = tuple(fixed) if np.ndim(fixed) else fixed
        fields[name] = value
    if not named:
        return values, None
    return SurfaceValues(**fields), f"{where}: {'; '.join(named)}"


# --------------------------------------------------------------------------------------------
# Default semantics: the shader nodes as a program (``shader``).

def _viewport_display(material, where: str) -> tuple[SurfaceMaterial, Optional[str]]:
    values, note = usable_values(SurfaceValues(
        base_colour=tuple(material.diffuse_color[:3]), metallic=material.metallic,
        roughness=material.roughness, specular_level=0.5), where)
    return SurfaceMaterial.principled(
        base_color=tuple(max(c, 0.0) for c in values.base_colour),
        metallic=min(max(values.metallic, 0.0), 1.0),
        roughness=min(max(values.roughness, 0.0), 1.0)), note


def displacement_method(material) -> str:
    """The material's Settings > Displacement method ('BUMP', 'DISPLACEMENT' or 'BOTH')."""
    method = getattr(material, "displacement_method", None)   # Blender 4.1 and later
    if method is None:
        method = getattr(getattr(material, "cycles", None), "displacement_method", 'BUMP')
    return method


def export_material(material, owner: str = "", context=None) -> tuple[
        SurfaceMaterial | Material, Optional[str]]:
    """(core material, note or None) for a bpy Material or None, default semantics; owner:
    the object using it, named in notes about invalid values; context: the export context
    (its image cache).

    None gets Blender's default surface (a default Principled BSDF).  The Glint section with
    "Custom" on gives the article's Material as typed.  A material without a node tree uses
    its Viewport Display colour, metallic and roughness; one whose tree has no Material
    Output for Cycles (another engine's, say) or nothing plugged into its Surface renders
    black, as in Cycles, with a note.  Otherwise its Surface is compiled (``shader``):
    constants where the tree folds to them, else a program the path integrator runs per
    hit."""
    if material is None:
        return SurfaceMaterial.principled(), None
    where = _where(material, owner)
    custom, custom_note = usable_custom_material(material, where)
    if custom is not None:
        return custom, None
    tree = node_tree_in_use(material)
    if tree is None:
        viewport, note = _viewport_display(material, where)
        return viewport, ("; ".join(filter(None, (custom_note, note))) or None)
    surface = surface_socket(tree)
    if surface is None or not surface.is_linked:
        return SurfaceMaterial(diffuse=(0.0, 0.0, 0.0)), "; ".join(filter(None, (
            custom_note, f"material '{material.name}': no shader reaches a Cycles Material "
                         f"Output; it renders black, as in Cycles")))
    compiler = ShaderCompiler(f"material '{material.name}'", context,
                              f"object '{owner}', " if owner else "")
    compiler.note(custom_note)
    displacement = surface.node.inputs.get("Displacement")
    if displacement is not None and displacement.is_linked:
        if displacement_method(material) != 'BUMP':
            compiler.note(f"material '{material.name}': its displacement is rendered as bump "
                          f"(Cycles' Bump Only), not by moving the surface")
        compiler.displace(displacement)
    value = compiler.compile(surface)
    return surface_material(value, compiler), ("; ".join(compiler.notes) or None)
