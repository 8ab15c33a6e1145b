#!/usr/bin/env bash
# Builds the extension zip (dist/glint-<version>.zip) with Blender's own extension tool,
# validating the manifest and its tags as Blender does.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup_env.sh"
cd "$GLINT_ROOT"

scripts=$("$GLINT_PYTHON" -c 'import glob, importlib.util; print(*glob.glob(importlib.util.find_spec("bpy").submodule_search_locations[0] + "/*/scripts"))')
mkdir -p dist
"$GLINT_PYTHON" "$scripts/addons_core/bl_pkg/cli/blender_ext.py" build \
    --source-dir . --output-dir dist \
    --valid-tags "$scripts/modules/_bpy_internal/extensions/tags.py"
