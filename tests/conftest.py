"""The suite's tiers: a test that renders with Cycles must be marked ``cycles`` (pytest.ini),
so that the fast tier (``-m "not cycles and not slow"``) never renders with Cycles.

A render handler in Blender sees every Cycles render the test process starts, through any
helper; a Cycles render in a test without the marker fails that test.  (Renders in child
processes, as the bench's tests start, are outside it: those tests carry the marker by hand.)
"""

from __future__ import annotations

import sys

import pytest

_current: dict = {"cycles": False, "renders": []}


def _note_render(scene, *_):
    if scene is not None and scene.render.engine == 'CYCLES' and not _current["cycles"]:
        _current["renders"].append(scene.name)


def _watch_renders():
    """Adds the handler once bpy is imported (a run of core tests alone never imports it)."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and _note_render not in bpy.app.handlers.render_pre:
        # Persistent: emptying the file (read_factory_settings) keeps it.
        bpy.app.handlers.render_pre.append(bpy.app.handlers.persistent(_note_render))


@pytest.fixture(autouse=True)
def _cycles_renders_need_the_marker(request):
    _current["cycles"] = request.node.get_closest_marker("cycles") is not None
    _current["renders"] = []
    _watch_renders()
    yield
    _watch_renders()
    if _current["renders"]:
        pytest.fail(f"rendered with Cycles (scene {_current['renders'][0]!r}) but is not marked "
                    f"'cycles': add @pytest.mark.cycles", pytrace=False)
