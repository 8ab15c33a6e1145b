"""The viewport's Rendered shading, tested headless as far as Blender allows.

Headless pip bpy has a 3D View with a real ``RegionView3D`` (the factory startup file's), but
no GPU context: ``gpu`` refuses to run in background mode (even ``gpu.types.Buffer`` raises
"GPU functions for drawing are not available in background mode"), so the drawing itself
(``addon.draw.viewport.FrameDrawer``) cannot run here; what it uploads (``texture_pixels``)
is tested.  Everything else the viewport does is: the view -> camera-rays mapping against
Blender's own projection (``bpy_extras.view3d_utils``, ``Object.calc_matrix_camera``), the
refinement schedule, the worker thread and its cancellation, and when a re-render starts.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import bpy
import numpy as np
import pytest
from bpy_extras import view3d_utils
from mathutils import Matrix

from addon_support import add_camera, core, depsgraph, empty_file, simple_scene
from glint.addon.draw.viewport import texture_pixels
from glint.addon.engine import viewport
from glint.addon.engine.base import GlintRenderEngine
from glint.addon.engine.job import prepare_job
from glint.addon.engine.viewport import (COARSE_PIXELS, ProgressiveRender, ViewportSession,
                                         coarse_divisor, export_viewport_scene,
                                         refinement_schedule)
from glint.addon.export.view import ViewportView, border_rect, camera_frame_rect, view_camera
from glint.addon.utils.colour import srgb_to_linear
from glint.core.camera import camera_rays


def pixel_centres(width, height, step=37.3):
    """Sample positions (xs, ys), core convention (row 0 at the top), spread over the image
    including its corner pixels."""
    xs = np.concatenate([[0.5, width - 0.5], np.arange(3.1, width, step)])
    ys = np.concatenate([[0.5, height - 0.5], np.arange(1.7, height, step * 0.61)])
    xs, ys = np.meshgrid(xs, ys)
    return xs.ravel(), ys.ravel()


def fake_region(width, height, view_matrix, window_matrix, view_perspective='PERSP'):
    """A Region and RegionView3D as ``bpy_extras.view3d_utils`` reads them."""
    view_matrix, window_matrix = Matrix(view_matrix), Matrix(window_matrix)
    region = SimpleNamespace(width=width, height=height)
    rv3d = SimpleNamespace(view_matrix=view_matrix, window_matrix=window_matrix,
                           perspective_matrix=window_matrix @ view_matrix,
                           is_perspective=window_matrix[3][3] == 0.0,
                           view_perspective=view_perspective)
    return region, rv3d


def assert_rays_reproject_onto_their_pixels(camera, region, rv3d, tolerance_px):
    """Points along each core ray, projected by Blender (location_3d_to_region_2d), land on the
    ray's pixel position."""
    xs, ys = pixel_centres(region.width, region.height)
    rays = camera_rays(camera, xs, ys)
    t_min = np.broadcast_to(rays.t_min, xs.shape)
    for k in range(0, len(xs), 7):
        for depth in (1.0, 10.0):
            origin = rays.origins[:, 0 if rays.shared_origin else k]
            point = origin + (t_min[k] + depth) * rays.directions[:, k]
            projected = view3d_utils.location_3d_to_region_2d(region, rv3d, point)
            assert projected is not None
            assert abs(projected.x - xs[k]) < tolerance_px
            assert abs(projected.y - (region.height - ys[k])) < tolerance_px


# --- the view -> camera rays -----------------------------------------------------------------

