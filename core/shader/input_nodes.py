"""Blender's input nodes over arrays of shading points, as Cycles evaluates them
(intern/cycles/kernel/svm: value.h, fresnel.h, geometry.h, tex_coord.h, attribute.h,
light_path.h): Value and RGB (constants of the material), and the per-hit Fresnel, Layer
Weight, Geometry, Texture Coordinate, Object Info, Attribute and Light Path.

Per-hit data beyond ``ShadingPoints``' attributes is read by name from its coordinates
(``ShadingPoints``' docstring lists the names); where the integrator gives none, a node
takes the value Cycles has for such a hit (``point_data``).
"""

from __future__ import annotations

import numpy as np

from ..vectors import dot
from . import point_data
from .point_data import ObjectFrame
from .registry import COLOR, FLOAT, VECTOR, node


def _array(value):
    value = np.asarray(value)
    return value if value.dtype.kind == "f" else value.astype(np.float64)


@node("ShaderNodeValue", outputs=(("Value", FLOAT),), options=("value",))
def value(points, *, value=0.5):
    return (np.asarray(value, points.dtype),)


@node("ShaderNodeRGB", outputs=(("Color", COLOR),), options=("color",))
def rgb(points, *, color=(0.5, 0.5, 0.5)):
    return (np.asarray(color[:3], points.dtype).reshape(3, 1),)


# --- Fresnel, Layer Weight ---------------------------------------------------------------------

