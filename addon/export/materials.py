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

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...core import Material, SceneError, SurfaceMaterial
from ...core.reflectance import blinn_exponent, dielectric_f0, principled_fresnel
from ...core.validation import MAX_COLOUR, value_text
from ..utils.colour import colour_from_blender, srgb_to_linear

AMBIENT_FRACTION = 0.1
#: Blinn exponent of the default roughness 0.5 (alpha 0.25): 2 / 0.25^2 - 2.
REFERENCE_EXPONENT = 30.0

def counted(value, nan: float = 0.0):
    """A value read from Blender (a float or an array) as Glint counts it when it is not
    usable as is: NaN as ``nan``, what is infinite or past MAX_COLOUR in size as
    +-MAX_COLOUR; None when it is usable (docs/invalid-data.md: Cycles' own clamps drop a NaN
    to the low end of an input's range; infinite pixels are what Glint cannot write)."""
    array = np.asarray(value, float)
    if (np.abs(array) <= MAX_COLOUR).all():
        return None
    fixed = np.clip(np.where(np.isnan(array), nan, array), -MAX_COLOUR, MAX_COLOUR)
    return float(fixed) if fixed.ndim == 0 else fixed


def as_stored(value) -> np.ndarray:
    """A value read from Blender as the float32 Blender holds it, for a message to show as
    Blender's interface shows it (0.1, not 0.10000000149011612; past float32's range: inf)."""
    with np.errstate(over="ignore"):
        return np.asarray(value, np.float32)


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
# Default semantics: the shader nodes as lobes.

@dataclass
class Lobes:
    """A shader's lobes, linear in everything so Mix and Add Shader are sums: colours (3,)
    arrays, and roughness / ior / transmission_fresnel carried as weighted sums (divided by
    their weights at the end)."""

    diffuse: np.ndarray
    f0: np.ndarray
    f90: np.ndarray
    gloss_weight: float        # sum of the glossy lobes' strengths (mean f90)
    roughness_sum: float       # sum of strength x roughness
    transmission: np.ndarray
    refraction_weight: float   # sum of the transmissions' strengths (mean colour)
    ior_sum: float
    fresnel_sum: float
    emission: np.ndarray
    transparency: np.ndarray
    translucency: np.ndarray
    holdout: float
    layered_sum: float         # sum of the layered diffuse lobes' strengths (mean colour)
    layer_f0_sum: float        # sum of strength x their specular layer's f0
    dielectric_sum: float      # sum of the glossy rises (f90 - f0) of dielectric curve
    specular_ior_sum: float    # sum of those rises x their index

    @classmethod
    def none(cls) -> "Lobes":
        zero = np.zeros(3)
        return cls(zero, zero, zero, 0.0, 0.0, zero, 0.0, 0.0, 0.0, zero, zero, zero, 0.0,
                   0.0, 0.0, 0.0, 0.0)

    def scaled(self, k: float) -> "Lobes":
        return Lobes(*(value * k for value in vars(self).values()))

    def __add__(self, other: "Lobes") -> "Lobes":
        return Lobes(*(a + b for a, b in zip(vars(self).values(), vars(other).values())))

    @classmethod
    def glossy(cls, f0, f90, roughness: float) -> "Lobes":
        lobes = cls.none()
        lobes.f0, lobes.f90 = np.asarray(f0, float), np.asarray(f90, float)
        lobes.gloss_weight = float(np.mean(f90))
        lobes.roughness_sum = lobes.gloss_weight * roughness
        return lobes

    @classmethod
    def refraction(cls, colour, ior: float, fresnel: float) -> "Lobes":
        lobes = cls.none()
        lobes.transmission = np.asarray(colour, float)
        lobes.refraction_weight = float(np.mean(colour))
        lobes.ior_sum = lobes.refraction_weight * ior
        lobes.fresnel_sum = lobes.refraction_weight * fresnel
        return lobes

    def beyond_limit(self) -> list[str]:
        """The colour lobes past MAX_COLOUR (a colour x a strength, a sum of shaders), which
        ``material`` clamps."""
        return [name for name in ("diffuse", "f0", "f90", "transmission", "emission",
                                  "transparency", "translucency")
                if np.max(getattr(self, name)) > MAX_COLOUR]

    def material(self) -> SurfaceMaterial:
        positive = lambda v: tuple(float(c) for c in np.clip(v, 0.0, MAX_COLOUR))  # noqa: E731
        roughness = self.roughness_sum / self.gloss_weight if self.gloss_weight > 0 else 0.5
        ior = self.ior_sum / self.refraction_weight if self.refraction_weight > 0 else 1.5
        fresnel = (self.fresnel_sum / self.refraction_weight if self.refraction_weight > 0
                   else 1.0)
        diffuse_weight = float(np.mean(np.maximum(self.diffuse, 0.0)))
        layer = self.layered_sum / diffuse_weight if diffuse_weight > 0 else 0.0
        layer_f0 = self.layer_f0_sum / self.layered_sum if self.layered_sum > 0 else 0.0
        rise = float(np.mean(np.maximum(self.f90 - self.f0, 0.0)))
        dielectric = self.dielectric_sum / rise if rise > 0 else 0.0
        specular_ior = (self.specular_ior_sum / self.dielectric_sum if self.dielectric_sum > 0
                        else 1.5)
        return SurfaceMaterial(
            diffuse=positive(self.diffuse), layer=float(np.clip(layer, 0, 1)),
            layer_f0=float(np.clip(layer_f0, 0, 1)), specular_f0=positive(self.f0),
            specular_dielectric=float(np.clip(dielectric, 0, 1)),
            specular_ior=max(float(specular_ior), 1.0),
            specular_f90=positive(self.f90), roughness=float(np.clip(roughness, 0, 1)),
            transmission=positive(self.transmission),
            transmission_fresnel=float(np.clip(fresnel, 0, 1)), ior=max(float(ior), 1e-3),
            emission=positive(self.emission), transparency=positive(self.transparency),
            translucency=positive(self.translucency),
            holdout=float(np.clip(self.holdout, 0, 1)))


