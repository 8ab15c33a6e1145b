"""Image Texture and Environment Texture nodes against Cycles, per pixel.

Every Cycles render here shades each pixel once at its centre (1 sample, pixel filter 0.01
pixel wide) with an Emission shader of strength 1 fed by the texture, world black, and is
read back scene-linear from an OpenEXR.  Glint's side is what a compiled program does: the
add-on's option reader (``addon.export.node_options``) exports the node's image, and the
registered node function runs over the pixels' shading points, whose texture coordinates
come from the project's own camera rays (``core.camera.camera_rays``) hitting the object
analytically.  Images are made in the test (8-bit PNGs with ``core.png``, float EXRs with
``exr.write_exr``).

Tolerances (``close``): 1e-4 absolute + 1e-4 relative where both sides hold the same values
(bytes, float32; Cycles computes in float32 and its 0.01-pixel filter moves a sample by up to
0.005 pixel: measured at most 5e-6 here).  Colour spaces Cycles converts to half floats are
compared texel by texel (Closest): the same half inputs through two OCIO processors
(Blender's and Cycles') may round to neighbouring halves, one half step apart, 2^-10
relative: 2e-3 relative + 1e-4 (measured at most 9.8e-4).  (Interpolated, such texels can
differ by a step of the larger of two neighbours, which near a zero crossing is no bound on
the result.)
"""

from __future__ import annotations

import math
import os
import pickle
import tempfile

import bpy
import numpy as np
import pytest
from mathutils import Euler, Vector

from addon_support import empty_file, glint, ico_sphere_mesh, link
from glint.addon.compat import new_material, new_world  # noqa: E402
from exr import read_exr, write_exr

from glint.addon.export.camera import export_camera
from glint.addon.export.context import ExportContext
from glint.addon.export.images import ColourSpaces, frame_number
from glint.addon.export.node_options import OPTION_READERS
from glint.core.camera import camera_rays
from glint.core.png import encode_png
from glint.core.shader import images as core_images
from glint.core.shader.points import ShadingPoints
from glint.core.shader.registry import NODES

RES = 32
STUDIO_LIGHTS = os.path.join(bpy.utils.system_resource('DATAFILES'), "studiolights", "world")


# --------------------------------------------------------------------------------------------
# Scenes and renders.

@pytest.fixture
def folder():
    with tempfile.TemporaryDirectory() as path:
        yield path


def cycles_file(resolution: int = RES):
    """An empty file rendering with Cycles at one sample per pixel centre, world black."""
    scene = empty_file()
    scene.render.resolution_x = scene.render.resolution_y = resolution
    scene.render.engine = 'CYCLES'
    cycles = scene.cycles
    cycles.device = 'CPU'
    cycles.samples = 1
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = 0
    cycles.filter_width = 0.01
    cycles.seed = 1
    world = new_world("black")
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    return scene


def add_camera(location=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), ortho_scale=2.0,
               lens=None):
    """An orthographic camera (a perspective one with ``lens``) at ``location`` looking at
    ``target``, made the scene camera."""
    data = bpy.data.cameras.new("camera")
    if lens is None:
        data.type, data.ortho_scale = 'ORTHO', ortho_scale
    else:
        data.lens = lens
    camera = link(bpy.data.objects.new("camera", data))
    camera.location = location
    direction = Vector(target) - Vector(location)
    camera.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    bpy.context.scene.camera = camera
    return camera


def pixel_rays(dx=0.0, dy=0.0):
    """(origins (3, n), directions (3, n)) of the scene camera's rays through the pixel
    centres (moved by dx, dy pixels), row 0 at the top, from Glint's own camera."""
    scene = bpy.context.scene
    width, height = scene.render.resolution_x, scene.render.resolution_y
    ys, xs = np.mgrid[0:height, 0:width]
    camera = export_camera(bpy.context.evaluated_depsgraph_get())
    rays = camera_rays(camera, xs.ravel() + 0.5 + dx, ys.ravel() + 0.5 + dy)
    origins = np.broadcast_to(rays.origins, rays.directions.shape)
    return origins, rays.directions


def render_cycles() -> np.ndarray:
    """(H, W, 4) float32 scene-linear Cycles render, row 0 = top."""
    scene = bpy.context.scene
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.exr_codec = 'OPEN_EXR', '32', 'NONE'
    with tempfile.TemporaryDirectory() as folder:
        scene.render.filepath = os.path.join(folder, "cycles.exr")
        bpy.ops.render.render(write_still=True)
        planes = read_exr(scene.render.filepath)
    return np.stack([planes[channel] for channel in "RGBA"], axis=-1)


def emission_material(image, *, interpolation="Linear", extension="REPEAT",
                      projection="FLAT", blend=0.0, alpha_strength=False, vector=None):
    """A material: Image Texture -> Emission (strength 1, or the texture's Alpha with
    ``alpha_strength``) -> output; ``vector``: a Texture Coordinate output feeding the
    texture's Vector.  Returns (material, image node)."""
    material = new_material("textured")
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation, texture.extension = interpolation, extension
    texture.projection, texture.projection_blend = projection, blend
    emission = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(texture.outputs["Color"], emission.inputs["Color"])
    if alpha_strength:
        tree.links.new(texture.outputs["Alpha"], emission.inputs["Strength"])
    if vector is not None:
        coordinates = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coordinates.outputs[vector], texture.inputs["Vector"])
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material, texture


