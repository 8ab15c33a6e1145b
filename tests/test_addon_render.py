"""The add-on in Blender: registration, the Render button (operator), the render engine (F12,
animation), the Image datablock, colour management, and failure handling."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest

from addon_support import (add_camera, add_point_light, add_sphere, add_world, animate_small_sphere,
                           core, core_image, cube_mesh, depsgraph, empty_file, glint, link,
                           prepare_job, read_png, simple_scene, to_rgba8)
from glint.addon.compat import new_material, set_file_format  # noqa: E402
from glint.addon.engine.base import GlintRenderEngine
from glint.addon.ui import compatible_panels
from glint.addon.engine.job import ThreadedRender
from glint.addon.utils.image import COLOUR_SPACE, read_image

IMAGE = "Glint Render"


def render_button():
    """Press the Render button the way a script does (execute, synchronous)."""
    return bpy.ops.glint.render()


def glint_image():
    return read_image(bpy.data.images[IMAGE])


def f12(tmp_path, name="f12.png", **render_kwargs):
    """Render with the Glint engine through Blender's own render operator and read the PNG
    Blender saved."""
    scene = bpy.context.scene
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / name)
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.render.image_settings.color_depth = '8'
    bpy.ops.render.render(write_still=True, **render_kwargs)
    return read_png(str(tmp_path / name))


# --- registration -----------------------------------------------------------------------------

def engine_available() -> bool:
    """Whether 'GLINT' can be chosen as the render engine (the engine enum is dynamic)."""
    render = bpy.context.scene.render
    previous = render.engine
    try:
        render.engine = 'GLINT'
    except TypeError:
        return False
    render.engine = previous
    return True


def test_register_unregister_register_again():
    panels = compatible_panels()
    assert panels and all('GLINT' in panel.COMPAT_ENGINES for panel in panels)
    assert 'GLINT' in bpy.types.RENDER_PT_format.COMPAT_ENGINES
    assert 'GLINT' in bpy.types.EEVEE_MATERIAL_PT_context_material.COMPAT_ENGINES

    glint.unregister()
    try:
        assert not engine_available()
        assert not hasattr(bpy.types.Scene, "glint")
        assert not hasattr(bpy.types.Material, "glint")
        assert not hasattr(bpy.ops.glint, "render") or not _operator_registered()
        assert not any('GLINT' in panel.COMPAT_ENGINES for panel in panels)
        assert not GlintRenderEngine.is_registered
    finally:
        glint.register()

    assert engine_available() and GlintRenderEngine.is_registered
    assert _operator_registered()
    assert all('GLINT' in panel.COMPAT_ENGINES for panel in panels)
    simple_scene()
    assert bpy.context.scene.glint.image_name == IMAGE
    assert render_button() == {'FINISHED'}


def _operator_registered() -> bool:
    try:
        bpy.ops.glint.render.get_rna_type()
        return True
    except KeyError:
        return False


def test_panels_and_engine_follow_blenders_conventions():
    assert GlintRenderEngine.bl_idname == "GLINT" and GlintRenderEngine.bl_label == "Glint"
    assert bpy.types.GLINT_OT_render.bl_idname == "glint.render"
    assert bpy.ops.glint.render.idname() == "GLINT_OT_render"
    assert bpy.types.GLINT_PT_render.COMPAT_ENGINES == {'GLINT'}
    assert bpy.types.GLINT_PT_sidebar.bl_category == "Glint"
    assert bpy.types.GLINT_PT_sidebar.bl_space_type == 'VIEW_3D'
    assert bpy.types.GLINT_PT_material.bl_context == "material"
    settings = bpy.context.scene.glint
    for name, items in [("anti_aliasing", {'OFF', 'FIXED', 'ADAPTIVE'}),
                        ("precision", {'AUTO', 'FLOAT64', 'FLOAT32'}),
                        ("semantics", {'DEFAULT', 'ARTICLE'})]:
        enum = settings.bl_rna.properties[name].enum_items
        assert {item.identifier for item in enum} == items


# --- the Render button and the Image ----------------------------------------------------------

def test_the_render_button_writes_the_cores_pixels_into_a_float_non_color_image():
    simple_scene()

    assert render_button() == {'FINISHED'}

    image = bpy.data.images[IMAGE]
    assert image.is_float and image.source == 'GENERATED'
    assert image.colorspace_settings.name == COLOUR_SPACE
    assert tuple(image.size) == (64, 48)
    expected = core_image()
    np.testing.assert_array_equal(glint_image(), expected)
    assert (expected[..., 3] == 1).all()  # Film > Transparent is off
    # Not a blank image: both spheres and the background are in it.
    assert len(np.unique(to_rgba8(expected).reshape(-1, 4), axis=0)) > 20


def test_rendering_twice_updates_the_same_image_in_place_and_resizes_it():
    scene = simple_scene()
    render_button()
    image = bpy.data.images[IMAGE]
    pointer = image.as_pointer()

    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    bpy.data.objects["small"].location.x -= 0.5
    assert render_button() == {'FINISHED'}

    assert [i.name for i in bpy.data.images if i.name.startswith(IMAGE)] == [IMAGE]
    assert bpy.data.images[IMAGE].as_pointer() == pointer
    assert tuple(bpy.data.images[IMAGE].size) == (40, 30)
    np.testing.assert_array_equal(glint_image(), core_image())


def test_the_image_name_setting_picks_the_image():
    scene = simple_scene()
    scene.glint.image_name = "My Render"
    render_button()
    assert "My Render" in bpy.data.images and IMAGE not in bpy.data.images


def test_an_image_loaded_from_a_file_is_never_overwritten(tmp_path):
    simple_scene()
    path = str(tmp_path / "photo.png")
    photo = bpy.data.images.new("photo", 4, 4)
    photo.filepath_raw, photo.file_format = path, 'PNG'
    photo.save()
    loaded = bpy.data.images.load(path)
    bpy.context.scene.glint.image_name = loaded.name

    with pytest.raises(RuntimeError, match="file image, which Glint does not overwrite"):
        render_button()
    assert tuple(loaded.size) == (4, 4)


def test_a_failed_render_leaves_the_previous_image_intact():
    scene = simple_scene()
    render_button()
    before = glint_image()

    camera = scene.camera
    scene.camera = None
    with pytest.raises(RuntimeError, match="has no camera"):
        render_button()
    scene.camera = camera
    camera.data.type = 'PANO'
    with pytest.raises(RuntimeError, match="panoramic"):
        render_button()

    np.testing.assert_array_equal(glint_image(), before)


def test_a_cancelled_render_stops_and_produces_no_image():
    simple_scene()
    job = prepare_job(depsgraph())
    fractions = []

    class CancelAfterFirstTile(ThreadedRender):
        def _progress(self, fraction):
            super()._progress(fraction)
            fractions.append(fraction)
            self.cancel()

    job.settings = core.RenderSettings(tile_size=8, threads=1, anti_aliasing="off")
    worker = CancelAfterFirstTile.of_job(job)
    assert worker.wait(timeout=60)

    assert worker.cancelled and worker.result is None and worker.error is None
    assert len(fractions) == 1 and fractions[0] < 1.0


def test_the_threaded_render_gives_the_same_image_as_a_direct_one():
    simple_scene()
    worker = ThreadedRender.of_job(prepare_job(depsgraph()))
    assert worker.wait(timeout=60)
    assert worker.error is None and not worker.cancelled and worker.fraction == 1.0
    np.testing.assert_array_equal(worker.result.image, core_image())


def test_undo_after_a_render():
    scene = simple_scene()
    bpy.ops.ed.undo_push(message="scene ready")
    render_button()
    bpy.data.objects["small"].location.x = 5.0
    bpy.ops.ed.undo_push(message="moved")

    bpy.ops.ed.undo()

    # Undo restores the data (the object is back) and leaves Glint working: settings are
    # still there and the next render reflects the restored scene.
    assert bpy.data.objects["small"].location.x == pytest.approx(1.2)
    assert bpy.context.scene.glint.image_name == IMAGE
    assert render_button() == {'FINISHED'}
    np.testing.assert_array_equal(glint_image(), core_image())
    del scene  # the pre-undo Python reference is stale; nothing of Glint kept one either


def test_a_scene_without_spheres_renders_the_background_with_a_warning():
    empty_file()
    add_camera()
    add_point_light()
    add_world("grey", (0.2, 0.2, 0.2))

    job = prepare_job(depsgraph())
    assert any("no sphere" in w for w in job.warnings)
    assert render_button() == {'FINISHED'}

    # Scene-linear: the world's radiance itself (Blender's view transform encodes it).
    np.testing.assert_allclose(glint_image()[..., :3], 0.2, atol=1e-6)


def test_a_scene_without_light_renders_ambient_only_with_a_warning():
    scene = simple_scene()
    bpy.data.objects.remove(bpy.data.objects["light"])
    add_world("grey", (0.5, 0.5, 0.5))

    job = prepare_job(depsgraph())
    assert any("no light" in w for w in job.warnings)
    scene.glint.samples, scene.glint.use_adaptive_sampling = 64, False
    scene.update_tag()
    assert render_button() == {'FINISHED'}

    material = job.scene.spheres[0].material
    # The big sphere's centre (facing the camera), lit by the world only: albedo x world
    # plus the rough glossy lobe's Fresnel at normal incidence x world.
    expected = (np.asarray(material.diffuse) + np.asarray(material.specular_f0)) * 0.5
    # Path traced with 64 samples, a 5 x 5 patch there: its mean moved by 0.4 % between
    # seeds, and 1,024 samples converge 0.1 % below the closed form: 1 %.
    patch = glint_image()[22:27, 30:35, :3].mean(axis=(0, 1))
    np.testing.assert_allclose(patch, expected, rtol=0.01)
    # The Whitted integrator lights a point by the world in closed form: the centre itself.
    scene.glint.integrator = 'WHITTED'
    scene.update_tag()
    assert render_button() == {'FINISHED'}
    np.testing.assert_allclose(glint_image()[24, 32, :3], expected, rtol=2e-3)


def test_a_non_sphere_mesh_is_rendered_as_its_triangles():
    simple_scene()
    without = core_image()
    box = link(bpy.data.objects.new("box", cube_mesh("box", 0.5)))
    box.location = (-1.5, 0.0, 0.0)

    job = prepare_job(depsgraph())
    assert not any("box" in w for w in job.warnings)
    assert [mesh.name for mesh in job.scene.meshes] == ["box"]
    assert render_button() == {'FINISHED'}
    changed = np.flatnonzero((glint_image() != without).any(axis=2).any(axis=0))
    # The box sits left of the spheres, at x = -1.5, where only the background was.  (Its
    # reflection and shadow change pixels elsewhere too.)
    assert len(changed) and changed.min() < glint_image().shape[1] // 4


# --- the render engine ------------------------------------------------------------------------

def saved_button_image(tmp_path, name="button.png"):
    """The Render button's Image as Blender saves it (Image > Save As with the scene's
    colour management, i.e. ``save_render``), read back as (H, W, 4) uint8."""
    path = tmp_path / name
    bpy.data.images[IMAGE].save_render(str(path), scene=bpy.context.scene)
    return read_png(str(path))


def lit_scene():
    """simple_scene with the light in front, so most pixels are lit and some are bright."""
    scene = simple_scene()
    bpy.data.objects["light"].location = (-4.0, -6.0, 3.0)
    bpy.data.lights["light"].energy = 3000.0
    return scene


@pytest.mark.parametrize("view_transform, look, exposure",
                         [("Standard", "None", 0.0), ("AgX", "None", 0.0),
                          ("AgX", "AgX - Punchy", 0.5)])
def test_f12_and_the_render_button_give_the_same_pixels_under_any_view_transform(
        tmp_path, view_transform, look, exposure):
    scene = lit_scene()
    scene.view_settings.view_transform = view_transform
    scene.view_settings.look = look
    scene.view_settings.exposure = exposure
    render_button()

    saved, button = f12(tmp_path), saved_button_image(tmp_path)

    assert saved.shape == (48, 64, 4)
    np.testing.assert_array_equal(saved, button)


def test_the_render_result_is_unclipped_scene_linear_radiance():
    lit_scene()
    render_button()
    image = glint_image()
    # A specular highlight of a 3 kW light is far above display white.
    assert image[..., :3].max() > 1.2
    np.testing.assert_array_equal(image, core_image())


def test_an_exr_render_keeps_values_above_one(tmp_path):
    scene = lit_scene()
    scene.render.engine = 'GLINT'
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.filepath = str(tmp_path / "frame.exr")
    bpy.ops.render.render(write_still=True)
    saved = bpy.data.images.load(str(tmp_path / "frame.exr"))
    pixels = read_image(saved)
    bpy.data.images.remove(saved)
    np.testing.assert_allclose(pixels, core_image(), rtol=1e-6, atol=1e-7)
    assert pixels[..., :3].max() > 1.2


def test_under_standard_the_saved_image_is_the_srgb_encoding_of_the_radiance(tmp_path):
    lit_scene()
    render_button()
    expected = to_rgba8(np.concatenate(
        [glint.addon.utils.colour.linear_to_srgb(np.clip(glint_image()[..., :3], 0, 1)),
         glint_image()[..., 3:]], axis=2))
    assert np.abs(saved_button_image(tmp_path).astype(int) - expected.astype(int)).max() <= 1


def test_f12_with_an_other_view_transform_is_colour_managed(tmp_path):
    scene = lit_scene()
    standard = f12(tmp_path, "standard.png")
    scene.view_settings.view_transform = 'AgX'
    agx = f12(tmp_path, "agx.png")
    # Scene-linear output: Blender's view transform applies, as with any engine; AgX
    # compresses the highlights Standard clips.
    assert np.abs(standard.astype(int) - agx.astype(int)).max() > 10


def test_f12_errors_are_reported_and_nothing_is_written(tmp_path):
    scene = simple_scene()
    scene.camera.data.type = 'PANO'
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "none.png")
    with pytest.raises(RuntimeError, match="'camera' is panoramic"):
        bpy.ops.render.render(write_still=True)
    assert not os.listdir(tmp_path)


def test_f12_renders_the_camera_view_of_objects_hidden_in_render(tmp_path):
    simple_scene()
    without = f12(tmp_path, "without.png")
    hidden = add_sphere("hidden", (-1.5, 0.0, 0.0), 0.5)
    hidden.hide_render = True

    assert np.array_equal(f12(tmp_path, "hidden.png"), without)
    hidden.hide_render = False
    assert not np.array_equal(f12(tmp_path, "shown.png"), without)


def test_animation_renders_every_frame(tmp_path):
    scene = simple_scene()
    animate_small_sphere(2)
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.engine = 'GLINT'
    scene.render.filepath = str(tmp_path / "frame_")
    scene.render.image_settings.file_format = 'PNG'

    bpy.ops.render.render(animation=True)

    frames = sorted(os.listdir(tmp_path))
    assert frames == ["frame_0001.png", "frame_0002.png"]
    first, second = (read_png(str(tmp_path / name)) for name in frames)
    assert not np.array_equal(first, second)


def test_transparent_film_gives_coverage_alpha_and_removes_the_background(tmp_path):
    scene = simple_scene()
    add_world("blue", (0.1, 0.2, 0.6))
    scene.render.film_transparent = True

    render_button()
    image = glint_image()
    raw = glint.core.render(prepare_job(depsgraph()).scene,
                            prepare_job(depsgraph()).settings).image

    np.testing.assert_array_equal(image[..., 3], raw[..., 3])
    missed = raw[..., 3] == 0
    assert missed.any() and (~missed).any()
    assert (image[missed] == 0).all()
    np.testing.assert_allclose(image[~missed], raw[~missed], atol=1e-6)

    saved = f12(tmp_path)
    np.testing.assert_array_equal(saved[..., 3], to_rgba8(image)[..., 3])
    np.testing.assert_array_equal(saved, saved_button_image(tmp_path))


@pytest.mark.parametrize("integrator", ["PATH", "WHITTED"])
def test_anti_aliased_edges_survive_transparency(integrator):
    """Partly covered pixels keep their partial alpha: the path integrator's pixel filter,
    the Whitted integrator's adaptive anti-aliasing."""
    scene = simple_scene()
    scene.render.film_transparent = True
    scene.glint.integrator = integrator
    scene.glint.anti_aliasing = 'ADAPTIVE'
    scene.glint.samples = 8

    render_button()
    image = glint_image()

    partial = (image[..., 3] > 0) & (image[..., 3] < 1)
    assert partial.any()
    # Premultiplied: no colour channel exceeds the coverage.
    assert (image[..., :3] <= image[..., 3:4] + 1e-6).all()