def _principled_lobes(values: dict) -> Lobes:
    """Lobes of Blender's Principled BSDF (``SurfaceMaterial.principled``'s model)."""
    base = np.asarray(values["base"], float)
    m = float(np.clip(values["metallic"], 0, 1))
    t = float(np.clip(values["transmission"], 0, 1))
    a = float(np.clip(values["alpha"], 0, 1))
    ior = max(float(values["ior"]), 1e-3)
    level = max(float(values["specular"]), 0.0)
    tint = np.asarray(values["tint"], float)
    roughness = float(np.clip(values["roughness"], 0, 1))
    f0_dielectric = min(1.0, dielectric_f0(ior) * 2.0 * level)
    dielectric = (1.0 - m) * a
    lobes = Lobes.glossy(dielectric * f0_dielectric * tint + m * a * base,
                         dielectric * min(1.0, 2.0 * level) * tint + m * a * np.ones(3),
                         roughness)
    lobes.diffuse = dielectric * (1.0 - t) * (1.0 - f0_dielectric) * base
    if f0_dielectric > 0:  # the diffuse lies under the specular layer (``SurfaceMaterial``)
        lobes.layered_sum = float(np.mean(lobes.diffuse))
        lobes.layer_f0_sum = lobes.layered_sum * min(1.0, f0_dielectric * float(np.max(tint)))
    share, specular_ior = principled_fresnel(base, tint, m, a, level, f0_dielectric)
    lobes.dielectric_sum = share * float(np.mean(np.maximum(lobes.f90 - lobes.f0, 0.0)))
    lobes.specular_ior_sum = lobes.dielectric_sum * specular_ior
    if t > 0:
        refraction = Lobes.refraction(dielectric * t * base, ior, 1.0)
        lobes = lobes + refraction
    lobes.emission = np.asarray(values["emission"], float)
    lobes.transparency = np.full(3, 1.0 - a)
    return lobes


#: Nodes whose value passes straight through (their first input of the socket's kind).
_PASS_THROUGH = {"NodeReroute"}


def layer_average(exponent: float) -> float:
    """Cosine-weighted mean of (1 - |N.V|)^k over a hemisphere: 2 / ((k + 1)(k + 2)), how a
    Fresnel or Layer Weight factor, which varies over a surface, is approximated by one
    constant (a sphere seen from afar shows the camera each cosine with that weight)."""
    return 2.0 / ((exponent + 1.0) * (exponent + 2.0))


def fresnel_average(ior: float) -> float:
    """Mean of Schlick's F over a cosine-weighted hemisphere: f0 + (1 - f0) / 21."""
    f0 = dielectric_f0(max(ior, 1e-3))
    return f0 + (1.0 - f0) * layer_average(5.0)