def test_the_startup_files_perspective_view_matches_view3d_utils():
    bpy.ops.wm.read_factory_settings()
    area = next(a for a in bpy.context.window.screen.areas if a.type == 'VIEW_3D')
    rv3d = area.spaces.active.region_3d
    region = next(r for r in area.regions if r.type == 'WINDOW')
    assert rv3d.is_perspective and region.width > 1000

    camera = view_camera(rv3d.view_matrix, rv3d.window_matrix, region.width, region.height)

    xs, ys = pixel_centres(region.width, region.height)
    rays = camera_rays(camera, xs, ys)
    eye = np.array(rv3d.view_matrix.inverted().translation)
    np.testing.assert_allclose(rays.origins[:, 0], eye, atol=1e-5)
    for k in range(len(xs)):
        coord = (xs[k], region.height - ys[k])
        expected = view3d_utils.region_2d_to_vector_3d(region, rv3d, coord)
        # view3d_utils unprojects a point at NDC depth -0.5 (0.013 from the eye here) in
        # float32 and subtracts the eye (18 units away): about 18 * 6e-8 / 0.013 = 1e-4 of
        # rounding in its own answer.
        np.testing.assert_allclose(rays.directions[:, k], np.array(expected), atol=3e-4)
    # Blender's float32 projection puts points along the rays back on their pixels.
    assert_rays_reproject_onto_their_pixels(camera, region, rv3d, tolerance_px=2e-3)
    # Clip planes from the projection: the startup view's 0.01 and 1000.
    assert camera.clip_start == pytest.approx(0.01, rel=1e-4)
    assert camera.clip_end == pytest.approx(1000, rel=2e-3)


@pytest.mark.parametrize("projection", ['PERSP', 'ORTHO'])
@pytest.mark.parametrize("fit, shift, size", [('AUTO', (0.0, 0.0), (320, 200)),
                                               ('VERTICAL', (0.2, -0.1), (200, 320)),
                                               ('HORIZONTAL', (-0.3, 0.25), (301, 157))])
def test_a_camera_view_gives_the_rays_f12_renders(projection, fit, shift, size):
    """In a camera view the region's matrices are the camera's (calc_matrix_camera is the
    projection Blender draws the camera view with): the viewport's rays are the exported
    camera's, which tests/test_silhouettes.py checks against view_frame."""
    scene = empty_file()
    width, height = size
    scene.render.resolution_x, scene.render.resolution_y = width, height
    camera = add_camera(location=(1.0, -7.0, 2.0), rotation=(1.3, 0.1, 0.3), lens=35.0)
    data = camera.data
    data.type, data.sensor_fit, data.ortho_scale = projection, fit, 5.0
    data.shift_x, data.shift_y = shift
    data.clip_start, data.clip_end = 0.5, 250.0
    graph = depsgraph()
    window = camera.calc_matrix_camera(graph, x=width, y=height)
    view = camera.matrix_world.inverted()

    ours = view_camera(view, window, width, height)
    f12 = prepare_job(graph).scene.camera

    xs, ys = pixel_centres(width, height)
    got, expected = camera_rays(ours, xs, ys), camera_rays(f12, xs, ys)
    # calc_matrix_camera and matrix_world are float32: 1e-6 of relative rounding.
    np.testing.assert_allclose(got.directions, expected.directions, atol=2e-6)
    np.testing.assert_allclose(np.broadcast_to(got.origins, expected.origins.shape),
                               expected.origins, atol=2e-5)
    np.testing.assert_allclose(np.broadcast_to(got.t_min, xs.shape),
                               np.broadcast_to(expected.t_min, xs.shape), rtol=1e-5)
    np.testing.assert_allclose(np.broadcast_to(got.t_max, xs.shape),
                               np.broadcast_to(expected.t_max, xs.shape), rtol=1e-4)
    region, rv3d = fake_region(width, height, view, window, 'CAMERA')
    assert_rays_reproject_onto_their_pixels(ours, region, rv3d, tolerance_px=2e-3)


def ortho_projection(left, right, bottom, top, near, far):
    """glOrtho, as Blender's viewport builds orthographic views (near < 0: behind the view
    point)."""
    m = np.eye(4)
    m[0, 0], m[0, 3] = 2 / (right - left), -(right + left) / (right - left)
    m[1, 1], m[1, 3] = 2 / (top - bottom), -(top + bottom) / (top - bottom)
    m[2, 2], m[2, 3] = -2 / (far - near), -(far + near) / (far - near)
    return m