def uv_plane(material, uv0=(0.0, 0.0), uv1=(1.0, 1.0), cuts=1):
    """The square [-1, 1]^2 at z = 0 facing +Z, in cuts x cuts quads, its UVs running
    linearly from uv0 to uv1."""
    mesh = bpy.data.meshes.new("plane")
    steps = np.linspace(0.0, 1.0, cuts + 1)
    vertices = [(2 * x - 1, 2 * y - 1, 0.0) for y in steps for x in steps]
    faces = [(j * (cuts + 1) + i, j * (cuts + 1) + i + 1, (j + 1) * (cuts + 1) + i + 1,
              (j + 1) * (cuts + 1) + i) for j in range(cuts) for i in range(cuts)]
    mesh.from_pydata(vertices, [], faces)
    layer = mesh.uv_layers.new(name="UVMap")
    (u0, v0), (u1, v1) = uv0, uv1
    for loop in mesh.loops:
        x, y, _ = vertices[loop.vertex_index]
        layer.data[loop.index].uv = (u0 + (u1 - u0) * (x + 1) / 2, v0 + (v1 - v0) * (y + 1) / 2)
    mesh.materials.append(material)
    return link(bpy.data.objects.new("plane", mesh))


def plane_uvs(uv0=(0.0, 0.0), uv1=(1.0, 1.0)) -> np.ndarray:
    """(3, n) the ``uv_plane``'s UVs where the top-down ``add_camera`` rays hit it."""
    origins, directions = pixel_rays()
    hits = origins - directions * (origins[2] / directions[2])
    fraction = (hits[:2] + 1) / 2
    u = uv0[0] + (uv1[0] - uv0[0]) * fraction[0]
    v = uv0[1] + (uv1[1] - uv0[1]) * fraction[1]
    return np.stack([u, v, np.zeros_like(u)])


def points_for(position, normal=None, **sources) -> ShadingPoints:
    """ShadingPoints at (3, n) positions, with coordinates ``sources`` ({name: (3, n)})."""
    n = position.shape[1]
    normal = np.tile([[0.0], [0.0], [1.0]], n) if normal is None else normal
    return ShadingPoints(position, normal, normal, normal,
                         sources={name: (lambda value=value: value)
                                  for name, value in sources.items()})


def glint_node(node, points, vector=None):
    """(outputs, notes): what a compiled program computes for ``node`` over ``points``: the
    add-on's option reader exports its options, the registered function evaluates it (its
    unlinked Vector the registered implicit coordinate unless ``vector`` is given)."""
    spec = NODES[node.bl_idname]
    context = ExportContext.for_camera(None, judged_from=None)
    context.frame = bpy.context.scene.frame_current
    options = OPTION_READERS[node.bl_idname](node, context)
    if vector is None:
        vector = points.coordinate(spec.implicit["Vector"])
    return spec.function(points, vector, **options), context.notes


def glint_emission(node, points, vector=None, alpha_strength=False):
    """(H, W, 3) Glint's emission for the Cycles material's texture node, and the notes."""
    outputs, notes = glint_node(node, points, vector)
    colour = outputs[0] * outputs[1] if alpha_strength else outputs[0]
    scene = bpy.context.scene
    shape = (scene.render.resolution_y, scene.render.resolution_x, 3)
    return colour.T.reshape(shape), notes


def close(glint_image, cycles_image, relative=1e-4, absolute=1e-4, where=None):
    """Assert Glint's and Cycles' (H, W, 3) images agree within tolerance (module doc)."""
    cycles_image = cycles_image[..., :3]
    error = np.abs(glint_image - cycles_image)
    allowed = absolute + relative * np.abs(cycles_image)
    bad = error > allowed
    if where is not None:
        bad &= where[..., None]
    assert not bad.any(), (f"{bad.any(axis=-1).sum()} pixels differ, worst "
                           f"{error[bad].max():.3g} at {np.argwhere(bad)[0]}: Glint "
                           f"{glint_image[tuple(np.argwhere(bad)[0][:2])]}, Cycles "
                           f"{cycles_image[tuple(np.argwhere(bad)[0][:2])]}")


def save_png(folder, name, rgba8_top_first) -> str:
    path = os.path.join(folder, name)
    with open(path, "wb") as file:
        file.write(encode_png(np.ascontiguousarray(rgba8_top_first, np.uint8)))
    return path


def save_exr(folder, name, rgba_top_first) -> str:
    path = os.path.join(folder, name)
    write_exr(path, rgba_top_first)
    return path


def random_bytes(height, width, seed=1, alpha=False):
    rgba = np.random.default_rng(seed).integers(0, 256, (height, width, 4), dtype=np.uint8)
    if not alpha:
        rgba[..., 3] = 255
    return rgba


# --------------------------------------------------------------------------------------------
# The texel lookup against Blender's own pixels.

