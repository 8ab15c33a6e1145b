"""Readers of the shader nodes whose options are more than plain properties: what the core's
node functions (``core.shader.registry``) take by keyword, as plain Python values (floats,
tuples, strings).  ``OPTION_READERS[bl_idname](node)`` returns all the options of that node
type; nodes without a reader have their ``NodeSpec.options`` read with ``getattr``.

A Color Ramp goes as its stops (the core bakes Cycles' table from them); a curve goes as
Cycles' table of it, evaluated by Blender here (``CurveMapping.evaluate``, the call Cycles'
export makes), with its range and whether it extrapolates.  Blackbody, Wavelength and RGB
to BW get the file's working colour space (Linear Rec.709, Rec.2020, ACEScg...) as
matrices or weights, which Blender's colour management gives through ``mathutils.Color``.

Readers that take a second argument named ``context`` get the export's ``ExportContext``:
image nodes take their ``core.shader.images.ImageData`` from its image exporter
(``ExportContext.image_exporter``: each image read once per export), and warnings go to it.
A context may name what is being compiled in ``owner`` ("material 'Wood'"); without it the
owner is found from the node's tree.

Every procedural texture but White Noise has a Texture Mapping (``node.texture_mapping``, a
``TexMapping`` struct, set in the node's sidebar) that Cycles applies to the Vector before
the texture; ``texture_mapping`` reads the parts Cycles reads (not Min/Max, and not the
node's Color Mapping, which Cycles ignores).
"""

from __future__ import annotations

import bpy
from mathutils import Color, Matrix

from ...core.shader.colour_models import CYCLES_XYZ_TO_REC709, IDENTITY
from ...core.shader.colour_nodes import RAMP_TABLE_SIZE
from ...core.shader.ies import IESError, parse_ies
from ..compat import sky_model


def _floats(values) -> tuple:
    return tuple(float(v) for v in values)


def color_ramp(node) -> dict:
    ramp = node.color_ramp
    return dict(elements=tuple((float(element.position), _floats(element.color))
                               for element in ramp.elements),
                interpolation=ramp.interpolation, color_mode=ramp.color_mode,
                hue_interpolation=ramp.hue_interpolation)


def _curve_range(curves) -> tuple[float, float]:
    """The x range Cycles bakes a set of curves over: the first point of any of them to the
    last point of any."""
    return (min(curve.points[0].location[0] for curve in curves),
            max(curve.points[-1].location[0] for curve in curves))


def _positions(low: float, high: float):
    steps = RAMP_TABLE_SIZE - 1
    return [low + i / steps * (high - low) for i in range(RAMP_TABLE_SIZE)]


def _curve_options(mapping, table, low, high) -> dict:
    return dict(curve_table=table, curve_min=float(low), curve_max=float(high),
                extrapolate=mapping.extend == 'EXTRAPOLATED')


def rgb_curves(node) -> dict:
    """R, G and B each applied over the combined curve, as Cycles bakes them."""
    mapping = node.mapping
    mapping.update()
    red, green, blue, combined = mapping.curves[:4]
    low, high = _curve_range((red, green, blue, combined))
    table = []
    for x in _positions(low, high):
        under = mapping.evaluate(combined, x)
        table.append((mapping.evaluate(red, under), mapping.evaluate(green, under),
                      mapping.evaluate(blue, under)))
    return _curve_options(mapping, tuple(table), low, high)


def vector_curves(node) -> dict:
    mapping = node.mapping
    mapping.update()
    curves = mapping.curves[:3]
    low, high = _curve_range(curves)
    table = tuple(tuple(mapping.evaluate(curve, x) for curve in curves)
                  for x in _positions(low, high))
    return _curve_options(mapping, table, low, high)


def float_curve(node) -> dict:
    mapping = node.mapping
    mapping.update()
    curve = mapping.curves[0]
    low, high = _curve_range((curve,))
    table = tuple((mapping.evaluate(curve, x),) for x in _positions(low, high))
    return _curve_options(mapping, table, low, high)


def value(node) -> dict:
    return dict(value=float(node.outputs[0].default_value))


def rgb(node) -> dict:
    return dict(color=_floats(node.outputs[0].default_value[:3]))


def _rows(matrix, count: int = 4) -> tuple:
    return tuple(_floats(matrix[row][:count]) for row in range(3))


def texture_coordinate(node) -> dict:
    """The chosen object's world -> local matrix, for the Object output."""
    chosen = node.object
    return dict(object_matrix=None if chosen is None else _rows(chosen.matrix_world.inverted()),
                from_instancer=bool(node.from_instancer))


def world_to_camera(scene) -> tuple | None:
    """The 3 x 4 world -> camera matrix of Cycles' camera space (x right, y up, z into the
    view) for the scene's camera, its scale removed as Cycles does; None without a camera."""
    camera = scene.camera if scene is not None else None
    if camera is None:
        return None
    location, rotation, _scale = camera.matrix_world.decompose()
    camera_to_world = Matrix.Translation(location) @ rotation.to_matrix().to_4x4()
    camera_to_world = camera_to_world @ Matrix.Diagonal((1.0, 1.0, -1.0, 1.0))
    return _rows(camera_to_world.inverted())


def vector_transform(node, scene=None) -> dict:
    """``scene``: whose camera defines camera space (the context's scene by default)."""
    scene = scene if scene is not None else bpy.context.scene
    return dict(vector_type=node.vector_type, convert_from=node.convert_from,
                convert_to=node.convert_to, world_to_camera=world_to_camera(scene))


_BASIS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _matrix_of(convert) -> tuple:
    """The 3 x 3 matrix (rows) of a linear colour conversion ``Color -> Color``."""
    columns = [tuple(convert(Color(axis))) for axis in _BASIS]
    return tuple(tuple(float(columns[col][row]) for col in range(3)) for row in range(3))