def test_path_traced_frames_are_denoised_by_default_and_lose_their_grain():
    """Glint's Denoise option is on in a new file (``addon_support`` turns it off for the
    other tests): a path-traced frame is denoised with OIDN, which brings 16 samples of a
    ball under a grey sky closer to 1,024 samples than the 16 samples themselves; the
    Whitted integrator's frames are not denoised."""
    from glint.addon.utils.denoise import available

    assert type(bpy.context.scene.glint).bl_rna.properties["use_denoising"].default
    assert available()       # Open Image Denoise, beside the bpy module's libraries
    scene = simple_scene()
    add_world("grey", (0.5, 0.5, 0.5))
    scene.glint.use_adaptive_sampling = False
    scene.glint.samples = 1024
    scene.update_tag()
    reference = prepare_job(depsgraph()).run(passes=True)
    scene.glint.samples, scene.glint.use_denoising = 16, True
    scene.update_tag()
    job = prepare_job(depsgraph())
    assert job.denoise
    denoised = job.run()
    job.denoise = False
    noisy = job.run()
    assert denoised.denoised and not noisy.denoised
    # The big ball's pixels 3 in from its rim, where the grain is the sampling's alone (its
    # rim mixes it with the edge, which OIDN keeps sharp rather than smooth).
    inside = reference.passes.primitive == 0
    for _ in range(3):
        inside[1:-1, 1:-1] &= (inside[:-2, 1:-1] & inside[2:, 1:-1]
                               & inside[1:-1, :-2] & inside[1:-1, 2:])
    assert inside.sum() > 300

    def error(result):
        return np.sqrt(np.mean((result.image - reference.image)[inside, :3] ** 2))

    # (Measured: 0.60 times the noisy frame's error.)
    assert error(denoised) < 0.75 * error(noisy)
    np.testing.assert_array_equal(denoised.image[..., 3], noisy.image[..., 3])
    scene.glint.integrator = 'WHITTED'
    scene.update_tag()
    assert not prepare_job(depsgraph()).denoise