def test_closest_lookup_at_texel_centres_reads_blenders_pixels(folder):
    """At each texel's centre, Closest returns Image.pixels' value (bytes / 255 for a
    Non-Color byte image, the float buffer for an EXR): rows from the bottom, as Blender."""
    empty_file()
    byte_path = save_png(folder, "bytes.png", random_bytes(5, 7, alpha=True))
    float_path = save_exr(folder, "floats.exr",
                          np.random.default_rng(2).random((6, 3, 4), np.float32) * 4)
    for path, colour_space in ((byte_path, "Non-Color"), (float_path, "Linear Rec.709")):
        image = bpy.data.images.load(path)
        image.colorspace_settings.name = colour_space
        image.alpha_mode = 'CHANNEL_PACKED'   # no association: Image.pixels as stored
        width, height = image.size
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
        expected = pixels.reshape(height, width, 4)
        rows, columns = np.mgrid[0:height, 0:width]
        material, node = emission_material(image, interpolation="Closest")
        uv = np.stack([(columns.ravel() + 0.5) / width, (rows.ravel() + 0.5) / height,
                       np.zeros(width * height)])
        (colour, alpha), _ = glint_node(node, points_for(uv, uv=uv))
        assert np.allclose(colour.T, expected[..., :3].reshape(-1, 3), rtol=1e-6, atol=1e-7)
        assert np.allclose(alpha, expected[..., 3].ravel(), rtol=1e-6, atol=1e-7)


# --------------------------------------------------------------------------------------------
# Interpolation and extension.

#: UVs beyond [0, 1] on both axes (every extension's wrapping shows), chosen so that no pixel
#: centre lies within 0.1 texel of a texel edge of the 7 x 5 image (Closest is then exact).
WIDE_UV = ((-0.64, -0.6), (1.64, 1.53))


@pytest.mark.cycles
def test_wide_uvs_keep_clear_of_texel_edges():
    cycles_file()
    add_camera()
    uv = plane_uvs(*WIDE_UV)
    for coordinate, size in ((uv[0], 7), (uv[1], 5)):
        fraction = (coordinate * size) % 1
        assert np.min(np.minimum(fraction, 1 - fraction)) > 0.1


@pytest.mark.cycles
@pytest.mark.parametrize("interpolation", ["Closest", "Linear", "Cubic", "Smart"])
@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
def test_interpolation_and_extension_match_cycles(folder, interpolation, extension):
    """An 8-bit sRGB PNG on a plane whose UVs run past [0, 1]: every interpolation with every
    extension matches Cycles per pixel (sRGB decoded after interpolation, Cubic the B-spline,
    Smart the Cubic, Clip fading to black across the border)."""
    cycles_file()
    add_camera()
    path = save_png(folder, "texture.png", random_bytes(5, 7))
    material, node = emission_material(bpy.data.images.load(path),
                                       interpolation=interpolation, extension=extension)
    uv_plane(material, *WIDE_UV)
    uv = plane_uvs(*WIDE_UV)
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    close(glint_image, render_cycles())


@pytest.mark.cycles
def test_float_image_interpolates_linear_values(folder):
    """A float EXR interpolates its scene-linear values (no decoding) with Cubic and Mirror,
    against Cycles."""
    cycles_file()
    add_camera()
    rgba = np.random.default_rng(3).random((4, 6, 4), np.float32) * 3
    rgba[..., 3] = 1
    path = save_exr(folder, "texture.exr", rgba)
    material, node = emission_material(bpy.data.images.load(path), interpolation="Cubic",
                                       extension="MIRROR")
    uv_plane(material, *WIDE_UV)
    uv = plane_uvs(*WIDE_UV)
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    close(glint_image, render_cycles())


# --------------------------------------------------------------------------------------------
# Projections, on a flat-shaded icosphere seen at an angle.

def mesh_hits(obj, offsets=(0.0, 0.05, -0.05)):
    """Where the camera's pixel-centre rays hit ``obj``'s triangles (brute force, nearest
    hit): (object-space points (3, n), object-space face normals (3, n), hit mask (n,)).
    A pixel counts as hit only if rays moved by ``offsets`` pixels in x and y meet the same
    triangle, so no sample lies on a facet edge."""
    mesh = obj.data
    mesh.calc_loop_triangles()
    corners = np.array([[mesh.vertices[i].co for i in triangle.vertices]
                        for triangle in mesh.loop_triangles])           # (t, 3, 3) object
    to_object = np.array(obj.matrix_world.inverted())
    scene = bpy.context.scene
    width, height = scene.render.resolution_x, scene.render.resolution_y
    camera = export_camera(bpy.context.evaluated_depsgraph_get())
    ys, xs = np.mgrid[0:height, 0:width]
    found = []
    for dx in offsets:
        for dy in offsets:
            rays = camera_rays(camera, xs.ravel() + 0.5 + dx, ys.ravel() + 0.5 + dy)
            origins = np.broadcast_to(rays.origins, rays.directions.shape)
            o = to_object[:3, :3] @ origins + to_object[:3, 3:]
            d = to_object[:3, :3] @ rays.directions
            a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]              # (t, 3)
            e1, e2 = b - a, c - a
            p = np.cross(d.T[:, None, :], e2[None])                           # (n, t, 3)
            det = np.einsum("ntk,tk->nt", p, e1)
            s = o.T[:, None, :] - a[None]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.einsum("ntk,ntk->nt", s, p) / det
                q = np.cross(s, e1[None])
                v = np.einsum("ntk,nk->nt", q, d.T) / det
                t = np.einsum("ntk,tk->nt", q, e2) / det
            valid = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
            t = np.where(valid, t, np.inf)
            nearest = t.argmin(axis=1)
            hit_t = t[np.arange(len(nearest)), nearest]
            found.append((np.where(np.isfinite(hit_t), nearest, -1), o + d * hit_t, None))
    triangles = np.stack([f[0] for f in found])
    hit = (triangles[0] >= 0) & np.all(triangles == triangles[0], axis=0)
    points = np.where(hit, found[0][1], 0.0)
    normals = np.array([triangle.normal for triangle in mesh.loop_triangles])
    normal = np.where(hit, normals[triangles[0]].T, 0.0)
    return points, normal, hit


