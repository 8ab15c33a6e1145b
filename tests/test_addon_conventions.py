"""Blender conventions: panels, the Render button exporting what F12 exports, thread settings,
the one warning about ignored scene settings, a .blend whose engine is GLINT."""

from __future__ import annotations

import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

from addon_support import (RENDER_SCRIPT, REPOSITORY, add_sphere, add_world, depsgraph, glint,
                           link, prepare_job, read_image, read_png, simple_scene, to_rgba8)
from glint.addon.compat import LIGHT_TEMPERATURE  # noqa: E402
from glint.addon.ui import compatible_panels


def glint_panels():
    """Blender's panels (not Glint's own) that show with the Glint engine."""
    return {p.__name__ for p in bpy.types.Panel.__subclasses__()
            if 'GLINT' in getattr(p, "COMPAT_ENGINES", ()) and not p.__name__.startswith("GLINT_")}


def test_one_light_panel_and_no_panels_that_do_not_apply():
    shown = glint_panels()
    light_panels = {name for name in shown if name.startswith(("DATA_PT_", "NODE_DATA_PT_"))
                    and "light" in name.lower()}
    # EEVEE's light panel (type, colour, power, radius) is the one Light panel; the others are
    # the light's context, custom properties and animation (which Blender 4.2 does not have),
    # as for every engine.
    animation = {"DATA_PT_light_animation"} & set(dir(bpy.types))
    assert light_panels == {"DATA_PT_EEVEE_light", "DATA_PT_context_light",
                            "DATA_PT_custom_props_light", *animation}
    for name in ("DATA_PT_light", "NODE_DATA_PT_light", "DATA_PT_lightprobe",
                 "DATA_PT_context_lightprobe"):
        assert name not in shown, name
    assert not any("lightprobe" in name for name in shown)
    # Unregistering takes Glint out of every panel it added itself to, shared sets included.
    glint.unregister()
    try:
        assert not glint_panels()
    finally:
        glint.register()
    assert glint_panels() == shown and all('GLINT' in p.COMPAT_ENGINES for p in compatible_panels())


class EditedFields:
    """A UILayout stand-in for a panel's ``draw``: records the property of every ``prop``
    call on ``data``; every other layout call (row, column, label, ...) gives another
    recorder, and any attribute (active, use_property_split, ...) may be set."""

    def __init__(self, data, fields):
        self._data, self._fields = data, fields

    def prop(self, data, name, *args, **kwargs):
        if data == self._data:
            self._fields.add(DERIVED_FIELDS.get(name, name))

    def template_node_view(self, tree, *args, **kwargs):
        if tree == self._data.node_tree:
            self._fields.add("nodes")

    def __getattr__(self, name):
        return lambda *args, **kwargs: EditedFields(self._data, self._fields)


class FieldsRead:
    """A light datablock seen through the exporter's eyes: records every field read."""

    def __init__(self, light):
        object.__setattr__(self, "_light", light)
        object.__setattr__(self, "fields", set())

    def __getattr__(self, name):
        self.fields.add(name)
        return getattr(self._light, name)


class PanelContext:
    """``bpy.context`` as the Properties editor's Light tab has it with Glint as the engine;
    whatever else a panel's poll asks for (context.mesh, ...) is None."""

    def __init__(self, obj):
        self.object, self.light, self.engine = obj, obj.data, 'GLINT'
        self.scene = bpy.context.scene

    def __getattr__(self, name):
        return None


def light_panels_shown(context):
    """The light panels of the Properties editor shown with Glint for ``context``: marked for
    Glint, polled true, under a parent that is shown too."""
    panels = {p.__name__: p for p in bpy.types.Panel.__subclasses__()
              if 'GLINT' in getattr(p, "COMPAT_ENGINES", ()) and p.bl_space_type == 'PROPERTIES'
              and getattr(p, "bl_context", "") == "data"}
    polled = {name for name, p in panels.items()
              if not hasattr(p, "poll") or p.poll(context)}

    def shown(name):
        parent = getattr(panels[name], "bl_parent_id", "")
        return name in polled and (not parent or (parent in panels and shown(parent)))
    return [panels[name] for name in polled if shown(name)]


#: Fields the exporter reads that Blender derives from another one, which is the one edited.
#: A light's node tree and its Use Nodes toggle are one thing to edit: its nodes.
DERIVED_FIELDS = {"temperature_color": "temperature", "node_tree": "nodes", "use_nodes": "nodes"}


@pytest.mark.parametrize("kind, shape", [("POINT", None), ("SPOT", None), ("SUN", None),
                                         ("AREA", "SQUARE"), ("AREA", "RECTANGLE"),
                                         ("AREA", "DISK"), ("AREA", "ELLIPSE")])