@pytest.mark.parametrize("crop", [True, False])
def test_a_render_region_holds_that_part_of_the_full_frame(tmp_path, crop):
    scene = simple_scene()
    full = f12(tmp_path, "full.png")
    render = scene.render
    render.use_border, render.use_crop_to_border = True, crop
    render.border_min_x, render.border_max_x = 0.3, 0.8
    render.border_min_y, render.border_max_y = 0.25, 0.9

    region = f12(tmp_path, "region.png")

    # Blender's pixels: x in [int(0.3 * 64), int(0.8 * 64)), rows from the bottom likewise.
    x0, x1, y0, y1 = 19, 51, 12, 43
    top, bottom = 48 - y1, 48 - y0
    if crop:
        np.testing.assert_array_equal(region, full[top:bottom, x0:x1])
    else:
        np.testing.assert_array_equal(region[top:bottom, x0:x1], full[top:bottom, x0:x1])
        outside = np.ones(full.shape[:2], bool)
        outside[top:bottom, x0:x1] = False
        assert (region[outside] == 0).all()


# --- the interactive path, driven without a window ----------------------------------------
# Headless Blender has no event loop, so the modal operator's methods are driven directly:
# the same code a window runs, with recorded stand-ins for the window manager and events.

class RecordingWindowManager:
    def __init__(self):
        self.calls = []

    def progress_update(self, value):
        self.calls.append(("progress_update", value))

    def progress_end(self):
        self.calls.append(("progress_end",))

    def event_timer_remove(self, timer):
        self.calls.append(("event_timer_remove", timer))


