"""docs/supported-nodes.md is what scripts/supported_nodes.py makes of the node registry and
the running Blender's shader nodes: the page cannot drift from the code."""

from __future__ import annotations

import os
import sys

import addon_support  # noqa: F401  (Blender and the glint package, as the add-on sees them)

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPOSITORY, "scripts"))

import supported_nodes  # noqa: E402


def test_the_page_is_generated_from_the_registry():
    import bpy

    if bpy.app.version[:2] != (5, 0):
        # The page lists the README's Blender's nodes; others have a few more or fewer.
        assert "| Math | supported |" in supported_nodes.page()
        return
    with open(supported_nodes.PAGE, encoding="utf-8") as page:
        assert page.read() == supported_nodes.page(), \
            "docs/supported-nodes.md is stale: run scripts/supported_nodes.py"


def test_every_registered_node_is_on_the_page_with_its_note():
    from glint.core.shader.registry import NODES

    page = supported_nodes.page()
    rows = supported_nodes.rows()
    labels = {label for _, label, _, _ in rows}
    import bpy
    for bl_idname, spec in NODES.items():
        cls = getattr(bpy.types, bl_idname, None)
        if cls is None:      # Glint's own conversions, not Blender nodes
            continue
        assert cls.bl_rna.name in labels, bl_idname
        if spec.note:
            assert spec.note in page, bl_idname
    # A node Glint does not evaluate is said to be ignored.
    assert any(label == "Wireframe" and status == "ignored"
               for _, label, status, _ in rows)