def working_space_luminance() -> tuple:
    """The Y (luminance) weights of the working space's RGB."""
    return tuple(float(Color(axis).from_scene_linear_to_xyz_d65()[1]) for axis in _BASIS)


def rgb_to_bw(node) -> dict:
    return dict(luminance=working_space_luminance())


def blackbody(node) -> dict:
    """Cycles leaves Blackbody's Rec.709 colour as it is in a Rec.709 working space, and
    otherwise takes it to XYZ with its own Rec.709 matrix and from there to the working
    space."""
    rec709_to_scene = _matrix_of(lambda c: c.from_rec709_linear_to_scene_linear())
    if all(abs(rec709_to_scene[i][j] - IDENTITY[i][j]) < 1e-4
           for i in range(3) for j in range(3)):
        return dict(rec709_to_scene=IDENTITY)
    xyz_to_scene = Matrix(_matrix_of(lambda c: c.from_xyz_d65_to_scene_linear()))
    matrix = xyz_to_scene @ Matrix(CYCLES_XYZ_TO_REC709).inverted()
    return dict(rec709_to_scene=tuple(_floats(row) for row in matrix))


def xyz_to_scene() -> tuple:
    """The 3 x 3 matrix (rows) taking CIE XYZ to the working space's RGB, as Cycles converts
    the XYZ colours of Wavelength and the Sky Texture."""
    return _matrix_of(lambda c: c.from_xyz_d65_to_scene_linear())


def wavelength(node) -> dict:
    return dict(xyz_to_scene=xyz_to_scene())


def owner_name(node, context=None) -> str:
    """How warnings name what uses ``node``: the context's owner, else the material, world
    or light whose node tree holds it, else its node group."""
    owner = getattr(context, "owner", None)
    if owner:
        return owner
    tree = node.id_data
    # An export reads the evaluated copy of a tree; the materials hold the original.
    tree = getattr(tree, "original", None) or tree
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


def ies_texture_options(node, context=None) -> dict:
    """IES Texture: its file (the Text datablock in Internal mode, the file at its path,
    relative to the .blend, in External mode) parsed into ``core.shader.ies.IESProfile``.
    A file that is missing or cannot be parsed gives no profile (Fac = 100 x Strength, as
    in Cycles), with one warning naming the node and what uses it."""
    if node.mode == 'EXTERNAL':
        source = f"file '{node.filepath}'"
        try:
            with open(bpy.path.abspath(node.filepath, library=node.id_data.library),
                      "rb") as file:
                # IES files are ASCII; Latin-1 reads any byte, as Cycles reads bytes.
                text, problem = file.read().decode("latin-1"), ""
        except OSError as error:
            text, problem = None, f"cannot be read ({error.strerror or error})"
    elif node.ies is None:
        source, text, problem = "Internal mode", None, "has no text"
    else:
        source, text, problem = f"text '{node.ies.name}'", node.ies.as_string(), ""
    profile = None
    if text is not None:
        try:
            profile = parse_ies(text)
        except IESError as error:
            problem = f"is not an IES file Cycles reads: {error}"
    note = getattr(context, "note", None)
    if profile is None and note is not None:
        note(f"{owner_name(node, context)}: IES Texture '{node.name}': {source} {problem}; "
             f"its Fac is 100 x Strength in every direction, as in Cycles")
    return dict(profile=profile)


def sky_texture(node) -> dict:
    """Sky Texture: its properties (Sun Direction as a tuple), Texture Mapping and the working
    space's XYZ -> RGB matrix."""
    options = {name: getattr(node, name) for name in (
        "sun_disc", "sun_size", "sun_intensity", "sun_elevation", "sun_rotation",
        "altitude", "air_density", "ozone_density", "turbidity", "ground_albedo")}
    options.update(sky_model(node))
    options["sun_direction"] = _floats(node.sun_direction)
    options["xyz_to_scene"] = xyz_to_scene()
    options.update(texture_mapping(node))
    return options


def texture_mapping(node) -> dict:
    """{'texture_mapping': {translation, rotation, scale (3-tuples of floats), vector_type,
    mapping_x, mapping_y, mapping_z (enum identifiers)}}."""
    mapping = node.texture_mapping
    return {"texture_mapping": {
        "translation": tuple(mapping.translation), "rotation": tuple(mapping.rotation),
        "scale": tuple(mapping.scale), "vector_type": mapping.vector_type,
        "mapping_x": mapping.mapping_x, "mapping_y": mapping.mapping_y,
        "mapping_z": mapping.mapping_z}}


OPTION_READERS = {
    "ShaderNodeTexImage": image_texture_options,
    "ShaderNodeTexEnvironment": environment_texture_options,
    "ShaderNodeValToRGB": color_ramp,
    "ShaderNodeRGBCurve": rgb_curves,
    "ShaderNodeVectorCurve": vector_curves,
    "ShaderNodeFloatCurve": float_curve,
    "ShaderNodeValue": value,
    "ShaderNodeRGB": rgb,
    "ShaderNodeTexCoord": texture_coordinate,
    "ShaderNodeVectorTransform": vector_transform,
    "ShaderNodeRGBToBW": rgb_to_bw,
    "ShaderNodeBlackbody": blackbody,
    "ShaderNodeWavelength": wavelength,
    "ShaderNodeTexSky": sky_texture,
    "ShaderNodeTexIES": ies_texture_options,
}
OPTION_READERS.update({node_type: texture_mapping for node_type in (
    "ShaderNodeTexNoise", "ShaderNodeTexVoronoi", "ShaderNodeTexWave", "ShaderNodeTexMagic",
    "ShaderNodeTexGradient", "ShaderNodeTexChecker", "ShaderNodeTexBrick")})
