"""Render passes: which of Blender's view-layer passes Glint produces, registering them
(``update_render_passes``), naming the enabled ones it cannot produce, and turning the core's
``PrimaryPasses`` (``core.passes``) into Blender's pass pixels.

Glint produces Depth (Z), Position, Normal, Object Index and Material Index from each pixel
centre's first hit, and Emission from its camera path (``core.passes``); the Combined pass's
alpha is the coverage less holdouts.  The other passes a view layer can enable (mist, vector,
UV, shadow, AO, environment, the light components, cryptomatte, grease pencil, AOVs and light
groups) are named in one warning, never silently left empty.  (Shadow: Cycles writes no
Shadow pass, only EEVEE does, so there is nothing here to check one against.)
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ...core.passes import entry_names, material_entries



@dataclass(frozen=True)
class PassSpec:
    flag: str        # the ViewLayer property enabling it
    name: str        # Blender's pass name
    channel_ids: str
    kind: str        # 'VALUE', 'VECTOR', 'COLOR'


SUPPORTED_PASSES = (
    PassSpec("use_pass_z", "Depth", "Z", 'VALUE'),
    PassSpec("use_pass_position", "Position", "XYZ", 'VECTOR'),
    PassSpec("use_pass_normal", "Normal", "XYZ", 'VECTOR'),
    PassSpec("use_pass_object_index", "Object Index", "X", 'VALUE'),
    PassSpec("use_pass_material_index", "Material Index", "X", 'VALUE'),
    PassSpec("use_pass_emit", "Emission", "RGB", 'COLOR'),
)

#: Enabled view-layer passes Glint cannot produce, by the ViewLayer property, as the UI names
#: them.
UNSUPPORTED_PASSES = {
    "use_pass_mist": "Mist", "use_pass_vector": "Vector", "use_pass_uv": "UV",
    "use_pass_shadow": "Shadow", "use_pass_ambient_occlusion": "Ambient Occlusion",
    "use_pass_environment": "Environment",
    "use_pass_diffuse_direct": "Diffuse Direct", "use_pass_diffuse_indirect": "Diffuse Indirect",
    "use_pass_diffuse_color": "Diffuse Color", "use_pass_glossy_direct": "Glossy Direct",
    "use_pass_glossy_indirect": "Glossy Indirect", "use_pass_glossy_color": "Glossy Color",
    "use_pass_transmission_direct": "Transmission Direct",
    "use_pass_transmission_indirect": "Transmission Indirect",
    "use_pass_transmission_color": "Transmission Color",
    "use_pass_subsurface_direct": "Subsurface Direct",
    "use_pass_subsurface_indirect": "Subsurface Indirect",
    "use_pass_subsurface_color": "Subsurface Color",
    "use_pass_cryptomatte_object": "Cryptomatte Object",
    "use_pass_cryptomatte_material": "Cryptomatte Material",
    "use_pass_cryptomatte_asset": "Cryptomatte Asset",
    "use_pass_grease_pencil": "Grease Pencil",
}


#: The denoising guides, enabled by Cycles' own View Layer > Passes > Data > Denoising Data
#: (``view_layer.cycles.denoising_store_passes``), which the compositor's Denoise node reads.
DENOISING_PASSES = (PassSpec("denoising_store_passes", "Denoising Albedo", "RGB", 'COLOR'),
                    PassSpec("denoising_store_passes", "Denoising Normal", "XYZ", 'VECTOR'))


def enabled_passes(view_layer) -> list[PassSpec]:
    return [spec for spec in SUPPORTED_PASSES if getattr(view_layer, spec.flag, False)]


def denoising_passes(view_layer) -> list[PassSpec]:
    """The denoising guides' passes, when the view layer stores denoising data."""
    cycles = getattr(view_layer, "cycles", None)
    return list(DENOISING_PASSES) if getattr(cycles, "denoising_store_passes", False) else []


