"""What differs between the Blender versions Glint supports (4.2 LTS to 5.3), in one place.

Each difference names the version that brought it; the rest of the add-on (and the tests'
scene builders) call these helpers instead of testing ``bpy.app.version`` themselves.  The
user guide's "Supported Blender versions" lists the same differences for users.
"""

from __future__ import annotations

import atexit

import bpy
import numpy as np

VERSION = bpy.app.version

#: Blender 5.0: mathutils' Matrix and Vector expose their floats through the buffer
#: protocol (``bytes(matrix)``); before, they are read item by item.
MATRIX_BUFFER = VERSION >= (5, 0, 0)


def matrix_bytes(matrix) -> bytes:
    """A 4x4 ``mathutils.Matrix`` as 64 bytes of row-major float32."""
    if MATRIX_BUFFER:
        return bytes(matrix)
    return np.asarray(matrix, np.float32).tobytes()


#: Blender 4.2 has no light Exposure (4.5 has it): there a light's power is its energy alone.
LIGHT_EXPOSURE = "exposure" in bpy.types.Light.bl_rna.properties


def light_exposure(light) -> float:
    """The light's Exposure in stops (its power is energy x 2^exposure); 0 where Blender has
    none."""
    return float(light.exposure) if LIGHT_EXPOSURE else 0.0


#: Blender 4.2 has no light Temperature (4.5 has it): there a light's colour is its Color alone.
LIGHT_TEMPERATURE = "use_temperature" in bpy.types.Light.bl_rna.properties


def uses_light_temperature(light) -> bool:
    """Whether the light's colour is multiplied by its temperature's (False where Blender has
    no light Temperature)."""
    return LIGHT_TEMPERATURE and light.use_temperature


#: Blender 4.3: ``Object.evaluated_geometry()`` hands out an instancer's instances as one
#: point cloud, read in bulk; on 4.2 the export walks the depsgraph's instances one by one
#: (the same scene, slower for many instances).
EVALUATED_GEOMETRY = hasattr(bpy.types.Object, "evaluated_geometry")


#: Blender 5.0: an output's kind is ``ImageFormatSettings.media_type``, which decides the file
#: formats it offers ('OPEN_EXR_MULTILAYER' only under 'MULTI_LAYER_IMAGE'); before, every
#: format is a file format of its own.
MEDIA_TYPE = "media_type" in bpy.types.ImageFormatSettings.bl_rna.properties


def set_file_format(settings, file_format: str) -> None:
    """Make ``settings`` (ImageFormatSettings) write ``file_format``: 'PNG', 'OPEN_EXR',
    'OPEN_EXR_MULTILAYER' or 'FFMPEG' (a video)."""
    if MEDIA_TYPE:
        settings.media_type = {'OPEN_EXR_MULTILAYER': 'MULTI_LAYER_IMAGE',
                               'FFMPEG': 'VIDEO'}.get(file_format, 'IMAGE')
    settings.file_format = file_format


#: Blender 5.0: every material and world renders its node tree (``use_nodes`` is deprecated
#: and new ones come with a tree); before, a new one has no tree until ``use_nodes`` is set,
#: and one with ``use_nodes`` off renders its plain colour, whatever its tree holds.
NODES_ALWAYS = VERSION >= (5, 0, 0)


#: Lights render their node tree only with Use Nodes on, until a Blender (5.3 here) where
#: every light has a tree and ``use_nodes`` is deprecated (always True): asked of its RNA.
LIGHT_NODES_ALWAYS = bool(getattr(bpy.types.Light.bl_rna.properties["use_nodes"],
                                  "is_deprecated", False))


def node_tree_in_use(datablock, always: bool = NODES_ALWAYS):
    """The node tree a material, world or light renders with, or None (it renders its
    colour); always: whether this Blender renders such a datablock's tree whatever its
    Use Nodes (``NODES_ALWAYS`` for materials and worlds, ``LIGHT_NODES_ALWAYS`` for
    lights)."""
    tree = datablock.node_tree
    if tree is None or always or datablock.use_nodes:
        return tree
    return None


def new_material(name: str):
    """A new material with its node tree (Principled BSDF into Material Output), as Blender
    5 creates one."""
    material = bpy.data.materials.new(name)
    if not NODES_ALWAYS:
        material.use_nodes = True
    return material


def new_world(name: str):
    """A new world with its node tree (Background into World Output), as Blender 5 creates
    one."""
    world = bpy.data.worlds.new(name)
    if not NODES_ALWAYS:
        world.use_nodes = True
    return world


#: The ``bpy`` module before 5.0 crashes (4.2.23) or hangs (4.5.15) when Python exits with a
#: class of its own still registered (an Operator, Panel or RenderEngine); 5.0 exits cleanly.
EXIT_NEEDS_UNREGISTER = VERSION < (5, 0, 0)


def unregister_at_exit(unregister) -> None:
    """Call ``unregister`` when Python exits, where the ``bpy`` module needs it."""
    if EXIT_NEEDS_UNREGISTER:
        atexit.register(unregister)