def test_an_orthographic_viewport_with_its_near_plane_behind_the_view_point():
    width, height = 400, 300
    view = Matrix.Rotation(0.4, 4, 'X') @ Matrix.Translation((0.5, -2.0, -10.0))
    window = ortho_projection(-4.2, 3.8, -2.9, 3.1, -500.0, 500.0)
    region, rv3d = fake_region(width, height, view, window)

    camera = view_camera(view, window, width, height)

    assert camera.projection == "ORTHO" and camera.clip_start > 0
    xs, ys = pixel_centres(width, height)
    rays = camera_rays(camera, xs, ys)
    for k in range(len(xs)):
        coord = (xs[k], height - ys[k])
        direction = np.array(view3d_utils.region_2d_to_vector_3d(region, rv3d, coord))
        np.testing.assert_allclose(rays.directions[:, k], direction, atol=1e-6)
        # view3d_utils puts the origin on the far plane's mirror (500 behind the view point);
        # ours starts at the near plane: the same line, so they differ along the ray only.
        origin = np.array(view3d_utils.region_2d_to_origin_3d(region, rv3d, coord))
        apart = rays.origins[:, k] + camera.clip_start * rays.directions[:, k] - origin
        np.testing.assert_allclose(apart - (apart @ direction) * direction, 0, atol=1e-4)
        # ... and rays start at the near plane: 500 behind the view point.
        assert (apart @ direction) == pytest.approx(0.0, abs=1e-3)
    assert_rays_reproject_onto_their_pixels(camera, region, rv3d, tolerance_px=1e-3)


def test_a_cropped_or_coarse_view_traces_the_same_rays_as_the_full_view():
    bpy.ops.wm.read_factory_settings()
    area = next(a for a in bpy.context.window.screen.areas if a.type == 'VIEW_3D')
    rv3d = area.spaces.active.region_3d
    full = ViewportView.from_matrices(rv3d.view_matrix, rv3d.window_matrix, 640, 400)
    rect = (100, 50, 356, 250)  # x0, y0, x1, y1 from the bottom
    cropped = dataclasses.replace(full, rect=rect)

    xs, ys = np.meshgrid(np.arange(0.5, 256), np.arange(0.5, 200))
    xs, ys = xs.ravel(), ys.ravel()
    inside = camera_rays(cropped.camera(), xs, ys)
    # Crop pixel (x, y) (row from the top of the crop) is region pixel (x0 + x, H - y1 + y).
    whole = camera_rays(full.camera(), xs + rect[0], ys + (400 - rect[3]))
    np.testing.assert_allclose(inside.directions, whole.directions, atol=1e-12)

    coarse = full.camera(divisor=8)
    assert (coarse.width, coarse.height) == (80, 50)
    # Coarse pixel centres are at the centres of 8 x 8 blocks of full pixels.
    cx, cy = np.meshgrid(np.arange(0.5, 80), np.arange(0.5, 50))
    got = camera_rays(coarse, cx.ravel(), cy.ravel())
    expected = camera_rays(full.camera(), 8 * cx.ravel(), 8 * cy.ravel())
    np.testing.assert_allclose(got.directions, expected.directions, atol=1e-12)


