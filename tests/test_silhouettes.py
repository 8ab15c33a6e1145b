"""Silhouettes: Glint (the add-on's exporter + the core) against Blender's Workbench and Cycles.

Each scene is rendered by Workbench (no anti-aliasing), by Cycles (1 sample, 0.01 px filter)
and by Glint, all with a transparent film, and the alpha masks are compared.  Blender draws the
UV-sphere meshes, Glint the analytic spheres the exporter fits to them, so a pixel may differ
only where the mesh itself is uncertain: in the band between the inscribed and circumscribed
spheres' silhouettes (see ``blender_scenes``).  A camera half a pixel off fails (proved below).
Renders are tiny (96 x 64 and the like) to keep the file fast.
"""

from __future__ import annotations

import numpy as np
import pytest

from addon_support import depsgraph
from blender_scenes import (ENGINES, CameraSetup, blender_mask, build_scene, clipped_spheres,
                            export_current_scene, fine_spheres, glint_masks, instanced_spheres,
                            mesh_behind_camera, shifted_by_pixels, silhouette_check,
                            transformed_spheres, triangle_meshes)
from glint.core.camera import camera_rays

PORTRAIT = (64, 96)  # CameraSetup's default is 96 x 64 landscape

SCENES = {
    "landscape, auto fit": (CameraSetup(), transformed_spheres),
    "portrait, auto fit": (CameraSetup(resolution=PORTRAIT, location=(0.5, -12.0, 1.0)),
                           transformed_spheres),
    "landscape, horizontal fit, collection instances": (
        CameraSetup(sensor_fit='HORIZONTAL', sensor=(30.0, 20.0)), instanced_spheres),
    "landscape, vertical fit": (CameraSetup(sensor_fit='VERTICAL', sensor=(36.0, 18.0)),
                                transformed_spheres),
    "portrait, horizontal fit, collection instances": (
        CameraSetup(resolution=PORTRAIT, sensor_fit='HORIZONTAL', sensor=(24.0, 36.0)),
        instanced_spheres),
    "portrait, vertical fit": (
        CameraSetup(resolution=PORTRAIT, sensor_fit='VERTICAL', sensor=(36.0, 30.0),
                    location=(0.5, -10.0, 1.0)),
        transformed_spheres),
    "lens shift x and y": (CameraSetup(shift=(0.18, -0.12)), transformed_spheres),
    "50 % resolution": (CameraSetup(resolution=(192, 128), percentage=50), instanced_spheres),
    "wide pixels": (CameraSetup(resolution=(64, 64), pixel_aspect=(1.5, 1.0)),
                    transformed_spheres),
    "tall pixels tip auto fit to vertical": (
        CameraSetup(resolution=(72, 64), pixel_aspect=(1.0, 1.6)), instanced_spheres),
    "orthographic, shifted": (CameraSetup(ortho_scale=6.5, shift=(0.05, 0.1)),
                              transformed_spheres),
    "orthographic portrait, vertical fit": (
        CameraSetup(resolution=PORTRAIT, ortho_scale=7.0, sensor_fit='VERTICAL'),
        instanced_spheres),
    "camera looking down, rolled": (CameraSetup(location=(2.0, -6.0, 7.0), roll=0.4),
                                    transformed_spheres),
    "camera looking up, rolled": (CameraSetup(location=(-1.0, -7.0, -6.0), roll=-0.6),
                                  instanced_spheres),
    "clip planes and a sphere behind the camera": (
        CameraSetup(lens=20.0, clip=(0.5, 12.0), location=(0.5, -3.0, 0.5)), clipped_spheres),
    "clip planes, portrait, looking down": (
        CameraSetup(resolution=PORTRAIT, lens=18.0, clip=(0.4, 10.0), location=(1.0, -2.0, 3.0),
                    roll=0.3),
        clipped_spheres),
}

FINE_SCENES = {
    "landscape": CameraSetup(),
    "portrait, vertical fit, shifted": CameraSetup(resolution=PORTRAIT, sensor_fit='VERTICAL',
                                                   shift=(-0.05, 0.08)),
    "orthographic portrait": CameraSetup(resolution=PORTRAIT, ortho_scale=5.0),
    "50 % resolution, wide pixels": CameraSetup(resolution=(128, 128), percentage=50,
                                                pixel_aspect=(1.5, 1.0)),
    "looking down, rolled": CameraSetup(location=(2.0, -6.0, 7.0), roll=0.4),
}

MIN_FINE_IOU = 0.995

