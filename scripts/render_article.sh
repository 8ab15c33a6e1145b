#!/usr/bin/env bash
# Main job: sets up .venv if needed, then renders the article's scene with render.py
# (pip bpy builds the scene in Blender and renders it through Glint) into out/article.png.
# Extra arguments go to render.py, e.g. ./scripts/render_article.sh --width 150 --height 100
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup_env.sh"
cd "$GLINT_ROOT"

output=out/article.png
mkdir -p "$(dirname "$output")"
TIMEFORMAT="render_article.sh: render.py took %1R s (Blender start-up included)"
time "$GLINT_PYTHON" render.py --output "$output" "$@"
echo "render_article.sh: wrote $GLINT_ROOT/$output"
