# shellcheck shell=bash
# Sourced by scripts/render_article.sh and scripts/test.sh (not run on its own).
#
# Makes a venv ready for one Blender version: the Python its `bpy` wheel supports, the
# packages of its pinned requirements file, and the system libraries bpy and Workbench's
# software EGL need. A stamp in the venv records what was set up; while it matches,
# nothing is checked again and a run starts at once.
#
# Which Blender: GLINT_BPY unset (or the default's series) sets up <repo>/.venv from
# requirements-dev.txt; GLINT_BPY=4.2 sets up <repo>/.venv-4.2 from requirements/bpy-4.2.txt,
# and so on for each file in requirements/. Each requirements file names its Python in a
# "# python: X.Y" line.
#
# Defines GLINT_ROOT (the repository), GLINT_VENV and GLINT_PYTHON (the venv's interpreter).
# Environment: GLINT_BASE_PYTHON picks the Python used to create the venv.

GLINT_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# Debian/Ubuntu packages for the libraries the bpy wheels (4.2 to 5.3) link against but do
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

glint_series() {
    # "5.3" from the "bpy==5.3.0" pin of a requirements file (following its "-r" includes).
    local file=$1 line
    while IFS= read -r line; do
        case $line in
            bpy==*) line=${line#bpy==}; echo "${line%.*}"; return 0 ;;
            "-r "*) glint_series "$(dirname "$file")/${line#-r }" && return 0 ;;
        esac
    done <"$file"
    return 1
}

glint_choose_venv() {
    # Sets GLINT_BPY_SERIES, GLINT_REQUIREMENTS (the file pip installs), GLINT_PYTHON_VERSION,
    # GLINT_PINS (the file naming the Python), GLINT_VENV, GLINT_VENV_NAME, GLINT_PYTHON and
    # GLINT_STAMP from GLINT_BPY.
    local default_series available
    default_series=$(glint_series "$GLINT_ROOT/requirements-dev.txt") ||
        glint_fail "requirements.txt pins no bpy version"
    if [ -z "${GLINT_BPY:-}" ] || [ "$GLINT_BPY" = "$default_series" ]; then
        GLINT_BPY_SERIES=$default_series
        GLINT_REQUIREMENTS=$GLINT_ROOT/requirements-dev.txt
        GLINT_PINS=$GLINT_ROOT/requirements.txt
        GLINT_VENV_NAME=.venv
    else
        GLINT_BPY_SERIES=$GLINT_BPY
        GLINT_REQUIREMENTS=$GLINT_ROOT/requirements/bpy-$GLINT_BPY.txt
        GLINT_PINS=$GLINT_REQUIREMENTS
        GLINT_VENV_NAME=.venv-$GLINT_BPY
        if [ ! -f "$GLINT_REQUIREMENTS" ]; then
            available=$(cd "$GLINT_ROOT/requirements" && ls bpy-*.txt | sed 's/^bpy-//; s/\.txt$//' | tr '\n' ' ')
            glint_fail "GLINT_BPY=$GLINT_BPY: no requirements/bpy-$GLINT_BPY.txt; choose one of: $default_series (the default) ${available}"
        fi
    fi
    GLINT_PYTHON_VERSION=$(sed -n 's/^# *python: *\([0-9]*\.[0-9]*\).*/\1/p' "$GLINT_PINS" | head -n 1)
    [ -n "$GLINT_PYTHON_VERSION" ] ||
        glint_fail "${GLINT_PINS#"$GLINT_ROOT"/} has no '# python: X.Y' line"
    GLINT_VENV=$GLINT_ROOT/$GLINT_VENV_NAME
    GLINT_PYTHON=$GLINT_VENV/bin/python
    GLINT_STAMP=$GLINT_VENV/.glint-setup-stamp
}

glint_is_wanted_python() {
    # A pyenv shim exists even when it cannot run that version, so ask the interpreter itself.
    "$1" -c "import sys, venv, ensurepip; sys.exit(sys.version_info[:2] != tuple(map(int, '$GLINT_PYTHON_VERSION'.split('.'))))" \
        >/dev/null 2>&1
}