@pytest.mark.cycles
@pytest.mark.parametrize("projection, blend", [("FLAT", 0.0), ("SPHERE", 0.0),
                                               ("TUBE", 0.0), ("BOX", 0.0), ("BOX", 0.3)])
def test_projections_match_cycles(folder, projection, blend):
    """Generated coordinates through each projection on a rotated, flat-shaded icosphere:
    Sphere and Tube wrap the unit box's coordinates around its centre, Box weighs the X, Y
    and Z images by the object-space normal (blended across ``blend``), as Cycles does."""
    cycles_file(48)
    add_camera(location=(3.0, -4.0, 4.5), ortho_scale=2.6)
    path = save_png(folder, "texture.png", random_bytes(6, 8, seed=4))
    material, node = emission_material(bpy.data.images.load(path), projection=projection,
                                       blend=blend, vector="Generated")
    mesh = ico_sphere_mesh("ico", radius=1.0, subdivisions=1, smooth=False)
    mesh.materials.append(material)
    ico = link(bpy.data.objects.new("ico", mesh))
    ico.rotation_euler = (0.3, 0.2, 0.5)
    bpy.context.view_layer.update()
    points, normal, hit = mesh_hits(ico)
    # Generated coordinates: the object-space point in the mesh's texture space (its
    # bounding box) mapped to [0, 1]^3.
    centre = np.array(mesh.texspace_location)[:, None]
    size = np.array(mesh.texspace_size)[:, None]
    generated = (points - centre) / size * 0.5 + 0.5
    shading = points_for(points, generated=generated, object_normal=normal)
    glint_image, _ = glint_emission(node, shading, vector=generated)
    cycles = render_cycles()
    assert hit.sum() > 600
    close(glint_image, cycles, where=hit.reshape(48, 48))


# --------------------------------------------------------------------------------------------
# Alpha.

def premultiplied_bytes(height, width, seed):
    """RGBA bytes whose colours never exceed their alpha (valid as straight and as
    premultiplied data), alphas from 0 to 255."""
    rng = np.random.default_rng(seed)
    alpha = rng.choice([0, 1, 64, 128, 200, 254, 255], (height, width))
    colour = (rng.random((height, width, 3)) * alpha[..., None]).round()
    return np.concatenate([colour, alpha[..., None]], axis=-1).astype(np.uint8)


@pytest.mark.cycles
@pytest.mark.parametrize("mode", ["STRAIGHT", "PREMUL", "CHANNEL_PACKED", "NONE"])
@pytest.mark.parametrize("packed", [False, True])
@pytest.mark.parametrize("kind", ["png Closest", "png Linear", "exr Linear"])
def test_alpha_modes_match_cycles(folder, mode, packed, kind):
    """Color with the Alpha output unused (premultiplied, as Cycles associates alpha at
    load), and Color x Alpha with it used (Color then divided by alpha, except for Channel
    Packed; None: alpha 1), for a file and a packed image: Cycles reads the first from the
    file itself (a PNG marked Premultiplied is multiplied by alpha once more, an EXR marked
    Straight taken as stored), the second through Blender's buffer (which divides the PNG
    by alpha first and multiplies the EXR by it)."""
    file_type, interpolation = kind.split()
    rgba = premultiplied_bytes(4, 4, seed=5)
    path = save_png(folder, "alpha.png", rgba) if file_type == "png" else \
        save_exr(folder, "alpha.exr", rgba.astype(np.float32) / 200)
    for alpha_strength in (False, True):
        cycles_file()
        add_camera()
        image = bpy.data.images.load(path)
        image.alpha_mode = mode
        if packed:
            image.pack()
        material, node = emission_material(image, interpolation=interpolation,
                                           extension="EXTEND", alpha_strength=alpha_strength)
        uv_plane(material)
        uv = plane_uvs()
        glint_image, _ = glint_emission(node, points_for(uv, uv=uv), alpha_strength=alpha_strength)
        close(glint_image, render_cycles())


# --------------------------------------------------------------------------------------------
# Colour spaces.

#: Byte images: kept as bytes (sRGB decoded after interpolation, Non-Color and Linear Rec.709
#: as they are) or converted by OCIO to half floats (the others; Rec.2100-PQ through
#: Blender's conversion scaled to Cycles' 100-nit white, Display P3 a display encoding).
BYTE_SPACES = ["sRGB", "Non-Color", "Linear Rec.709", "Linear Rec.2020", "ACEScg",
               "AgX Log", "Display P3", "Rec.2100-PQ"]