class ModalDriver:
    """A stand-in for the operator instance, using GLINT_OT_render's own methods."""

    modal = bpy.types.GLINT_OT_render.modal
    _stop_modal = bpy.types.GLINT_OT_render._stop_modal
    _store = bpy.types.GLINT_OT_render._store
    _running = True

    def __init__(self, job, worker):
        self._job, self._worker, self._image_name = job, worker, IMAGE
        self._timer, self._start = object(), 0.0
        self.reports = []

    def report(self, kinds, message):
        self.reports.append((set(kinds), message))

    def event(self, kind, value='PRESS'):
        return type("Event", (), {"type": kind, "value": value, "timer": self._timer})()


def test_modal_render_reports_progress_and_writes_the_image_when_done():
    simple_scene()
    render_button()
    before = glint_image()
    bpy.data.objects["small"].location.x -= 0.5
    job = prepare_job(depsgraph())
    driver = ModalDriver(job, ThreadedRender.of_job(job))
    context = type("Context", (), {"window_manager": RecordingWindowManager()})()
    driver._worker.wait(timeout=60)

    assert driver.modal(context, driver.event('MOUSEMOVE')) == {'PASS_THROUGH'}
    assert driver.modal(context, driver.event('TIMER')) == {'FINISHED'}

    calls = context.window_manager.calls
    assert ("progress_update", 100) in calls and ("progress_end",) in calls
    assert ("event_timer_remove", driver._timer) in calls
    np.testing.assert_array_equal(glint_image(), core_image())
    assert not np.array_equal(glint_image(), before)
    assert driver.reports[-1][0] == {'INFO'}