class NodeEvaluator:
    """Evaluates a material's node tree into Lobes, following links through reroutes and
    node groups; what it cannot evaluate gets its socket's own value (a texture: its image's
    average) and one note naming the node.

    A value that is NaN counts as 0, one that is infinite or past MAX_COLOUR in size as
    +-MAX_COLOUR, each with a note naming the socket (``usable``): Cycles renders a NaN input
    as the low end of the input's range (measured: a NaN channel of a Base Color or a
    Diffuse BSDF's Color, a NaN Metallic, Emission Strength or world colour channel add
    nothing; a NaN IOR reflects as an IOR near 0 does, as Glint's floor of 1e-3 does; a NaN
    Alpha: ``shader``), and an infinite one as infinite pixels, which Glint cannot write."""

    def __init__(self, owner: str, user: str = ""):
        self.owner = owner
        self.user = user   # "object 'name', " for the notes about values, or ""
        self.notes: list[str] = []

    def note(self, text: Optional[str]) -> None:
        if text and text not in self.notes:
            self.notes.append(text)

    def usable(self, value, socket, nan: float = 0.0):
        """``value`` (a float or an RGB array) read from ``socket``, NaN counted as ``nan``
        (itself NaN: left for the caller to handle) and what is infinite or past MAX_COLOUR
        in size clamped to +-MAX_COLOUR, with a note naming the socket and its node."""
        fixed = counted(value, nan)
        if fixed is None:
            return value
        if not np.isnan(fixed).any():
            self.note(f"{self.user}{self.owner}: '{socket.name}' of '{socket.node.name}' is "
                      f"{value_text(as_stored(value))}: it counts as "
                      f"{value_text(as_stored(fixed))}")
        return fixed

    # --- following links ------------------------------------------------------------------

    def source(self, socket, groups):
        """What feeds an input socket, through reroutes, muted nodes and node groups:
        (output socket, group stack) of the node that computes it, or (None, the unlinked
        input socket whose own value it takes; inside a group that is the group node's)."""
        for _ in range(256):
            if not socket.is_linked:
                return None, socket
            link = socket.links[0]
            if not link.is_valid or link.is_muted:
                return None, socket
            node, output = link.from_node, link.from_socket
            if node.bl_idname in _PASS_THROUGH or (node.mute and node.inputs):
                inputs = [i for i in node.inputs if i.type == output.type] or list(node.inputs)
                socket = inputs[0]
                continue
            if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
                outputs = [n for n in node.node_tree.nodes if n.bl_idname == "NodeGroupOutput"]
                active = [n for n in outputs if n.is_active_output] or outputs
                inner = active[0].inputs.get(output.name) if active else None
                if inner is None:
                    return None, socket
                groups = groups + (node,)
                socket = inner
                continue
            if node.bl_idname == "NodeGroupInput" and groups:
                outer = groups[-1].inputs.get(output.name)
                if outer is None:
                    return None, socket
                groups = groups[:-1]
                socket = outer
                continue
            return output, groups
        return None, socket

    def _math(self, node, groups):
        """A Math node of constant inputs, or None for operations not evaluated."""
        a, b = (self.value(node.inputs[i], groups) for i in (0, 1))
        operations = {
            "ADD": lambda: a + b, "SUBTRACT": lambda: a - b, "MULTIPLY": lambda: a * b,
            "DIVIDE": lambda: a / b if b else 0.0, "MINIMUM": lambda: min(a, b),
            "MAXIMUM": lambda: max(a, b), "ABSOLUTE": lambda: abs(a),
            "POWER": lambda: a ** b if a > 0 or float(b).is_integer() else 0.0,
            "SQRT": lambda: math.sqrt(a) if a > 0 else 0.0,
        }
        if node.operation not in operations:
            return None
        try:
            result = float(operations[node.operation]())
        except OverflowError:
            result = math.inf
        return min(max(result, 0.0), 1.0) if node.use_clamp else result

    def value(self, socket, groups=(), nan: float = 0.0) -> float:
        """A float input's value; NaN counts as ``nan`` (``usable``)."""
        output, groups = self.source(socket, groups)
        if output is None:
            return self.usable(float(groups.default_value), groups, nan)
        node = output.node
        if node.bl_idname == "ShaderNodeMath":
            result = self._math(node, groups)
            if result is not None:
                return self.usable(result, output, nan)
        if node.bl_idname == "ShaderNodeValue":
            return self.usable(float(output.default_value), output, nan)
        if node.bl_idname == "ShaderNodeFresnel":
            return fresnel_average(self.value(node.inputs["IOR"], groups))
        if node.bl_idname == "ShaderNodeLayerWeight":
            blend = float(np.clip(self.value(node.inputs["Blend"], groups), 0, 1 - 1e-5))
            if output.name == "Fresnel":
                return fresnel_average(1.0 / (1.0 - blend))
            exponent = 2 * blend if blend < 0.5 else 0.5 / (1 - blend)
            return layer_average(exponent)
        colour = self._node_colour(output, groups)
        if colour is not None:
            return float(np.dot(colour, (0.2126, 0.7152, 0.0722)))
        self.note(f"{self.owner}: node '{node.name}' ({node.bl_label}) is not evaluated; "
                  f"'{socket.name}' uses its own value")
        return self.usable(float(socket.default_value), socket, nan)

    def colour(self, socket, groups=()) -> np.ndarray:
        outer = groups
        output, groups = self.source(socket, groups)
        if output is None:
            return self.usable(np.asarray(groups.default_value[:3], float), groups)
        colour = self._node_colour(output, groups)
        if colour is not None:
            return colour
        node = output.node
        if output.type == 'VALUE':
            return np.full(3, self.value(socket, outer))
        self.note(f"{self.owner}: node '{node.name}' ({node.bl_label}) is not evaluated; "
                  f"'{socket.name}' uses its own value")
        return self.usable(np.asarray(socket.default_value[:3], float), socket)

    def _node_colour(self, output, groups):
        node = output.node
        if node.bl_idname == "ShaderNodeRGB":
            return self.usable(np.asarray(output.default_value[:3], float), output)
        if node.bl_idname == "ShaderNodeValue":
            return np.full(3, self.usable(float(output.default_value), output))
        if node.bl_idname in ("ShaderNodeTexImage", "ShaderNodeTexEnvironment"):
            average = image_average(node.image)
            if average is None:
                return None
            self.note(f"{self.owner}: texture '{node.name}' counts as its image's average "
                      f"colour")
            average = self.usable(average, output)
            return average if output.name == "Color" else np.full(3, average.mean())
        return None

    # --- shaders --------------------------------------------------------------------------

    def shader(self, socket, groups=()) -> Lobes:
        output, groups = self.source(socket, groups)
        if output is None:
            return Lobes.none()
        node = output.node
        kind = node.bl_idname
        colour = lambda name: self.colour(node.inputs[name], groups)  # noqa: E731
        value = lambda name: self.value(node.inputs[name], groups)  # noqa: E731
        if kind == "ShaderNodeBsdfPrincipled":
            alpha = self.value(node.inputs["Alpha"], groups, nan=math.nan)
            if math.isnan(alpha):
                # Measured: Cycles renders a Principled BSDF of NaN Alpha black and opaque.
                self.note(f"{self.user}{self.owner}: 'Alpha' of '{node.name}' is nan: the "
                          f"Principled BSDF renders black and opaque, as in Cycles")
                return Lobes.none()
            for name in ("Coat Weight", "Sheen Weight"):
                if name in node.inputs and value(name) > 0:
                    self.note(f"{self.owner}: Principled '{node.name}': {name} is not "
                              f"modelled")
            return _principled_lobes(dict(
                base=colour("Base Color"), metallic=value("Metallic"),
                roughness=value("Roughness"), ior=value("IOR"), alpha=alpha,
                specular=value("Specular IOR Level"), tint=colour("Specular Tint"),
                transmission=value("Transmission Weight"),
                emission=colour("Emission Color") * value("Emission Strength")))
        if kind == "ShaderNodeBsdfTranslucent":
            lobes = Lobes.none()
            lobes.translucency = colour("Color")
            return lobes
        if kind in ("ShaderNodeBsdfDiffuse",
                    "ShaderNodeSubsurfaceScattering", "ShaderNodeBsdfToon",
                    "ShaderNodeBsdfSheen", "ShaderNodeBsdfVelvet"):
            if kind != "ShaderNodeBsdfDiffuse":
                self.note(f"{self.owner}: {node.bl_label} '{node.name}' is approximated by a "
                          f"Diffuse BSDF of its colour")
            lobes = Lobes.none()
            lobes.diffuse = colour("Color")
            return lobes
        if kind in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"):
            tint = colour("Color")
            return Lobes.glossy(tint, tint, value("Roughness"))
        if kind == "ShaderNodeBsdfGlass":
            tint, ior = colour("Color"), value("IOR")
            return (Lobes.glossy(tint * dielectric_f0(max(ior, 1e-3)), tint, value("Roughness"))
                    + Lobes.refraction(tint, ior, 1.0))
        if kind == "ShaderNodeBsdfRefraction":
            return Lobes.refraction(colour("Color"), value("IOR"), 0.0)
        if kind == "ShaderNodeBsdfTransparent":
            lobes = Lobes.none()
            lobes.transparency = colour("Color")
            return lobes
        if kind in ("ShaderNodeEmission", "ShaderNodeBackground"):
            lobes = Lobes.none()
            lobes.emission = colour("Color") * value("Strength")
            return lobes
        if kind == "ShaderNodeHoldout":
            lobes = Lobes.none()
            lobes.holdout = 1.0
            return lobes
        if kind == "ShaderNodeMixShader":
            factor = float(np.clip(self.value(node.inputs[0], groups), 0, 1))
            return (self.shader(node.inputs[1], groups).scaled(1 - factor)
                    + self.shader(node.inputs[2], groups).scaled(factor))
        if kind == "ShaderNodeAddShader":
            return self.shader(node.inputs[0], groups) + self.shader(node.inputs[1], groups)
        if kind == "NodeUndefined":
            # A node of an add-on that is not installed (another engine's shader): Cycles
            # renders the surface black, and so does Glint.
            self.note(f"{self.owner}: node '{node.name}' is undefined (an add-on's that is "
                      f"not installed); the surface renders black, as in Cycles")
            return Lobes.none()
        self.note(f"{self.owner}: shader node '{node.name}' ({node.bl_label}) is not "
                  f"supported; it renders as Blender's default grey diffuse")
        lobes = Lobes.none()
        lobes.diffuse = np.full(3, 0.8)
        return lobes


