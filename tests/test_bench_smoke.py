"""The bench's two reference implementations compute the article's image (correctness only:
the bench times them, tests never do)."""

import os

import numpy as np
import pytest

from bench import baseline, per_pixel
from core import article_scene

pytestmark = pytest.mark.slow  # every test here takes seconds (child processes)

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The image the article's own program produces (a copy of shared/reference/article_300x200.npy).
REFERENCE = os.path.join(REPOSITORY, "tests", "data", "article_300x200.npy")
#: A 30 x 20 crop holding the red and green spheres' edge, shadow and floor.
ROWS, COLUMNS = range(110, 130), range(100, 130)


def test_baseline_reproduces_the_article_image():
    reference = np.load(REFERENCE)
    image = baseline.render(article_scene(300, 200), max_depth=3)
    assert image.shape == (200, 300, 4)
    assert np.abs(image[..., :3] - reference).max() <= 1e-9
    # alpha is the camera ray's coverage: every lit pixel is covered.
    assert np.all(image[..., 3][reference.sum(axis=-1) > 0] == 1.0)


def test_baseline_in_bands_equals_one_broadcast():
    scene = article_scene(60, 40)
    whole = baseline.render(scene)
    assert np.array_equal(baseline.render_in_chunks(scene, max_elements=60 * 4 * 7), whole)


def test_per_pixel_program_matches_the_article_image_on_a_crop():
    reference = np.load(REFERENCE)[ROWS.start:ROWS.stop, COLUMNS.start:COLUMNS.stop]
    crop = per_pixel.render(article_scene(300, 200), max_depth=3, rows=ROWS, columns=COLUMNS)
    assert crop.shape == (20, 30, 3)
    # The crop is not trivial: shadowed (black) pixels and both spheres' colours.
    assert (reference.sum(axis=-1) == 0).any()
    assert (reference[..., 1] > reference[..., 0] + 0.1).any()
    assert (reference[..., 0] > reference[..., 1] + 0.1).any()
    assert np.abs(crop - reference).max() <= 1e-9


def test_scale_cases_render_the_same_scene_in_glint_and_cycles(tmp_path):
    """bench.scale's cases (the scale rows against Cycles), tiny: both engines draw the scene the case
    built, Glint exports every point, instance or triangle of it, and the report's targets
    read the results."""
    from bench import report, scale
    from bench.suite import QUICK, Bench, scale_rows

    cases = [scale.Case.parse(spec) for spec in (
        "points:200:48x27", "instances:50:48x27", "vertex-instances:50:48x27",
        "duplicates:20:48x27", "suzanne:1:48x27")]
    results = scale.run(cases, repeats=1, budget=0.0, out=str(tmp_path))

    drawn = {r["kind"]: r["glint"]["drawn"] for r in results}
    assert drawn["points"]["spheres"] == 200
    # 64 x 32 UV spheres of radius 0.05 are far below a pixel here: analytic spheres.
    assert drawn["instances"]["spheres"] == 50
    assert drawn["vertex-instances"]["spheres"] == 50
    assert drawn["duplicates"]["spheres"] == 20
    # Suzanne at level 1 (968 triangles -> 1,968 quads) and the floor's 2 triangles.
    assert drawn["suzanne"]["triangles"] == scale.suzanne_triangles(1) + 2 == 3938
    for result in results:
        assert not result["glint"]["warnings"], result["case"]
        # Two renders of the same scene: alike in the 8 x 8 boxes (Cycles' one sample is
        # noisy per pixel, not per box), and covering nearly the same pixels.
        assert result["similarity"]["r"] > 0.8, result["case"]
        assert result["similarity"]["coverage_mismatch"] < 0.02 * 48 * 27, result["case"]
        assert os.path.exists(result["picture"])

    bench = Bench(QUICK, str(tmp_path))
    for result in results:
        bench.scale_results.append(result)
        bench.rows.extend(scale_rows("scale-points", result))
    statuses = {t.name.split(")")[0]: t.status for t in report.scale_targets(bench)}
    assert statuses["(scale 1"] in ("PASS", "FAIL") and statuses["(scale 2"] in ("PASS", "FAIL")
    assert statuses["(scale 3"] == "MEASURED" and statuses["(scale 4"] == "NOT MEASURED"
    assert len(report.table(bench)) == 2 + 2 * len(results)