def test_modal_render_cancelled_with_esc_keeps_the_previous_image():
    scene = simple_scene()
    render_button()
    before = glint_image()
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    job = prepare_job(depsgraph())
    job.settings = core.RenderSettings(tile_size=8, threads=1, anti_aliasing="fixed",
                                       samples=64)
    driver = ModalDriver(job, ThreadedRender.of_job(job))
    context = type("Context", (), {"window_manager": RecordingWindowManager()})()

    assert driver.modal(context, driver.event('ESC')) == {'RUNNING_MODAL'}
    assert driver._worker.wait(timeout=60)
    assert driver.modal(context, driver.event('TIMER')) == {'CANCELLED'}

    assert driver._worker.cancelled
    np.testing.assert_array_equal(glint_image(), before)
    kinds, message = driver.reports[-1]
    assert kinds == {'WARNING'} and "cancelled" in message and IMAGE in message


class RecordingLayout:
    """Records what a panel draws, checking every property it names exists."""

    def __init__(self):
        self.drawn, self.operators = [], []
        self.use_property_split = self.use_property_decorate = self.active = None

    def column(self, **_):
        return self

    row = column

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, f"{data} has no property {name!r}"
        self.drawn.append(name)

    def operator(self, idname, **_):
        category, name = idname.split(".")
        getattr(getattr(bpy.ops, category), name).get_rna_type()
        self.operators.append(idname)

    def label(self, **_):
        pass