def test_light_panels_edit_what_the_exporter_reads_and_nothing_shown_is_ignored(kind, shape):
    """With Glint as the engine, every field of a light the exporter reads can be edited in a
    panel shown for it (Blender 4.2+ edits the spot cone only in Beam Shape, DATA_PT_spot),
    and every light panel shown edits something the exporter reads (a panel of EEVEE's
    shadow settings, say, would edit only what Glint ignores).  Panels every datablock has
    (custom properties, animation) are not about what is rendered and are left out."""
    from bl_ui import space_properties
    from rna_prop_ui import PropertyPanel

    # Blender 4.5 and later show an Animation panel (PropertiesAnimationMixin); 4.2 has none.
    common_panels = tuple(panel for panel in (
        PropertyPanel, getattr(space_properties, "PropertiesAnimationMixin", None))
        if panel is not None)

    from glint.addon.export.lights import export_article_light, export_light

    simple_scene()
    light = bpy.data.lights.new("lamp", type=kind)
    if shape is not None:
        light.shape = shape
    if LIGHT_TEMPERATURE:
        light.use_temperature = True     # so that the temperature's colour is read too
    obj = link(bpy.data.objects.new("lamp", light))
    read = FieldsRead(light)
    identity = [[float(r == c) for c in range(4)] for r in range(4)]
    export_light(read, identity, "lamp")
    export_article_light(read, identity, "lamp")
    needed = {DERIVED_FIELDS.get(name, name) for name in read.fields}

    edited = set()
    context = PanelContext(obj)
    for panel in light_panels_shown(context):
        if issubclass(panel, common_panels):
            continue
        fields = set()
        panel.draw(type("Self", (), {"layout": EditedFields(light, fields),
                                     "bl_space_type": panel.bl_space_type})(), context)
        if fields:
            assert fields & needed, f"{panel.__name__} edits only what Glint ignores: {fields}"
        edited |= fields

    assert {"type", "color", "energy"} <= needed      # the recorder sees the reads
    assert needed <= edited, f"not editable with Glint: {needed - edited}"
    if kind == 'SPOT':
        assert {"spot_size", "spot_blend"} <= needed


def particle_scene():
    """simple_scene() plus a particle system whose instance object is hidden for render."""
    scene = simple_scene()
    source = add_sphere("source", (0.0, 0.0, -30.0), 0.2)
    source.hide_render = True
    emitter = add_sphere("emitter", (0.0, -2.0, 0.0), 0.5)
    modifier = emitter.modifiers.new("particles", 'PARTICLE_SYSTEM')
    settings = modifier.particle_system.settings
    settings.count, settings.frame_start, settings.frame_end = 6, 1, 1
    settings.physics_type = 'NO'
    settings.render_type, settings.instance_object = 'OBJECT', source
    settings.particle_size = 1.0
    emitter.show_instancer_for_render = emitter.show_instancer_for_viewport = False
    scene.frame_set(2)
    return scene


@pytest.mark.slow
def test_the_render_button_renders_particle_instances_of_a_source_hidden_for_render(tmp_path):
    scene = particle_scene()
    button_scene = prepare_job(depsgraph()).scene
    instanced = [s for s in button_scene.spheres if "instanced by" in s.name] + \
        [s for s in button_scene.sphere_sets if "instance" in s.name]
    assert instanced, [s.name for s in button_scene.spheres]
    assert not any(s.name == "source" for s in button_scene.spheres)

    bpy.ops.glint.render()
    # The button's Image as Blender saves it, through the scene's colour management.
    bpy.data.images["Glint Render"].save_render(str(tmp_path / "button.png"), scene=scene)
    button = read_png(str(tmp_path / "button.png"))
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "f12.png")
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    bpy.ops.render.render(write_still=True)
    f12 = read_png(str(tmp_path / "f12.png"))
    assert np.abs(f12.astype(int) - button.astype(int)).max() <= 1


def test_blenders_thread_setting_reaches_the_core():
    scene = simple_scene()
    assert prepare_job(depsgraph()).settings.threads is None      # Auto-detect: every core
    scene.render.threads_mode, scene.render.threads = 'FIXED', 3
    assert prepare_job(depsgraph()).settings.threads == 3