#: Float images: Blender's float buffer, converted to scene-linear on load, except sRGB,
#: which Cycles keeps encoded and decodes after interpolation.
FLOAT_SPACES = ["Linear Rec.709", "Non-Color", "ACEScg", "ACES2065-1", "sRGB", "Rec.2100-PQ"]


def converted(colour_space) -> bool:
    """Whether Cycles converts an image in this colour space to half floats."""
    return ColourSpaces.kind(colour_space, colour_space == "Non-Color") == "other"


def colour_space_check(colour_space):
    """(interpolation, relative, absolute) to compare an image in this colour space with
    (module docstring)."""
    return ("Closest", 2e-3, 1e-4) if converted(colour_space) else ("Linear", 1e-4, 1e-4)


@pytest.mark.cycles
@pytest.mark.parametrize("colour_space", BYTE_SPACES)
@pytest.mark.parametrize("alpha", [False, True])
def test_byte_image_colour_spaces_match_cycles(folder, colour_space, alpha):
    """An 8-bit PNG in each colour space (with and without alpha)."""
    cycles_file()
    add_camera()
    rgba = premultiplied_bytes(4, 6, seed=6) if alpha else random_bytes(4, 6, seed=6)
    image = bpy.data.images.load(save_png(folder, "colours.png", rgba))
    image.colorspace_settings.name = colour_space
    interpolation, relative, absolute = colour_space_check(colour_space)
    material, node = emission_material(image, interpolation=interpolation, extension="EXTEND")
    uv_plane(material)
    uv = plane_uvs()
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    close(glint_image, render_cycles(), relative, absolute)


@pytest.mark.cycles
@pytest.mark.parametrize("colour_space", FLOAT_SPACES)
@pytest.mark.parametrize("packed", [False, True])
def test_float_image_colour_spaces_match_cycles(folder, colour_space, packed):
    """A float EXR with alpha in each colour space, from its file (Cycles converts it
    itself) and packed (Cycles takes Blender's converted buffer)."""
    cycles_file()
    add_camera()
    rgba = np.random.default_rng(7).random((4, 6, 4), np.float32)
    rgba[..., 3] = np.random.default_rng(8).choice([0.0, 0.3, 1.0], (4, 6))
    rgba[..., :3] *= rgba[..., 3:]           # EXR colours are premultiplied
    image = bpy.data.images.load(save_exr(folder, "colours.exr", rgba))
    image.colorspace_settings.name = colour_space
    if packed:
        image.pack()
    interpolation, relative, absolute = colour_space_check(colour_space)
    material, node = emission_material(image, interpolation=interpolation, extension="EXTEND")
    uv_plane(material)
    uv = plane_uvs()
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    close(glint_image, render_cycles(), relative, absolute)


@pytest.mark.cycles
@pytest.mark.parametrize("packed", [False, True])
def test_16_bit_png_matches_cycles(folder, packed):
    """A 16-bit sRGB PNG with alpha is a float image in Blender (linearised on load) but
    stays sRGB-encoded 16-bit in Cycles when it reads the file (decoded after
    interpolation): Linear interpolation tells the two apart."""
    scene = cycles_file()
    add_camera()
    rgba = np.random.default_rng(9).random((4, 6, 4), np.float32)
    rgba[..., 3] = np.random.default_rng(10).choice([0.2, 0.6, 1.0], (4, 6))
    source = bpy.data.images.new("sixteen", 6, 4, alpha=True, float_buffer=True)
    source.pixels.foreach_set(rgba[::-1].ravel())
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = 'PNG', '16', 'RGBA'
    path = os.path.join(folder, "sixteen.png")
    source.save_render(path, scene=scene)
    image = bpy.data.images.load(path)
    assert image.is_float and image.colorspace_settings.name == "sRGB"
    if packed:
        image.pack()
    material, node = emission_material(image, extension="EXTEND")
    uv_plane(material)
    uv = plane_uvs()
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    # 16-bit values in float32 on both sides: float32 tolerances.
    close(glint_image, render_cycles())


def test_colour_space_kinds_follow_cycles():
    """Cycles keeps sRGB bytes encoded, takes Linear Rec.709 and Non-Color as they are and
    converts the rest; Blender's config marks Rec.2100-PQ and -HLG hdr-video."""
    empty_file()
    kinds = {name: ColourSpaces.kind(name, name == "Non-Color")
             for name in ("sRGB", "Linear Rec.709", "Non-Color", "ACEScg", "Filmic Log")}
    assert kinds == {"sRGB": "srgb", "Linear Rec.709": "linear", "Non-Color": "data",
                     "ACEScg": "other", "Filmic Log": "other"}
    # Blender 5.0's config brought the Rec.2100 spaces; 4.2's and 4.5's have none.
    names = {item.identifier for item in bpy.types.ColorManagedInputColorspaceSettings
             .bl_rna.properties["name"].enum_items}
    rec2100 = [name for name in ("Rec.2100-PQ", "Rec.2100-HLG") if name in names]
    assert len(rec2100) == (2 if bpy.app.version >= (5, 0, 0) else 0)
    assert [ColourSpaces.cycles_scale(name) for name in rec2100] == pytest.approx(
        [2.03] * len(rec2100))
    assert ColourSpaces.cycles_scale("ACEScg") == 1.0