def test_panels_draw_the_settings_and_the_render_button():
    scene = simple_scene()
    layout = RecordingLayout()
    glint.addon.ui.draw_render_settings(layout, scene)
    assert {"semantics", "precision", "max_depth", "anti_aliasing", "samples",
            "light_samples", "world_samples", "film_transparent",
            "image_name"} <= set(layout.drawn)
    assert layout.operators == ["glint.render"]

    material = new_material("m")
    panel = type("Panel", (), {"layout": RecordingLayout()})()
    context = type("Context", (), {"material": material})()
    bpy.types.GLINT_PT_material.draw_header(panel, context)
    bpy.types.GLINT_PT_material.draw(panel, context)
    assert panel.layout.drawn == ["use_custom", "ambient", "diffuse", "specular", "shininess",
                                  "reflection"]


def test_the_image_is_shown_in_an_open_image_editor():
    simple_scene()
    area = max(bpy.context.window.screen.areas, key=lambda a: a.width * a.height)
    area.type = 'IMAGE_EDITOR'

    render_button()

    assert area.spaces.active.image == bpy.data.images[IMAGE]


# --- view layers ------------------------------------------------------------------------------

def test_each_view_layer_renders_its_own_visibility_into_its_own_layer(tmp_path):
    from exr import read_exr

    scene = simple_scene()
    extra = bpy.data.collections.new("extra")
    scene.collection.children.link(extra)
    small = bpy.data.objects["small"]
    scene.collection.objects.unlink(small)
    extra.objects.link(small)
    scene.view_layers[0].name = "Everything"
    without = scene.view_layers.new("Without small")
    without.layer_collection.children["extra"].exclude = True
    scene.render.use_single_layer = False
    scene.render.engine = 'GLINT'
    settings = scene.render.image_settings
    set_file_format(settings, 'OPEN_EXR_MULTILAYER')
    settings.exr_codec, settings.color_depth = 'NONE', '32'
    scene.render.filepath = str(tmp_path / "layers.exr")

    bpy.ops.render.render(write_still=True)

    planes = read_exr(tmp_path / "layers.exr")
    layers = {layer: np.stack([planes[f"{layer}.Combined.{c}"] for c in "RGBA"], axis=-1)
              for layer in ("Everything", "Without small")}
    # Each layer is what the core renders of that layer's objects (scene-linear in the EXR).
    everything = core_image()
    scene.collection.children.unlink(extra)
    alone = core_image()
    linear = prepare_job(depsgraph()).scene_linear
    np.testing.assert_allclose(layers["Everything"], linear(everything), atol=1e-6)
    np.testing.assert_allclose(layers["Without small"], linear(alone), atol=1e-6)
    assert not np.allclose(layers["Everything"], layers["Without small"], atol=1e-3)


