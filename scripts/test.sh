#!/usr/bin/env bash
# The whole test suite: sets up .venv if needed, then runs pytest over tests/.
# Extra arguments go to pytest, e.g. ./scripts/test.sh -k extension -x
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup_env.sh"
cd "$GLINT_ROOT"

status=0
"$GLINT_PYTHON" -m pytest "$@" || status=$?
if [ "$status" -eq 5 ]; then
    echo "test.sh: pytest collected no tests, which counts as a failure" >&2
fi
exit "$status"
