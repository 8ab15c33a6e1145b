#!/usr/bin/env bash
# Main job: sets up .venv if needed, then renders the article's scene with render.py
# (pip bpy builds the scene in Blender and renders it through Glint) into out/article.png.
# render.py prints where it wrote the image and how long the render took; the line after
# it gives the whole run, Blender's start-up included.
# Extra arguments go to render.py, e.g. ./scripts/render_article.sh --width 150 --height 100
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup_env.sh"
cd "$GLINT_ROOT"

output=out/article.png
mkdir -p "$(dirname "$output")"
LC_NUMERIC=C  # so $EPOCHREALTIME uses the "." that awk reads
started=$EPOCHREALTIME
"$GLINT_PYTHON" render.py --output "$output" "$@"
awk -v started="$started" -v finished="$EPOCHREALTIME" \
    'BEGIN { printf "render_article.sh: %.1f s in all, Blender start-up included\n", finished - started }'