def test_the_camera_frame_and_its_render_border_in_region_pixels():
    scene = empty_file()
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    camera = add_camera(location=(0.0, -6.0, 1.0), rotation=(1.4, 0.0, 0.2))
    graph = depsgraph()
    # A camera view zoomed out: the frame is smaller than the region and off centre.
    window = Matrix(camera.calc_matrix_camera(graph, x=160, y=90))
    zoom = Matrix.Diagonal((0.5, 0.5, 1.0, 1.0))
    zoom[0][3], zoom[1][3] = 0.2, -0.1  # a pan in NDC
    window = zoom @ window
    view = camera.matrix_world.inverted()
    corners = [camera.matrix_world @ c for c in camera.data.view_frame(scene=scene)]
    width, height = 800, 450

    frame = camera_frame_rect(window @ view, corners, width, height)

    # NDC [-1, 1] scaled by 0.5 and moved by (0.2, -0.1): x in [0.25, 0.75] * 800 + 80.
    np.testing.assert_allclose(frame, (280, 90, 680, 315), atol=1e-2)
    assert border_rect(frame, (0.25, 0.0, 0.75, 0.5), width, height) == (380, 90, 580, 202)
    assert border_rect(frame, (0.5, 0.5, 0.5, 0.9), width, height) is None


# --- progressive refinement ------------------------------------------------------------------