# --------------------------------------------------------------------------------------------
# What cannot be read, and what should not be.

@pytest.mark.cycles
@pytest.mark.parametrize("fault", ["missing", "unreadable"])
def test_missing_file_renders_magenta_with_one_warning(folder, fault):
    """An image whose file is gone (or holds no image) renders magenta (1, 0, 1) as in
    Cycles, with one warning naming the image, its path and the material; an image node
    without an image too."""
    cycles_file()
    add_camera()
    path = save_png(folder, "gone.png", random_bytes(2, 2))
    image = bpy.data.images.load(path)
    if fault == "missing":
        os.remove(path)
    else:
        with open(path, "wb") as file:
            file.write(b"not an image at all")
    material, node = emission_material(image)
    material.name = "Painted"
    uv_plane(material)
    uv = plane_uvs()
    glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
    cycles = render_cycles()
    close(glint_image, cycles)
    assert np.allclose(cycles[..., :3], (1.0, 0.0, 1.0))
    assert len(notes) == 1
    assert "'gone.png'" in notes[0] and path in notes[0] and "material 'Painted'" in notes[0]
    assert "magenta" in notes[0]
    node.image = None
    glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
    assert np.allclose(glint_image, (1.0, 0.0, 1.0))
    assert len(notes) == 1 and "material 'Painted'" in notes[0] and "no image" in notes[0]


@pytest.mark.cycles
def test_non_finite_texels_are_zeroed_with_one_warning(folder):
    """A float image's NaN and infinite texels are zeroed, all four channels (Cycles'
    loader's intent; its loop reaches only every fourth pixel, 0, 4, ..., which is where
    the two agree; elsewhere a NaN reaches Cycles' shading and only the film's clamp zeroes
    the channel it poisons), with one warning naming the image and the count."""
    cycles_file()
    add_camera()
    rgba = np.full((1, 8, 4), 0.5, np.float32)
    rgba[..., 3] = 1
    rgba[0, 0, 0] = np.nan       # reached by Cycles' loop
    rgba[0, 4, 2] = np.inf       # reached
    rgba[0, 1, 1] = np.nan       # not reached: Cycles shows (0.5, 0, 0.5)
    rgba[0, 5, 3] = -np.inf
    image = bpy.data.images.load(save_exr(folder, "holes.exr", rgba))
    material, node = emission_material(image, interpolation="Closest")
    uv_plane(material)
    uv = plane_uvs()
    glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
    cycles = render_cycles()
    texel = (np.arange(RES) * 8) // RES                 # each pixel column's texel
    reached = np.isin(texel, [0, 2, 3, 4, 6, 7])[None, :].repeat(RES, axis=0)
    close(glint_image, cycles, where=reached)
    assert np.all(glint_image[:, np.isin(texel, [0, 1, 4, 5])] == 0)
    assert len(notes) == 1 and "'holes.exr'" in notes[0] and "4 pixels" in notes[0]


def test_an_image_is_read_once_and_shared(folder):
    """Two materials using one image get the same ImageData (read once per export), whose
    texels are read-only and reach worker processes out of band (one buffer, not a copy
    per material)."""
    empty_file()
    image = bpy.data.images.load(save_png(folder, "shared.png", random_bytes(64, 64)))
    first, node_a = emission_material(image)
    second, node_b = emission_material(image)
    context = ExportContext.for_camera(None, judged_from=None)
    read = OPTION_READERS["ShaderNodeTexImage"]
    a, b = read(node_a, context)["image"], read(node_b, context)["image"]
    assert a is b
    assert not a.texels.flags.writeable
    buffers = []
    payload = pickle.dumps({"first": a, "second": b}, protocol=5,
                           buffer_callback=buffers.append)
    assert len(buffers) == 1 and buffers[0].raw().readonly
    copy = pickle.loads(payload, buffers=buffers)
    assert copy["first"] is copy["second"]
    assert np.array_equal(copy["first"].texels, a.texels)


# --------------------------------------------------------------------------------------------
# UDIM tiles, sequences and movies.

def udim_image(folder):
    """A tiled image of tiles 1001 (4 x 3), 1002 (5 x 2) and 1011 (3 x 3)."""
    for number, (width, height), seed in ((1001, (4, 3), 11), (1002, (5, 2), 12),
                                          (1011, (3, 3), 13)):
        save_png(folder, f"tiles.{number}.png", random_bytes(height, width, seed=seed))
    image = bpy.data.images.load(os.path.join(folder, "tiles.1001.png"))
    image.source = 'TILED'
    image.filepath = os.path.join(folder, "tiles.<UDIM>.png")
    assert sorted(tile.number for tile in image.tiles) == [1001, 1002, 1011]
    return image