def image_average(image):
    """The mean scene-linear RGB (3,) of an image's pixels, or None if it has none loaded.
    Byte images in an sRGB colour space are linearised per pixel before averaging."""
    if image is None:
        return None
    try:
        width, height = image.size
        if width * height == 0:
            return None
        pixels = np.empty(width * height * image.channels, np.float32)
        image.pixels.foreach_get(pixels)
    except (RuntimeError, ValueError):
        return None
    rgb = pixels.reshape(-1, image.channels)[:, :3].astype(np.float64)
    if image.channels < 3:
        rgb = np.repeat(pixels.reshape(-1, image.channels)[:, :1], 3, axis=1)
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        rgb = srgb_to_linear(rgb)
    return rgb.mean(axis=0)


def surface_socket(tree):
    """The Surface input of the active Material Output (Cycles' or All), or None."""
    if tree is None:
        return None
    output = tree.get_output_node('CYCLES') or tree.get_output_node('ALL')
    return None if output is None else output.inputs.get("Surface")


def _viewport_display(material, where: str) -> tuple[SurfaceMaterial, Optional[str]]:
    values, note = usable_values(SurfaceValues(
        base_colour=tuple(material.diffuse_color[:3]), metallic=material.metallic,
        roughness=material.roughness, specular_level=0.5), where)
    return SurfaceMaterial.principled(
        base_color=tuple(max(c, 0.0) for c in values.base_colour),
        metallic=min(max(values.metallic, 0.0), 1.0),
        roughness=min(max(values.roughness, 0.0), 1.0)), note