def test_the_refinement_schedule():
    settings = core.RenderSettings(anti_aliasing="adaptive", samples=8, semantics="article")
    passes = refinement_schedule(1574, 954, settings)
    assert [p.divisor for p in passes] == [coarse_divisor(1574, 954), 1, 1]
    d = passes[0].divisor
    assert d & (d - 1) == 0 and (1574 // d) * (954 // d) <= COARSE_PIXELS
    assert (1574 // (d // 2)) * (954 // (d // 2)) > COARSE_PIXELS  # the finest that fits
    assert [p.settings.anti_aliasing for p in passes] == ["off", "off", "adaptive"]
    # The last pass is the scene's own settings (tiles aside), so it is what F12 renders.
    assert dataclasses.replace(passes[-1].settings, tile_size=settings.tile_size) == settings
    assert all(p.settings.semantics == "article" for p in passes)

    assert [p.divisor for p in refinement_schedule(1574, 954, dataclasses.replace(
        settings, anti_aliasing="off"))] == [d, 1]
    assert [p.divisor for p in refinement_schedule(120, 90, settings)] == [1, 1]
    # Fixed anti-aliasing with many samples gets a 4-sample pass before its own.
    fixed = refinement_schedule(1574, 954, dataclasses.replace(settings, anti_aliasing="fixed",
                                                               samples=64))
    assert [(p.settings.anti_aliasing, p.settings.samples) for p in fixed[2:]] == [
        ("fixed", 4), ("fixed", 64)]
    assert [p.divisor for p in refinement_schedule(1574, 954, dataclasses.replace(
        settings, anti_aliasing="fixed", samples=4))] == [d, 1, 1]
    # Pixel Size 2: everything at half resolution, the coarse pass coarser still.
    halved = refinement_schedule(1574, 954, settings, pixel_size=2)
    assert [p.divisor for p in halved][1:] == [2, 2] and halved[0].divisor >= 4


def viewport_inputs(width=200, height=150):
    """(scene, settings, pixel size) of simple_scene() exported for the viewport,
    and a camera-like view of it."""
    simple_scene()
    graph = depsgraph()
    scene, settings, size, _ = export_viewport_scene(graph)
    camera = bpy.context.scene.camera
    view = ViewportView.from_matrices(
        camera.matrix_world.inverted(), camera.calc_matrix_camera(graph, x=width, y=height),
        width, height)
    return scene, settings, size, view


@pytest.mark.parametrize("integrator", ["path", "whitted"])
def test_progressive_passes_end_with_the_image_f12_renders(integrator):
    scene, settings, _, view = viewport_inputs(400, 300)
    if integrator == "whitted":
        settings = dataclasses.replace(settings, integrator="whitted",
                                       anti_aliasing="adaptive", samples=4)
    else:   # (no noise threshold: every pass of 1, 1 and 2 samples is taken)
        settings = dataclasses.replace(settings, samples=4, noise_threshold=0.0)
    frames = []

    progressive = ProgressiveRender(scene, view, settings, on_frame=frames.append)
    assert progressive.wait(timeout=120)

    assert progressive.error is None
    assert progressive.frame is frames[-1] and frames[-1].final
    assert progressive.frame_times == sorted(progressive.frame_times)
    f12 = dataclasses.replace(scene, camera=view.camera())
    expected = prepare_job(depsgraph())
    expected.scene, expected.settings = f12, settings
    np.testing.assert_array_equal(frames[-1].image, expected.run().image)
    if integrator == "path":
        # The coarse pass, then the view's own frame after 1, 2 and 4 samples a pixel
        # (``core.progressive``), each sharper than the last and only the last final.
        assert [f.index for f in frames] == [0, 1, 1, 1]
        assert [f.final for f in frames] == [False, False, False, True]
        assert [f.image.shape for f in frames] == [(75, 100, 4)] + [(300, 400, 4)] * 3
        assert not np.array_equal(frames[1].image, frames[2].image)
        return
    assert [f.index for f in frames] == [0, 1, 2]
    assert [f.image.shape for f in frames] == [(75, 100, 4), (300, 400, 4), (300, 400, 4)]
    # The pixel-centre pass is the same picture without anti-aliasing: equal away from edges.
    centre = dataclasses.replace(settings, anti_aliasing="off")
    expected.settings = centre
    np.testing.assert_array_equal(frames[1].image, expected.run().image)


def test_a_cancel_stops_the_worker_between_tiles_and_keeps_the_last_frame():
    scene, settings, _, view = viewport_inputs(640, 480)
    slow = dataclasses.replace(settings, anti_aliasing="fixed", samples=64, threads=1)
    frames = []

    progressive = ProgressiveRender(scene, view, slow, on_frame=frames.append)
    while not frames and not progressive.done:
        progressive.wait(timeout=0.01)
    progressive.cancel()
    assert progressive.wait(timeout=60)

    # The coarse pass (and maybe the pixel-centre one) landed; the 64-sample pass (about 64
    # times the pixel-centre pass) was cut short and never replaced the frame.
    assert progressive.cancelled and progressive.error is None
    assert 1 <= len(frames) < len(progressive.schedule)
    assert progressive.frame is frames[-1] and not progressive.frame.final


def test_the_session_re_renders_only_when_the_scene_or_the_view_changed():
    scene, settings, size, view = viewport_inputs()
    session = ViewportSession()
    assert not session.update_view(dataclasses.replace(view))   # no scene yet: nothing to do
    assert session.update_scene(scene, settings, size)
    first = session.render
    assert session.restarts == 1

    # The same view (equal, not identical) and the same export: nothing restarts.
    assert not session.update_view(dataclasses.replace(view))
    again, *_ = export_viewport_scene(depsgraph())
    assert not session.update_scene(again, settings, size)
    bpy.data.objects["big"].select_set(True)  # a selection is a depsgraph update too
    assert not session.update_scene(export_viewport_scene(depsgraph())[0], settings,
                                    size)
    assert session.render is first and session.restarts == 1

    # The user orbits: the running refinement is cancelled and a new one starts.
    orbit = ViewportView.from_matrices(Matrix.Rotation(0.1, 4, 'Z') @ Matrix(view.view_matrix),
                                       view.window_matrix, view.width, view.height)
    assert session.update_view(orbit)
    assert first.cancelled and session.render is not first
    second = session.render
    # The user moves an object: again.
    bpy.data.objects["small"].location.x += 0.3
    moved, *_ = export_viewport_scene(depsgraph())
    assert session.update_scene(moved, settings, size)
    assert second.cancelled and session.restarts == 3
    # A setting that changes the picture restarts it too.
    assert session.update_scene(moved, dataclasses.replace(settings, max_depth=1),
                                size)
    assert session.restarts == 4
    assert session.render.wait(timeout=60) and session.frame.final
    session.stop()


def test_until_a_new_view_has_its_first_pass_the_last_picture_stays():
    scene, settings, size, view = viewport_inputs()
    session = ViewportSession()
    session.update_scene(scene, settings, size)
    session.update_view(view)
    session.render.wait(timeout=60)
    shown = session.frame
    assert shown is not None

    orbit = dataclasses.replace(view, view_matrix=tuple(
        tuple(v + (0.01 if r == c == 0 else 0.0) for c, v in enumerate(row))
        for r, row in enumerate(view.view_matrix)))
    session.update_view(orbit)
    assert session.frame is shown or session.frame is session.render.frame
    session.render.wait(timeout=60)
    assert session.frame is session.render.frame and session.frame is not shown


def test_a_scene_without_a_camera_still_shows_in_a_free_view():
    *_, view = viewport_inputs()
    bpy.context.scene.camera = None
    with pytest.raises(Exception, match="has no camera"):
        prepare_job(depsgraph())
    for scene in (export_viewport_scene(depsgraph(), view=view)[0],
                  export_viewport_scene(depsgraph())[0]):   # no view either: still an export
        # (Which of them stay analytic spheres depends on the camera: the exporter keeps a
        # sphere-like mesh analytic where that is within a quarter pixel.)
        assert {s.name for s in scene.spheres} | {m.name for m in scene.meshes} == {
            "big", "small"}


def test_texture_pixels_are_scene_linear_premultiplied_rows_from_the_bottom():
    image = np.zeros((2, 3, 4), np.float32)
    image[0, 0] = (0.5, 0.25, 0.0, 0.5)     # top-left, premultiplied display values
    image[1, 2] = (1.0, 1.0, 1.0, 1.0)
    pixels = texture_pixels(image).reshape(2, 3, 4)
    np.testing.assert_allclose(pixels[1, 0], (srgb_to_linear(1.0) * 0.5,
                                              srgb_to_linear(0.5) * 0.5, 0.0, 0.5), rtol=1e-6)
    np.testing.assert_allclose(pixels[0, 2], (1, 1, 1, 1))
    assert pixels.dtype == np.float32


def test_the_engine_draws_its_own_viewport():
    assert GlintRenderEngine.bl_use_eevee_viewport is False
    for name in ("view_update", "view_draw"):
        assert getattr(GlintRenderEngine, name).__module__ == GlintRenderEngine.__module__
    # The drawing module imports gpu only inside the function that draws.
    source = open(viewport.__file__.replace("engine/viewport.py", "draw/viewport.py")).read()
    assert "\nimport gpu" not in source and "\nfrom gpu" not in source


# --- view_update / view_draw, with a recording drawer in place of the GPU -------------------

class RecordingEngine:
    """The parts of RenderEngine the viewport calls."""

    def __init__(self):
        self.reports, self.stats = [], []

    def report(self, kinds, message):
        self.reports.append((set(kinds), message))

    def update_stats(self, stats, info):
        self.stats.append(info)


class RecordingDrawer:
    def __init__(self):
        self.frames = []

    def draw(self, engine, scene, frame):
        self.frames.append(frame)


def camera_view_context(width, height, graph):
    camera = bpy.context.scene.camera
    window = camera.calc_matrix_camera(graph, x=width, y=height)
    region, rv3d = fake_region(width, height, camera.matrix_world.inverted(), window, 'CAMERA')
    return SimpleNamespace(region=region, region_data=rv3d, preferences=bpy.context.preferences)


def recorded_viewport(graph, width, height):
    """(viewport engine drawing into a RecordingDrawer, RecordingEngine, the drawer, a camera
    view context width x height) for ``view_update`` / ``view_draw`` calls."""
    from glint.addon.engine.viewport import ViewportEngine

    engine, drawer = RecordingEngine(), RecordingDrawer()
    viewport_engine = ViewportEngine()
    viewport_engine._drawer = drawer
    return viewport_engine, engine, drawer, camera_view_context(width, height, graph)


def draw_until_final(viewport_engine, engine, context, graph, limit=2000):
    for _ in range(limit):
        viewport_engine.view_draw(engine, context, graph)
        if not viewport_engine.session.busy and viewport_engine._drawn is \
                viewport_engine.session.frame:
            return
        viewport_engine.session.render.wait(timeout=0.01)
    raise AssertionError("the refinement did not finish")


def test_view_update_and_view_draw_draw_each_pass_and_warn_once():
    from addon_support import link

    scene = simple_scene()
    link(bpy.data.objects.new("fog", bpy.data.volumes.new("fog")))  # named in a warning
    scene.glint.anti_aliasing = 'ADAPTIVE'
    graph = depsgraph()
    viewport_engine, engine, drawer, context = recorded_viewport(graph, 400, 300)

    viewport_engine.view_update(engine, context, graph)
    viewport_engine.view_update(engine, context, graph)   # e.g. a selection: no new warning
    draw_until_final(viewport_engine, engine, context, graph)

    warnings = [message for kinds, message in engine.reports if kinds == {'WARNING'}]
    assert len(warnings) == 1 and "fog (volume object)" in warnings[0]
    assert viewport_engine.session.restarts == 1
    assert drawer.frames[-1].final and drawer.frames[-1].rect == (0, 0, 400, 300)
    indices = [f.index for f in drawer.frames]
    assert indices == sorted(indices)   # never an older pass after a newer one
    assert "done" in engine.stats[-1] and "adaptive" in engine.stats[-1]
    viewport_engine.free()


def test_a_camera_view_renders_only_its_render_border():
    scene = simple_scene()
    # Pixel centres, compared bit for bit: the Whitted integrator's.  (A path sample's
    # numbers are seeded by the pixel's place in the frame it is traced in, and the border
    # is traced as a frame of its own: the same picture, another grain.)
    scene.glint.integrator = 'WHITTED'
    render = scene.render
    render.use_border = True
    render.border_min_x, render.border_max_x = 0.25, 0.75
    render.border_min_y, render.border_max_y = 0.5, 1.0
    graph = depsgraph()
    # The region has the render's aspect, so the camera frame fills it.
    viewport_engine, engine, drawer, context = recorded_viewport(graph, 640, 480)

    viewport_engine.view_update(engine, context, graph)
    draw_until_final(viewport_engine, engine, context, graph)

    final = drawer.frames[-1]
    assert final.rect == (160, 240, 480, 480)
    assert final.image.shape == (240, 320, 4)
    # The same pixels as the whole view's, there.
    whole = ViewportView.from_matrices(context.region_data.view_matrix,
                                       context.region_data.window_matrix, 640, 480)
    job = prepare_job(graph)
    job.scene = dataclasses.replace(job.scene, camera=whole.camera())
    job.settings = dataclasses.replace(job.settings, anti_aliasing="off")
    expected = job.run().image
    np.testing.assert_array_equal(final.image, expected[0:240, 160:480])


def test_an_empty_render_border_draws_nothing():
    scene = simple_scene()
    scene.render.use_border = True
    scene.render.border_min_x = scene.render.border_max_x = 0.5
    graph = depsgraph()
    viewport_engine, engine, drawer, context = recorded_viewport(graph, 320, 240)

    viewport_engine.view_update(engine, context, graph)
    for _ in range(3):
        viewport_engine.view_draw(engine, context, graph)

    assert drawer.frames == [] and viewport_engine.session.render is None


def test_dropping_the_viewport_engine_stops_its_worker():
    import gc

    from glint.addon.engine.viewport import ViewportEngine

    scene, settings, size, view = viewport_inputs(640, 480)
    viewport_engine = ViewportEngine()
    viewport_engine.session.update_scene(
        scene, dataclasses.replace(settings, anti_aliasing="fixed", samples=64), size)
    viewport_engine.session.update_view(view)
    progressive = viewport_engine.session.render

    del viewport_engine
    gc.collect()

    assert progressive.cancelled and progressive.wait(timeout=60)
    assert progressive.frame is None or not progressive.frame.final
