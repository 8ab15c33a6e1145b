"""Glint's settings, stored in the .blend: ``Scene.glint`` (how to render) and
``Material.glint`` (the article's five material parameters, when typed in directly)."""

from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty, StringProperty)

from ..core import Material, RenderSettings
from ..core.choices import (ANTI_ALIASING_CHOICES, INTEGRATOR_CHOICES, PARALLELISM_CHOICES,
                            PRECISION_CHOICES, SEMANTICS_CHOICES)
from ..core.validation import MAX_COLOUR, MAX_DEPTH, MAX_LIGHT_SAMPLES, MAX_SAMPLES, MAX_SHININESS

DEFAULT_IMAGE_NAME = "Glint Render"
_ARTICLE_FLOOR = Material()  # the core's default material is the article's floor


def enum_items(choices) -> list[tuple[str, str, str]]:
    """EnumProperty items of one of the core's choice lists (``core.choices``): identifiers
    are the values in upper case, as .blend files store them; ``render_settings`` lowers
    them back."""
    return [(value.upper(), label, description) for value, label, description in choices]


class GlintRenderSettings(bpy.types.PropertyGroup):
    integrator: EnumProperty(
        name="Integrator", default=RenderSettings.integrator.upper(),
        items=enum_items(INTEGRATOR_CHOICES),
        description="How light is followed; Path Tracing follows the scene's Light Paths "
                    "(Cycles' settings)")
    use_adaptive_sampling: BoolProperty(
        name="Noise Threshold", default=True,
        description="Stop sampling a pixel once its noise is below the threshold, as Cycles' "
                    "adaptive sampling does")
    noise_threshold: FloatProperty(
        name="Noise Threshold", default=0.01, min=0.001, max=1.0, precision=3,
        description="Noise level at which a pixel stops taking samples (Cycles' meaning)")
    adaptive_min_samples: IntProperty(
        name="Min Samples", default=0, min=0, max=MAX_SAMPLES,
        description="Samples every pixel takes before the noise threshold may stop it; 0 "
                    "chooses from the threshold")
    time_limit: FloatProperty(
        name="Time Limit", default=0.0, min=0.0, subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE',
        description="Stop adding samples after this many seconds (0: no limit)")
    use_denoising: BoolProperty(
        name="Denoise", default=True,
        description="Denoise the final image with Open Image Denoise (Blender's own library), "
                    "guided by the first hits' albedo and normal")
    viewport_samples: IntProperty(
        name="Viewport Samples", default=16, min=1, soft_max=256, max=MAX_SAMPLES,
        description="Samples per pixel the viewport refines to")
    seed: IntProperty(
        name="Seed", default=0, min=0, description="Seed of the sampling pattern")
    max_depth: IntProperty(
        name="Max Depth", default=3, min=1, soft_max=16, max=MAX_DEPTH,
        description="Bounces per path; the camera ray's hit counts as the first (the article "
                    "uses 3)")
    anti_aliasing: EnumProperty(
        name="Anti-Aliasing", default='ADAPTIVE', items=enum_items(ANTI_ALIASING_CHOICES))
    # (4 path samples denoised reach a given error against Cycles' converged image sooner
    # than 8 or 16: docs/performance.md, "Samples".)
    samples: IntProperty(
        name="Samples", default=4, min=1, soft_max=256, max=MAX_SAMPLES,
        description="Samples per pixel: camera paths with Path Tracing (denoised), rays per "
                    "anti-aliased pixel with Direct")
    light_samples: IntProperty(
        name="Light Samples", default=16, min=1, soft_max=256, max=MAX_LIGHT_SAMPLES,
        description="Shadow rays per light with a radius (soft shadows, default semantics)")
    world_samples: IntProperty(
        name="World Samples", default=RenderSettings.world_samples, min=0, soft_max=64,
        max=MAX_LIGHT_SAMPLES,
        description="Rays per point towards the world, whose light they occlude (contact "
                    "shadows, default semantics); rounded up to a square, 0 leaves the "
                    "world unoccluded")
    precision: EnumProperty(
        name="Precision", default='AUTO', items=enum_items(PRECISION_CHOICES))
    semantics: EnumProperty(
        name="Semantics", default='DEFAULT', items=enum_items(SEMANTICS_CHOICES))
    parallelism: EnumProperty(
        name="Parallelism", default=RenderSettings.parallelism.upper(),
        items=enum_items(PARALLELISM_CHOICES),
        description="How tiles render at once (as many as Performance > Threads says)")
    cluster_address: StringProperty(
        name="Cluster", default="",
        description="Address of a Dask scheduler (tcp://HOST:8786 or tls://HOST:8786) whose "
                    "workers render F12's and animations' tiles; empty: this computer. Needs "
                    "dask[distributed] in Blender's Python and Glint's core on the workers")
    image_name: StringProperty(
        name="Image", default=DEFAULT_IMAGE_NAME,
        description="Image datablock the Render button writes (created if missing)")


class GlintMaterialSettings(bpy.types.PropertyGroup):
    use_custom: BoolProperty(
        name="Custom", default=False,
        description="Use these values instead of the ones derived from the material's "
                    "Principled BSDF or Viewport Display")
    ambient: FloatVectorProperty(
        name="Ambient", subtype='COLOR_GAMMA', size=3, min=0.0, soft_max=1.0, max=MAX_COLOUR,
        default=_ARTICLE_FLOOR.ambient, description="Reflectance of ambient light (ka)")
    diffuse: FloatVectorProperty(
        name="Diffuse", subtype='COLOR_GAMMA', size=3, min=0.0, soft_max=1.0, max=MAX_COLOUR,
        default=_ARTICLE_FLOOR.diffuse, description="Diffuse reflectance (kd)")
    specular: FloatVectorProperty(
        name="Specular", subtype='COLOR_GAMMA', size=3, min=0.0, soft_max=1.0, max=MAX_COLOUR,
        default=_ARTICLE_FLOOR.specular, description="Specular reflectance (ks)")
    shininess: FloatProperty(
        name="Shininess", default=_ARTICLE_FLOOR.shininess, min=0.0, soft_max=1000.0,
        max=MAX_SHININESS,
        description="Blinn-Phong exponent as the article writes it (shading uses a quarter "
                    "of it on N.H)")
    reflection: FloatProperty(
        name="Reflection", default=_ARTICLE_FLOOR.reflection, min=0.0, max=1.0,
        subtype='FACTOR', description="Mirror weight of the reflected ray")


classes = (GlintRenderSettings, GlintMaterialSettings)


def register_pointers():
    bpy.types.Scene.glint = PointerProperty(type=GlintRenderSettings, name="Glint")
    bpy.types.Material.glint = PointerProperty(type=GlintMaterialSettings, name="Glint")


def unregister_pointers():
    del bpy.types.Material.glint
    del bpy.types.Scene.glint