def test_world_samples_reach_the_core_and_0_leaves_the_world_unoccluded():
    from glint.core import RenderSettings

    scene = simple_scene()
    add_world("grey", (0.5, 0.5, 0.5))
    scene.render.resolution_x, scene.render.resolution_y = 96, 64
    scene.glint.integrator = 'WHITTED'       # (World Samples are the Whitted integrator's)
    scene.glint.anti_aliasing = 'OFF'
    assert scene.glint.world_samples == RenderSettings.world_samples
    occluded = prepare_job(depsgraph()).run().image
    # (A script's change to an add-on's property reaches the evaluated scene once the scene
    # is tagged, for Cycles' settings as for Glint's.)
    scene.glint.world_samples = 4
    scene.update_tag()
    assert prepare_job(depsgraph()).settings.world_samples == 4
    scene.glint.world_samples = 0
    scene.update_tag()
    job = prepare_job(depsgraph())
    assert job.settings.world_samples == 0
    open_sky = job.run().image
    # The small sphere hides part of the big one's sky: only there does the image change, and
    # only by getting brighter.
    change = open_sky[..., :3] - occluded[..., :3]
    assert change.min() >= -1e-6
    assert 0 < np.count_nonzero(change.max(axis=-1) > 1e-3) < change.shape[0] * change.shape[1] / 2


def test_scene_settings_glint_ignores_are_named_in_one_warning():
    scene = simple_scene()
    assert not [w for w in prepare_job(depsgraph()).warnings if "Glint ignores" in w]
    scene.render.use_motion_blur = True
    scene.camera.data.dof.use_dof = True
    bpy.data.objects["small"].is_shadow_catcher = True
    bpy.data.objects["small"].is_holdout = True   # rendered: not named
    bpy.data.objects["big"].visible_shadow = False

    ignored = [w for w in prepare_job(depsgraph()).warnings if "Glint ignores" in w]

    assert len(ignored) == 1
    for phrase in ("motion blur", "depth of field (camera 'camera')",
                   "shadow catcher objects 'small'", "objects invisible to shadow rays 'big'"):
        assert phrase in ignored[0], phrase
    assert "holdout" not in ignored[0]
    # The article's model has no holdouts: there they are named.
    simple_scene().glint.semantics = 'ARTICLE'
    bpy.data.objects["small"].is_holdout = True
    ignored = [w for w in prepare_job(depsgraph()).warnings if "Glint ignores" in w]
    assert "holdout objects 'small' (article semantics)" in ignored[0]


@pytest.mark.slow
def test_a_blend_whose_engine_is_glint_opens_without_an_engine_error(tmp_path):
    scene = simple_scene()
    scene.render.engine = 'GLINT'
    blend = tmp_path / "glint.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)

    result = subprocess.run([sys.executable, RENDER_SCRIPT, str(blend), "--output",
                             str(tmp_path / "out.png")], capture_output=True, text=True,
                            timeout=300, cwd=REPOSITORY)

    assert result.returncode == 0, result.stderr
    assert "not available" not in result.stdout + result.stderr
    assert os.path.exists(tmp_path / "out.png")


def _alpha_rows_glint_and_cycles(scene, tmp_path, row=40):
    """Row ``row``'s alpha (w,) of the scene rendered by Glint and by Cycles (256 samples, no
    denoising, a 1-pixel box filter, so that partly covered pixels mean the same in both)."""
    def alpha_row(engine):
        scene.render.engine = engine
        scene.render.filepath = str(tmp_path / f"{engine}.png")
        scene.render.image_settings.color_mode = 'RGBA'
        bpy.ops.render.render(write_still=True)
        return read_png(str(tmp_path / f"{engine}.png"))[row, :, 3] / 255.0

    scene.cycles.samples, scene.cycles.use_denoising = 256, False
    scene.cycles.pixel_filter_type, scene.render.filter_size = 'BOX', 1.0
    return alpha_row('GLINT'), alpha_row('CYCLES')


def _partial(row):
    """How many pixels of an alpha row are partly covered."""
    return int(((row > 0.02) & (row < 0.98)).sum())


def test_each_choice_list_is_defined_once_in_the_core():
    from glint.addon.cli.arguments import parse_args as script_parse_args
    from glint.core import choices
    from glint.core.__main__ import parse_args as core_parse_args

    settings = bpy.context.scene.glint
    for prop, choice_list in (("semantics", choices.SEMANTICS_CHOICES),
                              ("precision", choices.PRECISION_CHOICES),
                              ("anti_aliasing", choices.ANTI_ALIASING_CHOICES),
                              ("parallelism", choices.PARALLELISM_CHOICES)):
        items = settings.bl_rna.properties[prop].enum_items
        assert [(i.identifier, i.name, i.description) for i in items] == [
            (value.upper(), label, text) for value, label, text in choice_list]
    # The command lines accept exactly the core's values.
    for value in choices.PRECISIONS:
        assert core_parse_args(["--output", "x.png", "--precision", value]).precision == value
    for value in choices.PARALLELISM:
        assert core_parse_args(["--output", "x.png", "--parallelism", value]).parallelism \
            == value
        assert script_parse_args(["--output", "x.png", "--parallelism", value]
                                 ).parallelism == value
    from glint.core.settings import RenderSettings
    from glint.core.validation import SceneError
    # One default everywhere: the core's.
    assert core_parse_args(["--output", "x.png"]).parallelism == RenderSettings.parallelism
    assert settings.bl_rna.properties["parallelism"].default == \
        RenderSettings.parallelism.upper()
    for value in choices.ANTI_ALIASING:
        RenderSettings(anti_aliasing=value)
    try:
        RenderSettings(anti_aliasing="sometimes")
        raise AssertionError("accepted a value outside the list")
    except SceneError as error:
        assert "'off', 'fixed', 'adaptive'" in str(error)


