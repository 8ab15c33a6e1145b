"""Blender's Bump and Normal Map nodes over arrays of shading points.

Bump, as Cycles' ``svm_node_set_bump``: the height is evaluated at each point and at two
neighbours one ray footprint away along the surface (``ShadingPoints.shifted``: the height's
coordinates moved with them), and the normal tilted by the height's surface gradient.
Normal Map, as ``svm_node_normal_map``: a colour read as a direction in the UV map's tangent
space (its MikkTSpace tangents, exported per corner), in object or in world space."""

from __future__ import annotations

import numpy as np

from ..vectors import dot
from .point_data import ObjectFrame
from .program import run
from .registry import COLOR, FLOAT, VECTOR, node


def _cross(a, b):
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _tangents(normal):
    """Two orthogonal unit tangents (3, n) of unit normals (3, n)."""
    helper = np.where(np.abs(normal[0]) < 0.9, 1.0, 0.0).astype(normal.dtype)
    other = np.stack([helper, 1 - helper, np.zeros_like(helper)])
    first = _cross(normal, other)
    first /= np.sqrt(dot(first, first))
    return first, _cross(normal, first)


def _height(program, points):
    if program is None:
        return np.zeros(len(points), points.dtype)
    if not hasattr(program, "instructions"):
        return np.broadcast_to(np.asarray(program, points.dtype), (len(points),))
    return np.broadcast_to(run(program, points), (len(points),))


@node("ShaderNodeBump", inputs=(("Strength", FLOAT), ("Distance", FLOAT),
                                ("Filter Width", FLOAT), ("Normal", VECTOR)),
      outputs=(("Normal", VECTOR),), options=("invert", "height"),
      implicit={"Normal": "normal"}, reads_points=True,
      note="the neighbours' offsets are the ray's footprint times Filter Width")
def bump(points, strength, distance, filter_width, normal, *, invert=False, height=None):
    """Cycles' bump: dP = two tangents of the true normal times the footprint (times Filter
    Width), Rx = dPy x N, Ry = N x dPx, det = dPx . Rx, the gradient (h_x - h_c) Rx +
    (h_y - h_c) Ry, and N' = normalize(|det| N - distance sign(det) gradient), mixed with N
    by Strength."""
    normal = np.broadcast_to(normal, points.position.shape).astype(points.dtype)
    if height is None or not hasattr(height, "instructions"):
        return (normal,)
    return (_bumped(points, normal, lambda at: _height(height, at), strength,
                    -distance if invert else distance, filter_width),)


def _bumped(points, normal, height_at, strength, distance, filter_width):
    """The normal (3, n) tilted by the gradient of ``height_at(points)`` (``bump``)."""
    width = np.maximum(points.footprint * np.maximum(filter_width, 0), 1e-6)
    first, second = _tangents(points.true_normal)
    dx, dy = first * width, second * width
    h_c = height_at(points)
    h_x = height_at(points.shifted(dx))
    h_y = height_at(points.shifted(dy))
    rx, ry = _cross(dy, normal), _cross(normal, dx)
    det = dot(dx, rx)
    gradient = (h_x - h_c) * rx + (h_y - h_c) * ry
    out = np.abs(det) * normal - distance * np.sign(det) * gradient
    length = np.sqrt(dot(out, out))
    out = np.where(length > 0, out / np.where(length > 0, length, 1), normal)
    strength = np.maximum(strength, 0)
    mixed = strength * out + (1 - strength) * normal
    mixed /= np.sqrt(dot(mixed, mixed))
    # (The glossy lobes raise a normal that would mirror the view below the surface:
    # ``core.closures.with_specular_normal``, as Cycles' closures do, not the node.)
    return mixed


@node("ShaderNodeDisplacement", inputs=(("Height", FLOAT), ("Midlevel", FLOAT),
                                        ("Scale", FLOAT), ("Normal", VECTOR)),
      outputs=(("Displacement", VECTOR),), options=("space",),
      implicit={"Normal": "normal"}, reads_points=True,
      note="into a material output, rendered as bump (Cycles' Bump Only method; the surface "
           "is not moved); at sharp steps of height the neighbours' offsets differ from "
           "Cycles' ray differentials (a Wave's bands: 2-5 % per pixel)")
