#!/usr/bin/env bash
# The benchmark: python -m bench in the project's .venv, with the dev-only plotting
# requirement (bench/requirements.txt, matplotlib) installed on first use.
# Extra arguments go to the bench, e.g. ./scripts/bench.sh --quick
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup_env.sh"
cd "$GLINT_ROOT"

if ! "$GLINT_PYTHON" -c "import matplotlib" 2>/dev/null; then
    echo "bench.sh: installing bench/requirements.txt (matplotlib, for the plots)"
    "$GLINT_PYTHON" -m pip install --quiet -r bench/requirements.txt
fi
exec "$GLINT_PYTHON" -m bench "$@"