MESH_SCENES = {
    "triangle meshes, landscape": (CameraSetup(), triangle_meshes),
    "triangle meshes, portrait, shifted": (
        CameraSetup(resolution=PORTRAIT, shift=(0.05, -0.08), location=(0.5, -12.0, 1.0)),
        triangle_meshes),
    "triangle meshes, orthographic": (CameraSetup(ortho_scale=7.5), triangle_meshes),
    "triangle meshes, looking down, rolled": (CameraSetup(location=(2.0, -6.0, 7.0), roll=0.4),
                                              triangle_meshes),
    "a mesh partly behind the camera": (
        CameraSetup(lens=20.0, clip=(0.5, 12.0), location=(0.5, -3.0, 0.5)),
        mesh_behind_camera),
}
#: The excused pixels are those whose centre lies within 1e-3 px of an edge: a few per scene
#: (more where a symmetric scene puts edges through pixel centres), never a real band.
MAX_EXCUSED_FRACTION = 0.005


def render_all(setup, builder, directory):
    """(exported core scene, Glint's masks, {engine: Blender's mask}) of one scene."""
    scene = build_scene(setup, builder)
    exported, _ = export_current_scene()
    references = {engine: blender_mask(scene, engine, directory) for engine in ENGINES}
    return exported, glint_masks(exported), references


def assert_within_band(glint, references, min_iou=None):
    failures = []
    for engine, reference in references.items():
        # A mask that is empty or full would make any comparison vacuous.
        assert 0 < reference.sum() < reference.size, f"{engine} rendered an empty or full mask"
        check = silhouette_check(glint, reference)
        if check.outside_band or (min_iou is not None and check.iou < min_iou):
            failures.append(f"{engine}: {check.describe()}")
    assert not failures, "; ".join(failures)


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("name", SCENES)
def test_glint_silhouettes_match_workbench_and_cycles_within_the_mesh_band(name, tmp_path):
    glint, references = render_all(*SCENES[name], tmp_path)[1:]
    assert_within_band(glint, references)
    # The two Blender engines draw the same meshes: they may differ only in the band too.
    workbench, cycles = references["BLENDER_WORKBENCH"], references["CYCLES"]
    stray = (workbench != cycles) & ~glint.band
    assert not stray.any(), f"Workbench and Cycles differ outside the band at " \
                            f"{np.argwhere(stray)[:8].tolist()}"


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("name", FINE_SCENES)
def test_finely_tessellated_spheres_match_blender_with_iou_above_0_995(name, tmp_path):
    glint, references = render_all(FINE_SCENES[name], fine_spheres, tmp_path)[1:]
    assert_within_band(glint, references, min_iou=MIN_FINE_IOU)


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("name", MESH_SCENES)
def test_triangle_mesh_silhouettes_match_workbench_and_cycles_but_at_edges(name, tmp_path):
    exported, glint, references = render_all(*MESH_SCENES[name], tmp_path)
    assert exported.meshes and not exported.spheres and not exported.sphere_sets
    assert glint.band.sum() <= MAX_EXCUSED_FRACTION * glint.band.size, \
        f"{glint.band.sum()} pixels excused"
    assert_within_band(glint, references)
    # Each object shows: every mesh instance's own mask overlaps Blender's.
    assert sum(len(mesh.transforms) for mesh in exported.meshes) >= 2


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("dx, dy", [(0.5, 0.0), (0.0, 0.5)], ids=["x", "y"])
def test_a_camera_half_a_pixel_off_fails_the_edge_check_for_meshes(dx, dy, tmp_path):
    exported, glint, references = render_all(*MESH_SCENES["triangle meshes, landscape"],
                                             tmp_path)
    shifted = glint_masks(shifted_by_pixels(exported, dx, dy))
    for engine, reference in references.items():
        check = silhouette_check(shifted, reference)
        assert check.outside_band > 0, f"{engine}: a half-pixel shift went unnoticed"


@pytest.mark.slow
@pytest.mark.cycles
@pytest.mark.parametrize("dx, dy", [(0.5, 0.0), (0.0, 0.5)], ids=["x", "y"])
def test_a_camera_half_a_pixel_off_fails_the_band_check(dx, dy, tmp_path):
    exported, glint, references = render_all(FINE_SCENES["landscape"], fine_spheres, tmp_path)
    assert_within_band(glint, references)  # the true camera passes

    shifted = glint_masks(shifted_by_pixels(exported, dx, dy))
    for engine, reference in references.items():
        check = silhouette_check(shifted, reference)
        assert check.outside_band > 0, f"{engine}: a half-pixel shift went unnoticed: " \
                                       f"{check.describe()}"


# --------------------------------------------------------------------------------------------
# Camera rays against Blender's own view frame and projection matrix.
#
# mathutils works in float32.  Every value these cameras depend on (lens, sensor, shift,
# resolution, pixel aspect, clip start, ortho scale) is a small binary fraction, so Blender's
# float32 view frame and projection matrix are exact, and 1e-9 leaves room only for the
# float64 rounding of Glint's own arithmetic.  The camera's rotation is whatever float32
# matrix_world holds; both sides use it with its scale removed in float64, as Blender renders.