@pytest.mark.cycles
@pytest.mark.parametrize("packed", [False, True])
@pytest.mark.parametrize("interpolation", ["Closest", "Linear"])
def test_udim_tiles_match_cycles(folder, packed, interpolation):
    """UVs over tiles 1001, 1002, 1011 and the missing 1003, 1012, 1013: each point reads
    the tile its UV's integer parts name (truncated: u in (-1, 0) reads tile 1001's Extend),
    magenta where no tile is; from the files and packed.  The plane is cut so that a vertex
    lies in every tile: Cycles loads a file UDIM's tiles only where some mesh vertex's UV
    falls (``cull_tiles``), and shows the others magenta."""
    cycles_file(48)
    add_camera()
    image = udim_image(folder)
    if packed:
        image.pack()
    material, node = emission_material(image, interpolation=interpolation,
                                       extension="EXTEND")
    uv0, uv1 = (-0.45, -0.3), (2.45, 2.3)
    uv_plane(material, uv0, uv1, cuts=8)
    uv = plane_uvs(uv0, uv1)
    glint_image, _ = glint_emission(node, points_for(uv, uv=uv))
    cycles = render_cycles()
    # Pixels whose footprint straddles a tile border may sample either tile in Cycles.
    fraction = np.stack([uv[0] % 1, uv[1] % 1]).reshape(2, 48, 48)
    step = 3.0 / 48
    clear = np.all((fraction > step) & (fraction < 1 - step), axis=0)
    close(glint_image, cycles, where=clear)
    magenta = np.all(np.isclose(cycles[..., :3], (1, 0, 1)), axis=-1)
    assert magenta.sum() > 300          # the missing tiles show


@pytest.mark.cycles
def test_unreadable_udim_tile_is_magenta_with_one_warning(folder):
    """A tile whose file is gone renders magenta, the others as they are, as in Cycles."""
    cycles_file(48)
    add_camera()
    image = udim_image(folder)
    os.remove(os.path.join(folder, "tiles.1002.png"))
    material, node = emission_material(image, interpolation="Closest", extension="EXTEND")
    material.name = "Tiled"
    uv0, uv1 = (0.05, 0.05), (1.95, 1.95)
    uv_plane(material, uv0, uv1, cuts=4)
    uv = plane_uvs(uv0, uv1)
    glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
    close(glint_image, render_cycles())
    assert np.allclose(glint_image[40, 40], (1, 0, 1))      # tile 1002, bottom right
    assert not np.allclose(glint_image[40, 8], (1, 0, 1))   # tile 1001
    assert len(notes) == 1 and "[1002]" in notes[0] and "material 'Tiled'" in notes[0]


@pytest.mark.cycles
def test_image_sequence_frame_follows_the_image_user(folder):
    """A sequence's frame at the scene's frame, through the node's image user (start,
    offset, duration, cyclic), as Cycles reads it."""
    for number in range(1, 6):
        rgba = np.zeros((2, 2, 4), np.uint8)
        rgba[..., 0], rgba[..., 1], rgba[..., 3] = 40 * number, 255 - 40 * number, 255
        save_png(folder, f"frames_{number:03d}.png", rgba)
    for scene_frame, start, offset, cyclic in ((7, 3, 0, False), (9, 3, 1, False),
                                               (12, 2, 0, True), (1, 3, 0, False)):
        scene = cycles_file()
        add_camera()
        image = bpy.data.images.load(os.path.join(folder, "frames_001.png"))
        image.source = 'SEQUENCE'
        material, node = emission_material(image, interpolation="Closest")
        user = node.image_user
        user.frame_duration, user.frame_start = 4, start
        user.frame_offset, user.use_cyclic, user.use_auto_refresh = offset, cyclic, True
        scene.frame_set(scene_frame)
        uv_plane(material)
        uv = plane_uvs()
        glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
        expected = frame_number(user, scene_frame)
        cycles = render_cycles()
        close(glint_image, cycles)
        if 1 <= expected <= 5:
            assert np.allclose(glint_image[0, 0, 0], ((40 * expected) / 255) ** 2.2, rtol=0.1)
            assert not notes
        else:   # no such frame: magenta and a warning, as Cycles shows it
            assert np.allclose(glint_image, (1, 0, 1)) and len(notes) == 1


def test_frame_number_follows_blender():
    """The image user's frame calculation (Blender's BKE_image_user_frame_get)."""
    class User:
        frame_duration, frame_start, frame_offset, use_cyclic = 4, 3, 0, False
    user = User()
    assert [frame_number(user, f) for f in (1, 2, 3, 6, 7, 20)] == [0, 0, 1, 4, 4, 4]
    user.use_cyclic = True
    assert [frame_number(user, f) for f in (2, 3, 6, 7, 11)] == [4, 1, 4, 1, 1]
    user.frame_offset = 10
    assert frame_number(user, 4) == 12
    user.frame_duration = 0
    assert frame_number(user, 4) == 0


def write_movie(folder, colours) -> str:
    """A lossless QuickTime movie (PNG frames) of 32 x 32 frames, one flat colour each,
    rendered by Cycles from a keyed world colour."""
    scene = cycles_file(RES)
    add_camera()
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Strength"].default_value = 1.0
    for frame, colour in enumerate(colours, start=1):
        background.inputs["Color"].default_value = (*colour, 1.0)
        background.inputs["Color"].keyframe_insert("default_value", frame=frame)
    scene.frame_start, scene.frame_end = 1, len(colours)
    settings = scene.render.image_settings
    settings.media_type, settings.file_format, settings.color_mode = 'VIDEO', 'FFMPEG', 'RGB'
    scene.render.ffmpeg.format, scene.render.ffmpeg.codec = 'QUICKTIME', 'PNG'
    scene.render.filepath = os.path.join(folder, "movie")
    bpy.ops.render.render(animation=True)
    (name,) = [name for name in os.listdir(folder) if name.endswith(".mov")]
    return os.path.join(folder, name)