@pytest.mark.slow
@pytest.mark.cycles
def test_depth_of_field_is_read_as_cycles_reads_it_and_blurs_like_cycles(tmp_path):
    from addon_support import add_camera, add_point_light, empty_file

    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = 160, 80
    scene.render.film_transparent = True
    add_sphere("ball", (0.0, 0.0, 0.0), 1.0)
    add_point_light()
    cam = add_camera(location=(0.0, -10.0, 0.0))
    target = link(bpy.data.objects.new("focus", None))
    target.location = (0.0, -5.0, 3.0)            # 5 in front of the camera along its axis
    dof = cam.data.dof
    dof.use_dof, dof.focus_object, dof.aperture_fstop = True, target, 0.125
    scene.glint.anti_aliasing, scene.glint.samples = 'FIXED', 256

    exported = prepare_job(depsgraph()).scene.camera
    assert exported.aperture_radius == pytest.approx(50e-3 / (2 * 0.125))   # 0.2
    assert exported.focus_distance == pytest.approx(5.0, rel=1e-6)

    glint_alpha, cycles_alpha = _alpha_rows_glint_and_cycles(scene, tmp_path)
    # The ball's silhouette (depth about 10, focus at 5) spreads over a circle of confusion
    # of radius 0.2 * |10 - 5| / 5 = 0.2, i.e. 4.4 px (a pixel there is 10 * 0.72 / 160 =
    # 0.045 wide): both engines blur it over the same pixels.  256 samples leave about 0.03
    # of coverage noise in each; the 32 x 16 UV sphere Cycles draws sags by under 2 % of r.
    print("partial pixels glint", _partial(glint_alpha), "cycles", _partial(cycles_alpha),
          "max alpha difference", np.abs(glint_alpha - cycles_alpha).max())
    assert _partial(glint_alpha) >= 12   # both edges, about 7 px each (test_core_depth_of_field)
    assert abs(_partial(glint_alpha) - _partial(cycles_alpha)) <= 2
    assert np.abs(glint_alpha - cycles_alpha).max() < 0.15


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("fstop, focus", [(10.0, 5.0), (20.0, 2.5)])
def test_orthographic_depth_of_field_blurs_like_cycles(tmp_path, fstop, focus):
    """Cycles' orthographic lens has a radius of 1 / (2 F-stop) scene units (not lens /
    (2 F-stop)): the circle of confusion at depth z is that times |1 - z / focus|."""
    from addon_support import add_camera, add_point_light, empty_file

    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = 160, 80
    scene.render.film_transparent = True
    add_sphere("ball", (0.0, 0.0, 0.0), 1.0)
    add_point_light()
    cam = add_camera(location=(0.0, -10.0, 0.0))
    cam.data.type, cam.data.ortho_scale = 'ORTHO', 4.0      # a pixel is 0.025 wide
    dof = cam.data.dof
    dof.use_dof, dof.focus_distance, dof.aperture_fstop = True, focus, fstop
    scene.glint.anti_aliasing, scene.glint.samples = 'FIXED', 256
    radius = 1.0 / (2 * fstop)
    assert prepare_job(depsgraph()).scene.camera.aperture_radius == pytest.approx(radius)
    assert not [w for w in prepare_job(depsgraph()).warnings if "Glint ignores" in w]

    glint_alpha, cycles_alpha = _alpha_rows_glint_and_cycles(scene, tmp_path)
    # The silhouette (depth 10) blurs over a circle of radius 0.05 * |1 - 10 / 5| = 0.05
    # (an F-stop of 10) or 0.025 * |1 - 10 / 2.5| = 0.075 (an F-stop of 20): 2 or 3 pixels, so 4 or 6
    # partial pixels per edge; lens / (2 F-stop) would give under 0.2 pixel.  Tolerances as
    # for the perspective lens (test above): 256 samples leave about 0.03 of coverage noise.
    print("partial pixels glint", _partial(glint_alpha), "cycles", _partial(cycles_alpha),
          "max alpha difference", np.abs(glint_alpha - cycles_alpha).max())
    expected = 2 * 2 * radius * abs(1 - 10 / focus) / 0.025
    assert abs(_partial(cycles_alpha) - expected) <= 2
    assert abs(_partial(glint_alpha) - _partial(cycles_alpha)) <= 2
    assert np.abs(glint_alpha - cycles_alpha).max() < 0.15