def fresnel_dielectric_cos(cosine, eta):
    """Unpolarised Fresnel reflectance at a dielectric boundary of relative index eta for the
    cosine of the incident angle (either side of the normal); 1 under total internal
    reflection (Cycles' ``fresnel_dielectric_cos``)."""
    c = np.abs(cosine)
    g2 = eta * eta - 1 + c * c
    refracts = g2 > 0
    g = np.sqrt(np.where(refracts, g2, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1) / (c * (g - c) + 1)
        reflectance = 0.5 * a * a * (1 + b * b)
    return np.where(refracts, reflectance, 1)


@node("ShaderNodeFresnel", inputs=(("IOR", FLOAT), ("Normal", VECTOR)),
      outputs=(("Fac", FLOAT),), implicit={"Normal": "normal"}, reads_points=True)
def fresnel(points, ior, normal):
    """Seen from behind the surface (a backfacing hit) the index is inverted."""
    eta = np.maximum(_array(ior), 1e-5)
    eta = np.where(points.backfacing, 1 / eta, eta)
    return (fresnel_dielectric_cos(dot(points.incoming, _array(normal)), eta),)


@node("ShaderNodeLayerWeight", inputs=(("Blend", FLOAT), ("Normal", VECTOR)),
      outputs=(("Fresnel", FLOAT), ("Facing", FLOAT)), implicit={"Normal": "normal"}, reads_points=True)
def layer_weight(points, blend, normal):
    blend = _array(blend)
    cosine = dot(points.incoming, _array(normal))
    eta = np.maximum(1 - blend, 1e-5)
    eta = np.where(points.backfacing, eta, 1 / eta)
    fresnel_weight = fresnel_dielectric_cos(cosine, eta)
    exponent = np.clip(blend, 0, 1 - 1e-5)
    exponent = np.where(exponent < 0.5, 2 * exponent, 0.5 / (1 - exponent))
    facing = np.abs(cosine)
    with np.errstate(divide="ignore", invalid="ignore"):
        facing = np.where(blend != 0.5, np.power(facing, exponent), facing)
    return fresnel_weight, 1 - facing


# --- Geometry, Texture Coordinate ---------------------------------------------------------------

#: Cycles' Pointiness of a mesh where it is flat (and of anything it was not computed for).
FLAT_POINTINESS = 0.5


@node("ShaderNodeNewGeometry",
      outputs=(("Position", VECTOR), ("Normal", VECTOR), ("Tangent", VECTOR),
               ("True Normal", VECTOR), ("Incoming", VECTOR), ("Parametric", VECTOR),
               ("Backfacing", FLOAT), ("Pointiness", FLOAT), ("Random Per Island", FLOAT)), reads_points=True)
def geometry(points):
    """Tangent, Parametric, Pointiness and Random Per Island come from the integrator
    ('tangent', 'parametric', 'pointiness', 'random_per_island'); without them they are
    zero, zero, 0.5 (a flat surface) and 0."""
    return (points.position, points.normal, point_data.vector(points, "tangent"),
            points.true_normal, points.incoming, point_data.vector(points, "parametric"),
            points.backfacing.astype(points.dtype),
            point_data.scalar(points, "pointiness", FLAT_POINTINESS),
            point_data.scalar(points, "random_per_island"))


def _affine(matrix, position):
    m = np.asarray(matrix, np.float64).reshape(3, 4).astype(position.dtype)
    return np.tensordot(m[:, :3], position, axes=1) + m[:, 3].reshape(3, 1)


@node("ShaderNodeTexCoord",
      outputs=(("Generated", VECTOR), ("Normal", VECTOR), ("UV", VECTOR), ("Object", VECTOR),
               ("Camera", VECTOR), ("Window", VECTOR), ("Reflection", VECTOR)),
      options=("object_matrix", "from_instancer"), reads_points=True)
def texture_coordinate(points, *, object_matrix=None, from_instancer=False):
    """Generated, UV, Object, Camera and Window are the integrator's coordinates of those
    names ('instancer_generated' and 'instancer_uv' with ``from_instancer``); Object with a
    chosen object is the position through ``object_matrix`` (that object's world -> local
    3 x 4 matrix, row-major); Normal is the shading normal in object space and Reflection
    the incoming direction mirrored about the normal (world space), as Cycles computes them."""
    prefix = "instancer_" if from_instancer else ""
    generated = points.coordinate(prefix + "generated")
    uv = points.coordinate(prefix + "uv")
    if object_matrix is not None:
        object_coordinates = _affine(object_matrix, points.position)
    else:
        object_coordinates = points.coordinate("object")
    normal = ObjectFrame(points).to_object(points.normal, "NORMAL")
    reflection = 2 * dot(points.normal, points.incoming) * points.normal - points.incoming
    return (generated, normal, uv, object_coordinates, points.coordinate("camera"),
            points.coordinate("window"), reflection)


# --- Object Info, Attribute -------------------------------------------------------------------

@node("ShaderNodeObjectInfo",
      outputs=(("Location", VECTOR), ("Color", COLOR), ("Alpha", FLOAT),
               ("Object Index", FLOAT), ("Material Index", FLOAT), ("Random", FLOAT)), reads_points=True)
def object_info(points):
    """From the integrator's 'object_location', 'object_color', 'object_alpha',
    'object_index', 'material_index' and 'object_random'; without them: the origin, white,
    1, 0, 0 and 0 (an object's defaults in Blender)."""
    return (point_data.vector(points, "object_location"),
            point_data.vector(points, "object_color", (1.0, 1.0, 1.0)),
            point_data.scalar(points, "object_alpha", 1.0),
            point_data.scalar(points, "object_index"),
            point_data.scalar(points, "material_index"),
            point_data.scalar(points, "object_random"))


#: The coordinates of a mesh's attribute of a name (its value, its alpha), and of its render
#: colour attribute (a Vertex Color node without a name), as the integrator gives them.
ATTRIBUTE_PREFIX = "attribute:"
ATTRIBUTE_ALPHA_PREFIX = "attribute_alpha:"
RENDER_COLOR = "render_color"
RENDER_COLOR_ALPHA = "render_color_alpha"

#: The coordinate-name prefix of each Attribute node type.
ATTRIBUTE_PREFIXES = {"GEOMETRY": "attribute", "OBJECT": "object_attribute",
                      "INSTANCER": "instancer_attribute", "VIEW_LAYER": "view_layer_attribute"}


@node("ShaderNodeAttribute",
      outputs=(("Color", COLOR), ("Vector", VECTOR), ("Fac", FLOAT), ("Alpha", FLOAT)),
      options=("attribute_type", "attribute_name"), reads_points=True)
def attribute(points, *, attribute_type="GEOMETRY", attribute_name=""):
    """The integrator's coordinate '<prefix>:<name>' (prefix by type: ``ATTRIBUTE_PREFIXES``)
    as Color and Vector, its channel mean as Fac (Cycles' float of a vector attribute: a
    float attribute given as (f, f, f) reads back f) and '<prefix>_alpha:<name>' as Alpha.
    An attribute the integrator does not have reads as zero, as in Cycles, with Alpha 1 for
    a geometry attribute and 0 for the others (Cycles' values, seen in renders)."""
    try:
        prefix = ATTRIBUTE_PREFIXES[attribute_type]
    except KeyError:
        raise ValueError(f"Attribute: unknown attribute_type {attribute_type!r}") from None
    name = f"{prefix}:{attribute_name}"
    data = points.coordinate(name)
    known = attribute_type == "GEOMETRY" or point_data.provided(points, name)
    alpha = point_data.scalar(points, f"{prefix}_alpha:{attribute_name}", 1.0 if known else 0.0)
    return data, data, (data[0] + data[1] + data[2]) * (1 / 3), alpha


@node("ShaderNodeVertexColor", outputs=(("Color", COLOR), ("Alpha", FLOAT)),
      options=("layer_name",), reads_points=True)
def vertex_color(points, *, layer_name=""):
    """A colour attribute of the mesh by name, or its render colour attribute where the name
    is empty (``RENDER_COLOR``), and its alpha; black with alpha 0 where the mesh has none,
    as Cycles renders a missing one."""
    value, alpha = ((ATTRIBUTE_PREFIX + layer_name, ATTRIBUTE_ALPHA_PREFIX + layer_name)
                    if layer_name else (RENDER_COLOR, RENDER_COLOR_ALPHA))
    known = point_data.provided(points, value)
    return (points.coordinate(value),
            point_data.scalar(points, alpha, 1.0) if known else np.zeros((), points.dtype))


@node("ShaderNodeUVMap", outputs=(("UV", VECTOR),), options=("uv_map", "from_instancer"),
      reads_points=True)
def uv_map(points, *, uv_map="", from_instancer=False):
    """The UV map of that name ('uv:<name>'), or the render map where the name is empty."""
    prefix = "instancer_" if from_instancer else ""
    return (points.coordinate(f"{prefix}uv:{uv_map}" if uv_map else f"{prefix}uv"),)


@node("ShaderNodeTangent", outputs=(("Tangent", VECTOR),),
      options=("direction_type", "axis", "uv_map"), reads_points=True)
def tangent(points, *, direction_type="RADIAL", axis="Z", uv_map=""):
    """Cycles' ``svm_node_tangent``: the UV map's tangent ('tangent:<map>'; zero where the
    mesh has none), or the direction around the object's ``axis`` through the Generated
    coordinate's centre, taken to the world; then made perpendicular to the normal."""
    if direction_type == "UV_MAP":
        name = f"tangent:{uv_map}" if uv_map else "tangent"
        if not point_data.provided(points, name):
            return (np.zeros_like(points.position),)
        direction = points.coordinate(name)
    else:
        g = points.coordinate("generated") - 0.5
        zero = np.zeros_like(g[0])
        local = {"X": (zero, -g[2], g[1]), "Y": (-g[2], zero, g[0])}.get(
            axis, (-g[1], g[0], zero))
        direction = ObjectFrame(points).to_world(np.stack(local), "VECTOR")
    normal = points.normal
    side = np.cross(direction, normal, axis=0)
    length = np.sqrt(dot(side, side))
    side = side / np.where(length > 0, length, 1)
    return (np.cross(normal, side, axis=0),)


@node("ShaderNodeAmbientOcclusion", inputs=(("Color", COLOR), ("Distance", FLOAT),
                                            ("Normal", VECTOR)),
      outputs=(("Color", COLOR), ("AO", FLOAT)), options=("samples", "inside", "only_local"),
      stand_in=True,
      note="a stand-in: Color passes through and AO is 1 (nothing occluded); Glint traces "
           "no rays from shaders")
def ambient_occlusion(points, colour, distance, normal, *, samples=16, inside=False,
                      only_local=False):
    return colour, np.ones((), points.dtype)


@node("ShaderNodeBevel", inputs=(("Radius", FLOAT), ("Normal", VECTOR)),
      outputs=(("Normal", VECTOR),), options=("samples",), implicit={"Normal": "normal"},
      reads_points=True, stand_in=True,
      note="a stand-in: the normal unbevelled (Glint traces no rays from shaders)")
def bevel(points, radius, normal, *, samples=4):
    return (np.broadcast_to(normal, points.position.shape).astype(points.dtype),)


# --- Light Path ----------------------------------------------------------------------------------

#: Bits of the per-hit ray type code (coordinate 'ray_type', component 0) the integrator
#: sets for the ray that reached each hit, as Cycles' PATH_RAY_* flags.
RAY_CAMERA = 1
RAY_REFLECT = 2
RAY_TRANSMIT = 4
RAY_DIFFUSE = 8
RAY_GLOSSY = 16
RAY_SINGULAR = 32
RAY_TRANSPARENT = 64
RAY_VOLUME_SCATTER = 128
RAY_SHADOW = 256

_RAY_FLAGS = (RAY_CAMERA, RAY_SHADOW, RAY_DIFFUSE, RAY_GLOSSY, RAY_SINGULAR, RAY_REFLECT,
              RAY_TRANSMIT, RAY_VOLUME_SCATTER)
_DEPTHS = ("ray_depth", "diffuse_depth", "glossy_depth", "transparent_depth",
           "transmission_depth", "portal_depth")


@node("ShaderNodeLightPath",
      outputs=(("Is Camera Ray", FLOAT), ("Is Shadow Ray", FLOAT), ("Is Diffuse Ray", FLOAT),
               ("Is Glossy Ray", FLOAT), ("Is Singular Ray", FLOAT),
               ("Is Reflection Ray", FLOAT), ("Is Transmission Ray", FLOAT),
               ("Is Volume Scatter Ray", FLOAT), ("Ray Length", FLOAT), ("Ray Depth", FLOAT),
               ("Diffuse Depth", FLOAT), ("Glossy Depth", FLOAT), ("Transparent Depth", FLOAT),
               ("Transmission Depth", FLOAT), ("Portal Depth", FLOAT)), reads_points=True)
def light_path(points):
    """The ray-type bits of coordinate 'ray_type' (``RAY_*``; a camera ray without it), and
    the integrator's 'ray_length' and depths ('ray_depth', 'diffuse_depth', 'glossy_depth',
    'transparent_depth', 'transmission_depth', 'portal_depth'; 0 without them)."""
    code = point_data.scalar(points, "ray_type", RAY_CAMERA).astype(np.int64)
    flags = tuple(((code & flag) != 0).astype(points.dtype) for flag in _RAY_FLAGS)
    depths = tuple(point_data.scalar(points, name) for name in _DEPTHS)
    return flags + (point_data.scalar(points, "ray_length"),) + depths


@node("ShaderNodeLightFalloff", inputs=(("Strength", FLOAT), ("Smooth", FLOAT)),
      outputs=(("Quadratic", FLOAT), ("Linear", FLOAT), ("Constant", FLOAT)),
      reads_points=True)
def light_falloff(points, strength, smooth):
    """Cycles' Light Falloff over the integrator's 'ray_length' (what an emitter's shader
    sees: the distance from the point it lights): Strength as is (quadratic: the light's
    own inverse square), times the length (linear), times its square (constant); a Smooth
    above 0 multiplies each by length^2 / (smooth + length^2)."""
    length = point_data.scalar(points, "ray_length")
    squared = length * length
    smooth = np.asarray(smooth, points.dtype)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        soft = np.where((smooth > 0) & np.isfinite(squared),
                        squared / np.where(smooth + squared > 0, smooth + squared, 1), 1)
    strength = strength * soft
    return strength, strength * length, strength * squared