# --- position and unit ------------------------------------------------------------------------

def _scaled_simple_scene(scale, offset=(0.0, 0.0, 0.0), sun=False):
    """simple_scene with a soft light (a sun, or the point light with its power times scale^2,
    since its irradiance falls off as power / d^2), everything (objects, light radius, clip
    planes) moved by offset and scaled by ``scale``; Blender stores these in float32."""
    scene = simple_scene()
    light = bpy.data.objects["light"]
    if sun:
        # A sun's irradiance does not depend on distances: nothing to rescale.
        light.data.type = 'SUN'
        light.data.energy, light.data.angle = 3.0, 0.2   # soft shadows at any scale
        light.rotation_euler = (0.6, 0.3, 0.0)
    else:
        light.data.shadow_soft_size = 0.5 * scale
        light.data.energy *= scale ** 2
    for obj in bpy.data.objects:
        obj.location = [(c + o) * scale for c, o in zip(obj.location, offset)]
        if obj.type == 'MESH':
            obj.scale = (scale,) * 3
    camera = scene.camera.data
    camera.clip_start, camera.clip_end = 0.1 * scale, min(100.0 * scale, 3e38)
    return core_image()


@pytest.mark.parametrize("sun, scale", [(True, s) for s in (1e-5, 1e-3, 1e10, 1e20, 1e36)]
                         + [(False, s) for s in (1e-5, 1e-3, 1e3, 1e6)])
def test_a_blender_scene_renders_the_same_at_any_position_and_scale(sun, scale):
    """Over the range Blender's own data allows: its camera's clip_start is at least 1e-6
    (below 1e-5 the camera clips the scene away, in Blender too) and it stores float32, whose
    largest value (3.4e38) bounds the large end: a sun (no distance falloff) over all of it; a
    point light, whose power must grow as scale^2, up to validation's 1e15 W
    (core.validation.MAX_COLOUR x 1000)."""
    reference = _scaled_simple_scene(1.0, sun=sun)
    image = _scaled_simple_scene(scale, offset=(100.0, -50.0, 30.0), sun=sun)
    moved = np.abs(image - reference).max(axis=2) > 1 / 255
    assert moved.mean() < 0.002, f"{moved.sum()} pixels differ"