#: Blender 5.0: a scene's compositor is a node group of its own (``compositing_node_group``);
#: before, it is the scene's ``node_tree``, used while the scene's Use Nodes is on.  5.3: a
#: stack of compositor effects (``compositor_effects``), each a node group that runs for
#: renders when Enable for Render is on; 5.3 deprecates ``compositing_node_group``, the active
#: effect's group, and warns on every read.
COMPOSITOR_EFFECTS = "compositor_effects" in bpy.types.Scene.bl_rna.properties
COMPOSITING_NODE_GROUP = "compositing_node_group" in bpy.types.Scene.bl_rna.properties


def compositor_trees(scene) -> tuple:
    """The compositing node trees Blender runs on this scene's renders (whatever Post
    Processing > Compositing says): none, one, or 5.3's stack of effects in order."""
    if COMPOSITOR_EFFECTS:
        return tuple(effect.node_group for effect in scene.compositor_effects
                     if effect.enable_for_render and effect.node_group is not None)
    if COMPOSITING_NODE_GROUP:
        tree = scene.compositing_node_group
    else:
        tree = scene.node_tree if scene.use_nodes else None
    return () if tree is None else (tree,)


def new_compositor(scene, name: str):
    """A compositor for ``scene`` with nothing in it but where its image goes, as Blender's
    interface makes one: (node tree, the input socket the composited image goes into)."""
    if not (COMPOSITOR_EFFECTS or COMPOSITING_NODE_GROUP):
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        return tree, tree.nodes.new("CompositorNodeComposite").inputs["Image"]
    tree = bpy.data.node_groups.new(name, "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out='OUTPUT', socket_type='NodeSocketColor')
    output = tree.nodes.new("NodeGroupOutput")
    if COMPOSITOR_EFFECTS:
        scene.compositor_effects.new(name=name).node_group = tree
    else:
        scene.compositing_node_group = tree
    return tree, output.inputs["Image"]


#: The sequencer's strips are ``SequenceEditor.strips`` (and ``strips_all``) in 4.5 and later,
#: ``sequences`` in 4.2 (4.5 has both).  5.0: a new effect strip is given its ``length``; 4.5
#: and before, its ``frame_end``.
STRIPS = "strips" in bpy.types.SequenceEditor.bl_rna.properties
STRIP_LENGTH = VERSION >= (5, 0, 0)


def all_strips(editor):
    """Every strip of a SequenceEditor, inside meta strips too."""
    return editor.strips_all if STRIPS else editor.sequences_all


def new_effect_strip(scene, name: str, kind: str, channel: int, frame_start: int,
                     length: int):
    """A new effect strip (``kind``: 'COLOR', say) in the scene's sequencer."""
    editor = scene.sequence_editor_create()
    strips = editor.strips if STRIPS else editor.sequences
    if STRIP_LENGTH:
        return strips.new_effect(name=name, type=kind, channel=channel,
                                 frame_start=frame_start, length=length)
    return strips.new_effect(name=name, type=kind, channel=channel, frame_start=frame_start,
                             frame_end=frame_start + length)


#: Shader nodes newer than some Blender Glint supports, by the first supported version that
#: has them: the Metallic BSDF (4.5 has it, 4.2 does not).  An older Blender's files cannot
#: hold them.
NEWER_NODES = {"ShaderNodeBsdfMetallic": (4, 5, 0)}

#: Sockets of shader nodes newer than some Blender Glint supports, (node, socket identifier)
#: by the first supported version that has them: Bump's Filter Width and Light Path's Is
#: Volume Scatter Ray (4.5 has them, 4.2 does not), Light Path's Portal Depth (5.0 has it,
#: 4.5 does not).
NEWER_SOCKETS = {("ShaderNodeBump", "Filter Width"): (4, 5, 0),
                 ("ShaderNodeLightPath", "Is Volume Scatter Ray"): (4, 5, 0),
                 ("ShaderNodeLightPath", "Portal Depth"): (5, 0, 0)}

#: What the exporter takes for a newer input on a Blender whose node lacks it: the Bump's
#: neighbours 0.1 of the ray's footprint away, Filter Width's default.  (Cycles 4.2 bumps
#: otherwise: a strong bump differs from it, see the user guide.)
ABSENT_INPUT_VALUES = {("ShaderNodeBump", "Filter Width"): 0.1}


def absent_input_value(bl_idname: str, identifier: str):
    """The value the exporter reads for input ``identifier`` of a node of type ``bl_idname``
    that this Blender's node lacks, or None when it has none (``ABSENT_INPUT_VALUES``)."""
    return ABSENT_INPUT_VALUES.get((bl_idname, identifier))


#: Blender 5.0: the Sky Texture's Nishita model is called Single Scattering (and Multiple
#: Scattering, the new default, came with it), its Dust density Aerosol density; 4.2 and 4.5
#: have the old names.
SKY_AEROSOL = "aerosol_density" in bpy.types.ShaderNodeTexSky.bl_rna.properties
SKY_TYPE_NAMES = {"NISHITA": "SINGLE_SCATTERING"}


def sky_model(node) -> dict:
    """A Sky Texture's ``sky_type`` and ``aerosol_density`` under Blender 5's names."""
    if SKY_AEROSOL:
        return {"sky_type": node.sky_type, "aerosol_density": node.aerosol_density}
    return {"sky_type": SKY_TYPE_NAMES.get(node.sky_type, node.sky_type),
            "aerosol_density": node.dust_density}