def export_material(material, owner: str = "") -> tuple[SurfaceMaterial | Material,
                                                        Optional[str]]:
    """(core material, note or None) for a bpy Material or None, default semantics; owner:
    the object using it, named in notes about invalid values.

    None gets Blender's default surface (a default Principled BSDF).  The Glint section with
    "Custom" on gives the article's Material as typed.  A material without a node tree uses
    its Viewport Display colour, metallic and roughness; one whose tree has no Material
    Output for Cycles (another engine's, say) or nothing plugged into its Surface renders
    black, as in Cycles, with a note."""
    if material is None:
        return SurfaceMaterial.principled(), None
    where = _where(material, owner)
    custom, custom_note = usable_custom_material(material, where)
    if custom is not None:
        return custom, None
    if material.node_tree is None:
        surface_material, note = _viewport_display(material, where)
        return surface_material, ("; ".join(filter(None, (custom_note, note))) or None)
    surface = surface_socket(material.node_tree)
    if surface is None or not surface.is_linked:
        return Lobes.none().material(), "; ".join(filter(None, (
            custom_note, f"material '{material.name}': no shader reaches a Cycles Material "
                         f"Output; it renders black, as in Cycles")))
    evaluator = NodeEvaluator(f"material '{material.name}'",
                              f"object '{owner}', " if owner else "")
    evaluator.note(custom_note)
    lobes = evaluator.shader(surface)
    beyond = lobes.beyond_limit()
    if beyond:
        evaluator.note(f"{where}: {', '.join(beyond)} past {MAX_COLOUR:g} is clamped to it "
                       f"(Cycles' pixels are as blown out)")
    return lobes.material(), ("; ".join(evaluator.notes) or None)
