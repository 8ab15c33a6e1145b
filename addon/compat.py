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


#: Blender 4.3: ``Object.evaluated_geometry()`` hands out an instancer's instances as one
#: point cloud, read in bulk; on 4.2 the export walks the depsgraph's instances one by one
#: (the same scene, slower for many instances).
EVALUATED_GEOMETRY = hasattr(bpy.types.Object, "evaluated_geometry")


#: Blender 5.0: an output's kind is ``ImageFormatSettings.media_type``, which decides the file
#: formats it offers ('OPEN_EXR_MULTILAYER' only under 'MULTI_LAYER_IMAGE'); before, every
#: format is a file format of its own.
MEDIA_TYPE = "media_type" in bpy.types.ImageFormatSettings.bl_rna.properties


def set_file_format(settings, file_format: str) -> None:
    """Make ``settings`` (ImageFormatSettings) write ``file_format``: 'PNG', 'OPEN_EXR' or
    'OPEN_EXR_MULTILAYER'."""
    if MEDIA_TYPE:
        multilayer = file_format == 'OPEN_EXR_MULTILAYER'
        settings.media_type = 'MULTI_LAYER_IMAGE' if multilayer else 'IMAGE'
    settings.file_format = file_format


#: Blender 5.0: every material and world renders its node tree (``use_nodes`` is deprecated
#: and new ones come with a tree); before, a new one has no tree until ``use_nodes`` is set,
#: and one with ``use_nodes`` off renders its plain colour, whatever its tree holds.
NODES_ALWAYS = VERSION >= (5, 0, 0)


def node_tree_in_use(datablock):
    """The node tree a material or world renders with, or None (it renders its colour)."""
    tree = datablock.node_tree
    if tree is None or NODES_ALWAYS or datablock.use_nodes:
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