@pytest.mark.cycles
def test_movie_frame_follows_the_image_user(folder):
    """A movie's frame at the scene's frame through the image user, as Cycles reads it
    (through Blender's buffers)."""
    path = write_movie(folder, [(0.2, 0.0, 0.0), (0.0, 0.5, 0.0), (0.0, 0.0, 0.8),
                                (0.6, 0.6, 0.0)])
    for scene_frame, expected in ((4, 3), (2, 1), (5, 4)):
        scene = cycles_file()
        add_camera()
        image = bpy.data.images.load(path)
        material, node = emission_material(image, interpolation="Closest")
        node.image_user.frame_duration, node.image_user.frame_start = 4, 2
        node.image_user.use_auto_refresh = True
        scene.frame_set(scene_frame)
        uv_plane(material)
        uv = plane_uvs()
        glint_image, notes = glint_emission(node, points_for(uv, uv=uv))
        assert frame_number(node.image_user, scene_frame) == expected and not notes
        close(glint_image, render_cycles())


# --------------------------------------------------------------------------------------------
# The Environment Texture.

def environment_world(path, projection="EQUIRECTANGULAR", rotation=None):
    """The scene's world: Environment Texture (``path``) -> Background (strength 1), through
    a Mapping node rotating the direction by Euler ``rotation`` if given.  Returns the
    texture node."""
    world = bpy.context.scene.world
    tree = world.node_tree
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = 1.0
    texture = tree.nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(path)
    texture.projection = projection
    tree.links.new(texture.outputs["Color"], background.inputs["Color"])
    if rotation is not None:
        mapping = tree.nodes.new("ShaderNodeMapping")
        mapping.vector_type = 'VECTOR'
        mapping.inputs["Rotation"].default_value = rotation
        coordinates = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coordinates.outputs["Generated"], mapping.inputs["Vector"])
        tree.links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    return texture


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("projection", ["EQUIRECTANGULAR", "MIRROR_BALL"])
def test_environment_texture_matches_cycles(projection):
    """A camera looking at the world (a studio light's EXR as Environment Texture): each
    pixel is the image seen along its ray, Linear, as Cycles shows it."""
    cycles_file(64)
    add_camera(location=(0.0, 0.0, 0.0), target=(1.0, 0.4, 0.3), lens=12.0)
    texture = environment_world(os.path.join(STUDIO_LIGHTS, "forest.exr"), projection)
    _, directions = pixel_rays()
    glint_image, notes = glint_emission(texture, points_for(directions))
    assert not notes
    cycles = render_cycles()
    # Cycles' 0.01-pixel filter moves each sample up to 0.005 pixel off the centre, here up
    # to 0.025 texel (5 texels a pixel): allow how much Glint's own value changes over
    # that, beside the tolerance for float32 (and 2^-15 for a black half texel).
    moved = [glint_emission(texture, points_for(pixel_rays(dx, dy)[1]))[0]
             for dx in (-0.005, 0.005) for dy in (-0.005, 0.005)]
    spread = np.max([np.abs(image - glint_image) for image in moved], axis=0)
    error = np.abs(glint_image - cycles[..., :3])
    assert np.all(error <= 1e-4 + 1e-4 * np.abs(cycles[..., :3]) + spread), error.max()
    assert glint_image.std() > 0.05          # a picture, not a constant


# --------------------------------------------------------------------------------------------
# The registered nodes and bad input.

def test_image_nodes_are_registered_with_blenders_sockets():
    """The registry's specs name Blender 5.0's sockets and options, and the unlinked Vector:
    the UV map for Image Texture, the position (the world's direction) for Environment."""
    empty_file()
    material = new_material("sockets")
    for kind, implicit in (("ShaderNodeTexImage", "uv"), ("ShaderNodeTexEnvironment",
                                                          "position")):
        node = material.node_tree.nodes.new(kind)
        spec = NODES[kind]
        assert [name for name, _ in spec.inputs] == [s.identifier for s in node.inputs]
        assert [name for name, _ in spec.outputs] == [s.identifier for s in node.outputs]
        assert spec.implicit == {"Vector": implicit}
        for option in spec.options:
            assert option == "alpha_used" or hasattr(node, option), option


def test_bad_image_data_and_options_are_named():
    """Invalid image data or options raise one line naming the image and the field."""
    texels = np.zeros((6, 3), np.uint8)
    with pytest.raises(ValueError, match=r"image 'bad'.*6 texels for 5"):
        core_images.ImageData("bad", texels, 5, 1)
    with pytest.raises(ValueError, match=r"image 'bad'.*uint8, float16 or float32"):
        core_images.ImageData("bad", texels.astype(np.int32), 3, 2)
    image = core_images.ImageData("good", texels, 3, 2)
    with pytest.raises(ValueError, match=r"image 'good'.*interpolation.*'Bicubic'"):
        core_images.lookup(image, [0.5], [0.5], "Bicubic")
    with pytest.raises(ValueError, match=r"image 'good'.*extension.*'WRAP'"):
        core_images.lookup(image, [0.5], [0.5], "Linear", "WRAP")
    assert not image.texels.flags.writeable