def register_passes(engine, scene, view_layer) -> None:
    """``RenderEngine.update_render_passes``: the Combined pass and the enabled ones Glint
    writes, so the compositor and multilayer EXRs see them."""
    engine.register_pass(scene, view_layer, "Combined", 4, "RGBA", 'COLOR')
    for spec in enabled_passes(view_layer) + denoising_passes(view_layer):
        engine.register_pass(scene, view_layer, spec.name, len(spec.channel_ids),
                             spec.channel_ids, spec.kind)


def pass_warning(view_layer):
    """One warning naming every enabled pass of the view layer that Glint leaves out, or None."""
    missing = [label for flag, label in UNSUPPORTED_PASSES.items()
               if getattr(view_layer, flag, False)]
    missing += [f"AOV '{aov.name}'" for aov in getattr(view_layer, "aovs", ())]
    missing += [f"light group '{group.name}'" for group in getattr(view_layer, "lightgroups", ())]
    if not missing:
        return None
    return (f"view layer '{view_layer.name}': Glint does not produce these passes, which stay "
            f"empty: {', '.join(missing)}")


def _object_name(entry_name: str) -> str:
    """The Blender object a core scene entry was exported from: entries of instances are
    named "object (instanced by parent)", sets of instances "object (N instances)"."""
    return re.sub(r" \((instanced by .*|\d+ instances)\)$", "", entry_name or "")


def _material_key(entry):
    """A dict key for a material table entry: the entry, or, for one that holds arrays (a
    shader program, textures), its text, which equal exports share."""
    try:
        hash(entry)
    except TypeError:
        return repr(entry)
    return entry


def scene_pass_indices(scene) -> tuple[np.ndarray, np.ndarray]:
    """(object pass index per scene entry (E,), material pass index per material table entry
    (M,)), float32, for ``core.passes``' primitive and material ids.

    An entry's object is found by the name the export gave it (a mesh shared by several
    objects is one entry, named after the first of them, whose Object Index it gets).  A
    material table entry's Blender material is the one that exports to the same values
    (``export_material``), or Blender's default surface (pass index 0)."""
    import bpy

    from ..export.materials import export_material

    objects = [bpy.data.objects.get(_object_name(name)) for name in entry_names(scene)]
    object_index = [obj.pass_index if obj is not None else 0 for obj in objects]
    by_values = {}
    for material in bpy.data.materials:
        if material.users and material.pass_index:
            try:
                by_values.setdefault(_material_key(export_material(material)[0]),
                                     material.pass_index)
            except Exception:  # an invalid material fails the export itself, not here
                continue
    material_index = [by_values.get(_material_key(entry), 0)
                      for entry in material_entries(scene)]
    return np.asarray(object_index, np.float32), np.asarray(material_index, np.float32)


def pass_pixels(primary, specs, object_index, material_index, sources, region) -> dict:
    """{pass name: (h * w * channels,) float32} of the render region (x0, y0, x1, y1, rows
    from the bottom) for Blender's result: rows from the bottom.  sources: the scene entry of
    each primitive (``core.passes.primitive_sources``)."""
    height = primary.depth.shape[0]
    x0, y0, x1, y1 = region
    rows = slice(height - y1, height - y0)

    def region_of(array):
        return array[rows, x0:x1][::-1]

    def lookup(ids, table):
        hit = ids >= 0
        if not len(table):
            return np.zeros(ids.shape)
        return np.where(hit, table[np.where(hit, ids, 0)], 0.0)

    primitive = region_of(primary.primitive)
    entries = np.where(primitive >= 0, sources[np.maximum(primitive, 0)], -1) \
        if len(sources) else primitive
    values = {
        "Depth": lambda: region_of(primary.depth),
        "Position": lambda: region_of(primary.position),
        "Normal": lambda: region_of(primary.normal),
        "Object Index": lambda: lookup(entries, object_index),
        "Material Index": lambda: lookup(region_of(primary.material), material_index),
        "Emission": lambda: region_of(primary.emission),
    }
    return {spec.name: np.ascontiguousarray(values[spec.name](), np.float32).reshape(-1)
            for spec in specs}