def displacement(points, height, midlevel, scale, normal, *, space="OBJECT"):
    """Cycles' ``svm_node_displacement``: the normal times (Height - Midlevel) x Scale, in
    object space (the normal taken to the object, the offset back to the world, so the
    object's scale scales it) or in world space."""
    normal = np.broadcast_to(normal, points.position.shape).astype(points.dtype)
    amount = (np.asarray(height) - midlevel) * scale
    if space == "OBJECT":
        frame = ObjectFrame(points)
        return (frame.to_world(frame.to_object(normal, "NORMAL") * amount, "VECTOR"),)
    return (normal * amount,)


#: Cycles' Bump node's Filter Width default, which the bump it makes from a material's
#: displacement keeps.
DISPLACEMENT_FILTER_WIDTH = 0.1


@node("GlintDisplacementBump", inputs=(("Normal", VECTOR),), outputs=(("Normal", VECTOR),),
      options=("displacement",), implicit={"Normal": "normal"}, reads_points=True)
def displacement_bump(points, normal, *, displacement=None):
    """A material output's Displacement as Cycles' Bump Only method renders it
    (``ShaderGraph::bump_from_displacement``): the height is the displacement vector's dot
    product with the normal, at the point and its two neighbours, and a bump of distance 1
    and strength 1 gives the normal every shader with an unlinked Normal uses."""
    normal = np.broadcast_to(normal, points.position.shape).astype(points.dtype)
    if displacement is None or not hasattr(displacement, "instructions"):
        return (normal,)

    def height_at(at):
        vector = np.broadcast_to(run(displacement, at), at.position.shape)
        return dot(vector, at.normal)

    return (_bumped(points, normal, height_at, 1.0, 1.0, DISPLACEMENT_FILTER_WIDTH),)


@node("ShaderNodeNormalMap", inputs=(("Strength", FLOAT), ("Color", COLOR)),
      outputs=(("Normal", VECTOR),), options=("space", "uv_map"), reads_points=True)
def normal_map(points, strength, colour, *, space="TANGENT", uv_map=""):
    """Cycles' ``svm_node_normal_map``: the colour's 2 c - 1 as a direction in tangent space
    (the UV map's MikkTSpace tangent, the bitangent sign x (N x T), the normal), object
    or world space; mixed with the shading normal by Strength.  Without tangents (a mesh
    without the UV map, a sphere) the normal is unchanged, as in Cycles."""
    c = 2 * (np.broadcast_to(colour, points.position.shape) - 0.5)
    normal = points.normal
    facing = np.where(points.backfacing, -1.0, 1.0).astype(points.dtype)
    outward = normal * facing
    if space == "TANGENT":
        name = f"tangent:{uv_map}" if uv_map else "tangent"
        tangent = points.coordinate(name)
        sign = points.coordinate(f"{name}_sign")[0]
        has = dot(tangent, tangent) > 0
        bitangent = sign * _cross(outward, tangent)
        mapped = c[0] * tangent + c[1] * bitangent + c[2] * outward
        mapped = np.where(has, mapped, outward)
    elif space in ("OBJECT", "BLENDER_OBJECT"):
        if space == "BLENDER_OBJECT":
            c = np.stack([c[0], c[1], -c[2]])   # Blender's object space flips Z
        axes = [points.coordinate(f"object_axis_{axis}") for axis in "xyz"]
        mapped = _object_normal(axes, c)
    else:
        if space == "BLENDER_WORLD":
            c = np.stack([c[0], c[1], -c[2]])
        mapped = c
    length = np.sqrt(dot(mapped, mapped))
    mapped = np.where(length > 0, mapped / np.where(length > 0, length, 1), outward) * facing
    strength = np.maximum(strength, 0)
    if np.any(strength != 1):
        mixed = normal + (mapped - normal) * strength
        length = np.sqrt(dot(mixed, mixed))
        mapped = np.where(length > 0, mixed / np.where(length > 0, length, 1), normal)
    return (mapped,)


def _object_normal(axes, n):
    """An object-space normal n (3, k) in world space, by the inverse transpose of the
    matrix whose columns are the object's world-space axes (3, k) each."""
    x, y, z = axes
    # The inverse transpose's columns are the cofactors: (y x z, z x x, x x y) / det.
    cx, cy, cz = _cross(y, z), _cross(z, x), _cross(x, y)
    return n[0] * cx + n[1] * cy + n[2] * cz