glint_find_python() {
    local candidate version=$GLINT_PYTHON_VERSION
    # pyenv's shim runs only the versions pyenv has selected, so its installs are tried too.
    for candidate in "${GLINT_BASE_PYTHON:-}" "python$version" "${HOME:-}/.pyenv/shims/python$version" \
        "${HOME:-}/.pyenv/versions/$version".*/bin/"python$version" \
        "/usr/local/bin/python$version" "/usr/bin/python$version" python3; do
        [ -n "$candidate" ] || continue
        command -v "$candidate" >/dev/null 2>&1 || continue
        if glint_is_wanted_python "$candidate"; then
            "$candidate" -c 'import sys; print(sys.executable)'
            return 0
        fi
    done
    return 1
}

glint_requirements_hash() {
    # The hash covers the requirements and this script, so editing either redoes set-up.
    cat "$GLINT_PINS" "$GLINT_REQUIREMENTS" \
        "$GLINT_ROOT/scripts/setup_env.sh" "$GLINT_ROOT/scripts/check_bpy_runtime.py" |
        sha256sum | cut -d' ' -f1
}

glint_create_venv() {
    local base_python version=$GLINT_PYTHON_VERSION
    if ! base_python=$(glint_find_python); then
        glint_fail "Python $version not found (bpy $GLINT_BPY_SERIES supports only $version). Install it, e.g.
    apt-get install python$version python$version-venv
    pyenv install $version
or set GLINT_BASE_PYTHON to a python$version binary."
    fi
    if [ -e "$GLINT_VENV" ]; then
        glint_say "replacing $GLINT_VENV_NAME, which has no working Python $version"
        rm -rf "$GLINT_VENV"
    fi
    glint_say "creating $GLINT_VENV_NAME with $base_python"
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
    missing=$(ldd "$GLINT_VENV"/lib/python*/site-packages/bpy/*.so 2>/dev/null | grep 'not found' | sort -u || true)
    glint_fail "bpy still cannot import or render with Workbench, though every package listed in scripts/setup_env.sh is installed.
Libraries the loader cannot find: ${missing:-none}
Last lines of $GLINT_VENV/.glint-bpy-check.log:
$(tail -n 15 "$GLINT_VENV/.glint-bpy-check.log")"
}

glint_setup() {
    local wanted_hash
    glint_choose_venv
    wanted_hash=$(glint_requirements_hash)
    if [ -x "$GLINT_PYTHON" ] && [ -f "$GLINT_STAMP" ] && [ "$(cat "$GLINT_STAMP")" = "$wanted_hash" ]; then
        return 0
    fi

    # Two scripts started together must not run pip in the same venv at once.
    local lock_file
    lock_file="${TMPDIR:-/tmp}/glint-setup-$(printf '%s' "$GLINT_VENV" | sha256sum | cut -c1-16).lock"
    exec 9>"$lock_file"
    flock 9
    if [ -x "$GLINT_PYTHON" ] && [ -f "$GLINT_STAMP" ] && [ "$(cat "$GLINT_STAMP")" = "$wanted_hash" ]; then
        exec 9>&-
        return 0
    fi

    local started=$SECONDS requirements_name=${GLINT_REQUIREMENTS#"$GLINT_ROOT"/}
    { [ -x "$GLINT_PYTHON" ] && glint_is_wanted_python "$GLINT_PYTHON"; } || glint_create_venv
    rm -f "$GLINT_STAMP"
    glint_say "installing $requirements_name into $GLINT_VENV_NAME (the first time downloads bpy $GLINT_BPY_SERIES, about 375 MB)"
    "$GLINT_PYTHON" -m pip install --disable-pip-version-check --no-input --progress-bar off -q \
        -r "$GLINT_REQUIREMENTS" ||
        glint_fail "pip could not install $requirements_name (is PyPI reachable?)"
    glint_check_bpy_runtime
    echo "$wanted_hash" >"$GLINT_STAMP"
    glint_say "ready in $((SECONDS - started)) s"
    exec 9>&-
}

glint_setup