ORACLE_CAMERAS = {
    "landscape, auto fit": dict(resolution=(64, 32)),
    "portrait, auto fit": dict(resolution=(32, 64)),
    "portrait, horizontal fit": dict(resolution=(32, 64), sensor_fit='HORIZONTAL'),
    "landscape, vertical fit": dict(resolution=(64, 32), sensor_fit='VERTICAL'),
    "shift x and y": dict(resolution=(64, 32), shift=(0.25, -0.125)),
    "50 % resolution": dict(resolution=(128, 64), percentage=50),
    "wide pixels": dict(resolution=(64, 64), pixel_aspect=(2.0, 1.0)),
    "tall pixels": dict(resolution=(64, 32), pixel_aspect=(1.0, 4.0)),
    "orthographic, shifted": dict(resolution=(64, 32), ortho_scale=4.0, shift=(0.125, 0.25)),
    "orthographic, vertical fit": dict(resolution=(32, 64), ortho_scale=2.0,
                                       sensor_fit='VERTICAL'),
    "looking up, rolled": dict(resolution=(64, 32), location=(1.0, -4.0, -3.0), roll=0.7),
    "looking down, rolled": dict(resolution=(32, 64), location=(-2.0, -3.0, 6.0), roll=-1.1),
}

#: (column, row) image positions of view_frame's corners: top right, bottom right, bottom
#: left, top left (row 0 is the top).
FRAME_CORNERS = ((1, 0), (1, 1), (0, 1), (0, 0))
ORACLE_TOLERANCE = 1e-9


def oracle_camera(case):
    setup = CameraSetup(**{"lens": 32.0, "sensor": (32.0, 16.0), "clip": (0.25, 64.0),
                           "location": (0.5, -6.0, 1.5), **case})
    scene = build_scene(setup)
    camera = scene.camera
    camera.scale = (1.5, 1.5, 1.5)  # Blender ignores a camera's scale, and so must Glint
    exported, _ = export_current_scene()
    return scene, camera, exported.camera


def without_scale(camera_object):
    """(rotation (3, 3), translation (3,)) of the camera in float64, scale removed."""
    matrix = np.array(camera_object.matrix_world, np.float64)
    rotation = matrix[:3, :3] / np.linalg.norm(matrix[:3, :3], axis=0)
    return rotation, matrix[:3, 3]


def corner_rays(cam):
    width, height = cam.width, cam.height
    xs = np.array([c * width for c, _ in FRAME_CORNERS], np.float64)
    ys = np.array([r * height for _, r in FRAME_CORNERS], np.float64)
    rays = camera_rays(cam, xs, ys)
    origins = np.broadcast_to(rays.origins, rays.directions.shape).T
    return origins, rays.directions.T


@pytest.mark.parametrize("case", ORACLE_CAMERAS)
def test_corner_rays_pass_through_blenders_view_frame(case):
    scene, camera, cam = oracle_camera(ORACLE_CAMERAS[case])
    frame = np.array([tuple(corner) for corner in camera.data.view_frame(scene=scene)])
    rotation, translation = without_scale(camera)
    origins, directions = corner_rays(cam)
    if cam.projection == 'ORTHO':
        # The frame lies on the plane z = -1; an orthographic ray starts on z = 0 under it.
        expected_origins = (rotation @ (frame * [1, 1, 0]).T).T + translation
        expected_directions = np.tile(-rotation[:, 2], (4, 1))
    else:
        expected_origins = np.tile(translation, (4, 1))
        world = (rotation @ frame.T).T
        expected_directions = world / np.linalg.norm(world, axis=1, keepdims=True)
    np.testing.assert_allclose(origins, expected_origins, rtol=0, atol=ORACLE_TOLERANCE)
    np.testing.assert_allclose(directions, expected_directions, rtol=0, atol=ORACLE_TOLERANCE)


@pytest.mark.parametrize("case", ORACLE_CAMERAS)
def test_corner_rays_project_to_the_corners_of_calc_matrix_camera(case):
    scene, camera, cam = oracle_camera(ORACLE_CAMERAS[case])
    render = scene.render
    projection = np.array(camera.calc_matrix_camera(
        depsgraph(), x=cam.width, y=cam.height,
        scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y), np.float64)
    rotation, translation = without_scale(camera)
    origins, directions = corner_rays(cam)
    # Points halfway between the clip planes along each corner ray, in camera space.
    depth = (cam.clip_start + cam.clip_end) / 2
    # float32's rotation, normalised, is orthogonal only to ~1e-8: invert it, do not transpose.
    local_origins = np.linalg.solve(rotation, (origins - translation).T).T
    local_directions = np.linalg.solve(rotation, directions.T).T
    points = local_origins + local_directions * (depth / -local_directions[:, 2:3])
    clip = np.hstack([points, np.ones((4, 1))]) @ projection.T
    ndc = clip[:, :2] / clip[:, 3:4]
    expected = np.array([[2 * c - 1, 1 - 2 * r] for c, r in FRAME_CORNERS], np.float64)
    np.testing.assert_allclose(ndc, expected, rtol=0, atol=ORACLE_TOLERANCE)
    np.testing.assert_allclose(points[:, 2], -depth, rtol=0, atol=ORACLE_TOLERANCE)
