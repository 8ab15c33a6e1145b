# shellcheck shell=bash
# Sourced by scripts/render_article.sh and scripts/test.sh (not run on its own).
#
# Makes <repo>/.venv ready: Python 3.11 (the only Python bpy 5.0.1 supports), the
# packages of requirements-dev.txt, and the system libraries bpy and Workbench's
# software EGL need. A stamp in .venv records what was set up; while it matches,
# nothing is checked again and a run starts at once.
#
# Defines GLINT_ROOT (the repository) and GLINT_PYTHON (the venv's interpreter).
# Environment: GLINT_BASE_PYTHON picks the Python 3.11 used to create the venv.

GLINT_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
GLINT_VENV=$GLINT_ROOT/.venv
GLINT_PYTHON=$GLINT_VENV/bin/python
GLINT_STAMP=$GLINT_VENV/.glint-setup-stamp

# Debian/Ubuntu packages for the libraries the bpy 5.0.1 wheel links against but does
# not bundle (found with `ldd bpy/__init__.so`), plus the EGL loader and Mesa's software
# driver (swrast_dri.so) that Workbench renders with when there is no GPU or display.
GLINT_APT_PACKAGES=(
    libx11-6 libxext6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxcb1
    libsm6 libice6 libgl1 libegl1 libegl-mesa0 libgl1-mesa-dri
)

glint_say() {
    echo "setup: $*" >&2
}

glint_fail() {
    echo "setup: error: $*" >&2
    exit 1
}

glint_find_python311() {
    local candidate
    for candidate in "${GLINT_BASE_PYTHON:-}" python3.11 "${HOME:-}/.pyenv/shims/python3.11" \
        /root/.pyenv/shims/python3.11 /usr/local/bin/python3.11 /usr/bin/python3.11 python3; do
        [ -n "$candidate" ] || continue
        command -v "$candidate" >/dev/null 2>&1 || continue
        # A pyenv shim exists even when it cannot run 3.11, so ask the interpreter itself.
        if "$candidate" -c 'import sys, venv, ensurepip; sys.exit(sys.version_info[:2] != (3, 11))' \
            >/dev/null 2>&1; then
            "$candidate" -c 'import sys; print(sys.executable)'
            return 0
        fi
    done
    return 1
}

glint_requirements_hash() {
    # The hash covers the requirements and this script, so editing either redoes set-up.
    cat "$GLINT_ROOT/requirements.txt" "$GLINT_ROOT/requirements-dev.txt" \
        "$GLINT_ROOT/scripts/setup_env.sh" "$GLINT_ROOT/scripts/check_bpy_runtime.py" |
        sha256sum | cut -d' ' -f1
}

glint_venv_is_python311() {
    [ -x "$GLINT_PYTHON" ] &&
        "$GLINT_PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' >/dev/null 2>&1
}

glint_create_venv() {
    local base_python
    if ! base_python=$(glint_find_python311); then
        glint_fail "Python 3.11 not found (bpy 5.0.1 supports only 3.11). Install it, e.g.
    apt-get install python3.11 python3.11-venv    (Debian 12, Ubuntu 22.04)
    pyenv install 3.11
or set GLINT_BASE_PYTHON to a python3.11 binary."
    fi
    if [ -e "$GLINT_VENV" ]; then
        glint_say "replacing .venv, which has no working Python 3.11"
        rm -rf "$GLINT_VENV"
    fi
    glint_say "creating .venv with $base_python"
    "$base_python" -m venv "$GLINT_VENV"
}

glint_bpy_runs() {
    "$GLINT_PYTHON" "$GLINT_ROOT/scripts/check_bpy_runtime.py" >"$GLINT_VENV/.glint-bpy-check.log" 2>&1
}

glint_missing_apt_packages() {
    local package
    for package in "${GLINT_APT_PACKAGES[@]}"; do
        dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q 'install ok installed' ||
            printf '%s ' "$package"
    done
}

glint_install_system_libraries() {
    # Only packages that are absent: reinstalling present ones would upgrade them as a side effect.
    local missing
    if ! command -v dpkg-query >/dev/null 2>&1; then
        glint_fail "bpy cannot run and this is not a Debian/Ubuntu system; install the equivalents of:
    ${GLINT_APT_PACKAGES[*]}"
    fi
    missing=$(glint_missing_apt_packages)
    if [ -z "$missing" ]; then
        glint_say "all of ${GLINT_APT_PACKAGES[*]} are installed already"
        return 0
    fi
    local apt_command="apt-get install -y --no-install-recommends $missing"
    if [ "$(id -u)" -ne 0 ]; then
        glint_fail "bpy cannot run: system packages are missing. As root, run
    apt-get update && $apt_command"
    fi
    glint_say "installing missing system packages for bpy: $missing"
    DEBIAN_FRONTEND=noninteractive apt-get update -q >&2 ||
        glint_fail "apt-get update failed; run it by hand, then: $apt_command"
    # shellcheck disable=SC2086
    DEBIAN_FRONTEND=noninteractive $apt_command >&2 ||
        glint_fail "apt-get install failed; run by hand: $apt_command"
}

glint_check_bpy_runtime() {
    glint_say "checking that bpy imports and Workbench renders headless"
    glint_bpy_runs && return 0
    glint_say "bpy check failed:"
    tail -n 5 "$GLINT_VENV/.glint-bpy-check.log" | sed 's/^/    /' >&2
    glint_install_system_libraries
    glint_bpy_runs && return 0
    local missing
    missing=$(ldd "$GLINT_VENV"/lib/python3.11/site-packages/bpy/*.so 2>/dev/null | grep 'not found' | sort -u || true)
    glint_fail "bpy still cannot import or render with Workbench, though every package listed in scripts/setup_env.sh is installed.
Libraries the loader cannot find: ${missing:-none}
Last lines of $GLINT_VENV/.glint-bpy-check.log:
$(tail -n 15 "$GLINT_VENV/.glint-bpy-check.log")"
}

glint_setup() {
    local wanted_hash
    wanted_hash=$(glint_requirements_hash)
    if [ -x "$GLINT_PYTHON" ] && [ -f "$GLINT_STAMP" ] && [ "$(cat "$GLINT_STAMP")" = "$wanted_hash" ]; then
        return 0
    fi

    # Two scripts started together must not run pip in the same venv at once.
    local lock_file
    lock_file="${TMPDIR:-/tmp}/glint-setup-$(printf '%s' "$GLINT_ROOT" | sha256sum | cut -c1-16).lock"
    exec 9>"$lock_file"
    flock 9
    if [ -x "$GLINT_PYTHON" ] && [ -f "$GLINT_STAMP" ] && [ "$(cat "$GLINT_STAMP")" = "$wanted_hash" ]; then
        exec 9>&-
        return 0
    fi

    local started=$SECONDS
    glint_venv_is_python311 || glint_create_venv
    rm -f "$GLINT_STAMP"
    glint_say "installing requirements-dev.txt into .venv (the first time downloads bpy, about 375 MB)"
    "$GLINT_PYTHON" -m pip install --disable-pip-version-check --no-input --progress-bar off -q \
        -r "$GLINT_ROOT/requirements-dev.txt" ||
        glint_fail "pip could not install requirements-dev.txt (is PyPI reachable?)"
    glint_check_bpy_runtime
    echo "$wanted_hash" >"$GLINT_STAMP"
    glint_say "ready in $((SECONDS - started)) s"
    exec 9>&-
}

glint_setup