def test_the_readme_picture_puts_glint_beside_cycles(tmp_path):
    """bench.readme_picture, tiny: one PNG, Glint's image, a 4-pixel gap and Cycles' image of
    the same scene, alike in 8 x 8 boxes (Cycles' bounced light and 8 samples' noise keep r
    below 1; a different scene or an empty image would fall far below 0.8)."""
    import sys

    from bench import scale

    out = tmp_path / "picture.png"
    result = scale.child_result([sys.executable, "-m", "bench.readme_picture", "--out", str(out),
                                 "--width", "64", "--height", "48", "--cycles-samples", "8"],
                                timeout=600)
    assert result["picture"] == str(out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(out.read_bytes()[16:20], "big"), \
        int.from_bytes(out.read_bytes()[20:24], "big")
    assert (width, height) == (2 * 64 + 4, 48)
    assert result["similarity"]["r"] > 0.8
    # Glint lacks the bounced light: a few per cent darker (0.97 at the default size).
    assert 0.8 < result["similarity"]["brightness_ratio"] < 1.05


def test_texture_bench_times_every_case_on_a_tiny_frame(capsys):
    from bench import textures

    assert textures.main(["--width", "16", "--height", "8", "--repeats", "1"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert len(rows) == 1 + len(textures.cases(textures.frame_points(2, 1)))
    assert textures.frame_points(4, 2).shape == (3, 8)


def test_node_tree_bench_times_a_constant_and_a_twenty_node_material_on_a_tiny_frame(capsys):
    from bench import node_tree

    assert node_tree.main(["--width", "16", "--height", "8", "--repeats", "1"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert len(rows) == 3       # the header and two materials
    constant, tree = rows[1].split(" | "), rows[2].split(" | ")
    # The constant material is no program; the tree folds its RGB node and keeps the other
    # 19 as instructions (the Bump's height is a program of its own, inside the Bump's).
    assert constant[1] == "0" and tree[1] == "19"


# Opens each file bench.textured_scenes wrote (the add-on registered, so that the engine reads
# back) and prints what the speed-vs-error comparison relies on.
_TEXTURED_SUMMARY = """
import json, sys
import bpy
import render
render.register_glint(render.import_glint())
for path in sys.argv[1:]:
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    scene = bpy.context.scene
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree] + [scene.world.node_tree]
    print(json.dumps({"engine": scene.render.engine, "camera": scene.camera is not None,
                      "size": [scene.render.resolution_x, scene.render.resolution_y],
                      "images": {i.name: i.packed_file is not None for i in bpy.data.images},
                      "nodes": sorted({n.bl_idname for t in trees for n in t.nodes
                                       if any(s.is_linked for s in n.outputs)})}))
"""


def test_the_textured_scenes_are_self_contained_blend_files(tmp_path):
    """bench.textured_scenes writes three .blend files that render with Glint from a camera,
    every image packed (a file that named the bpy wheel's HDRI on disk would not open
    elsewhere), each holding the nodes its scene is about."""
    import json
    import subprocess
    import sys

    written = subprocess.run([sys.executable, "-m", "bench.textured_scenes", "--out",
                              str(tmp_path)], cwd=REPOSITORY, capture_output=True, text=True,
                             timeout=300, check=True).stdout.split()
    names = ["textured_product", "textured_procedural", "textured_normal_map"]
    assert written == [str(tmp_path / f"{name}.blend") for name in names]
    summary = subprocess.run([sys.executable, "-c", _TEXTURED_SUMMARY, *written], cwd=REPOSITORY,
                             capture_output=True, text=True, timeout=300, check=True).stdout
    scenes = dict(zip(names, (json.loads(line) for line in summary.splitlines()
                              if line.startswith("{"))))
    for scene in scenes.values():
        assert scene["engine"] == "GLINT" and scene["camera"] and scene["size"] == [480, 270]
        assert all(scene["images"].values())
    assert set(scenes["textured_product"]["images"]) == {"label", "studio.exr"}
    assert {"ShaderNodeTexImage", "ShaderNodeTexEnvironment", "ShaderNodeMapping"} <= set(
        scenes["textured_product"]["nodes"])
    assert {"ShaderNodeTexNoise", "ShaderNodeValToRGB", "ShaderNodeTexVoronoi", "ShaderNodeBump",
            "ShaderNodeMath"} <= set(scenes["textured_procedural"]["nodes"])
    assert {"ShaderNodeTexImage", "ShaderNodeNormalMap"} <= set(
        scenes["textured_normal_map"]["nodes"])
