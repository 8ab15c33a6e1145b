"""The extension package: Blender's own tool validates and builds it, and the zip installs,
enables, disables and enables again in headless Blender the way a user's Blender does it.
"""

from __future__ import annotations

import glob
import importlib.util
import json
import os
import subprocess
import sys
import tomllib
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
INSTALLER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "install_extension_in_bpy.py")

# Top-level entries of the zip; addon/ imports core/ relatively, so both ship.
PACKAGE_TOP_LEVEL = {"__init__.py", "blender_manifest.toml", "addon", "core"}
PACKAGE_DIRECTORIES = ("addon", "core")

REGISTERED = {
    "enabled": True,
    "engine_selectable": True,
    "engine_class_registered": True,
    "operator_registered": True,
    "scene_property": True,
}
NOT_REGISTERED = {name: False for name in REGISTERED}


def bpy_scripts_directory() -> str:
    """bpy/<major.minor>/scripts of the installed pip bpy, found without importing bpy."""
    spec = importlib.util.find_spec("bpy")
    assert spec is not None and spec.submodule_search_locations, "the bpy module is not installed"
    matches = glob.glob(os.path.join(spec.submodule_search_locations[0], "*", "scripts"))
    assert len(matches) == 1, f"expected one bpy/<version>/scripts directory, found {matches}"
    return matches[0]


@pytest.fixture(scope="module")
def blender_ext() -> tuple[list[str], list[str]]:
    """Command prefix for Blender's extension tool, with Blender's list of valid tags."""
    scripts = bpy_scripts_directory()
    tool = os.path.join(scripts, "addons_core", "bl_pkg", "cli", "blender_ext.py")
    tags = os.path.join(scripts, "modules", "_bpy_internal", "extensions", "tags.py")
    return [sys.executable, tool], ["--valid-tags", tags]


def run(command: list[str], **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(command, capture_output=True, text=True, timeout=300, **kwargs)


@pytest.fixture(scope="module")
def manifest() -> dict:
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as file:
        return tomllib.load(file)


@pytest.fixture(scope="module")
def package_zip(blender_ext, tmp_path_factory) -> str:
    (tool, valid_tags) = blender_ext
    output = str(tmp_path_factory.mktemp("package") / "glint.zip")
    result = run([*tool, "build", "--source-dir", ROOT, "--output-filepath", output, *valid_tags])
    assert result.returncode == 0, f"blender_ext.py build failed:\n{result.stdout}{result.stderr}"
    return output


def test_manifest_passes_blenders_validation_including_tags(blender_ext):
    (tool, valid_tags) = blender_ext
    result = run([*tool, "validate", *valid_tags, ROOT])
    assert result.returncode == 0, f"blender_ext.py validate failed:\n{result.stdout}{result.stderr}"


def test_manifest_ships_no_wheels_because_blender_bundles_numpy(manifest):
    assert "wheels" not in manifest


def test_zip_holds_the_add_on_and_nothing_else(package_zip):
    with zipfile.ZipFile(package_zip) as archive:
        packaged = set(archive.namelist())

    assert {name.split("/")[0] for name in packaged} == PACKAGE_TOP_LEVEL
    assert not [name for name in packaged if "__pycache__" in name or name.endswith(".pyc")]

    # Nothing under addon/ or core/ may be lost to an exclude pattern (a bare "render.py"
    # pattern would silently drop core/render.py, for instance).
    on_disk = set()
    for directory in PACKAGE_DIRECTORIES:
        for parent, subdirectories, files in os.walk(os.path.join(ROOT, directory)):
            subdirectories[:] = [name for name in subdirectories if name != "__pycache__"]
            on_disk.update(
                os.path.relpath(os.path.join(parent, name), ROOT).replace(os.sep, "/")
                for name in files if not name.endswith(".pyc")
            )
    packaged_in_directories = {name for name in packaged if name.split("/")[0] in PACKAGE_DIRECTORIES}
    assert packaged_in_directories == on_disk


def test_zip_installs_and_registers_cleanly_in_headless_blender(package_zip, manifest, tmp_path):
    user_resources = tmp_path / "blender_user"
    # Only our temporary user directory: inherited BLENDER_USER_* or BLENDER_SYSTEM_*
    # variables would point Blender back at a real one.
    environment = {
        name: value for name, value in os.environ.items()
        if not name.startswith(("BLENDER_USER_", "BLENDER_SYSTEM_"))
    }
    environment["BLENDER_USER_RESOURCES"] = str(user_resources)

    result = run([sys.executable, INSTALLER, package_zip, manifest["id"]], env=environment, cwd=tmp_path)
    assert result.returncode == 0, f"installing in bpy failed:\n{result.stdout}{result.stderr}"
    report = json.loads(result.stdout.strip().splitlines()[-1])

    # Blender used the temporary user directory, and the add-on runs from the installed
    # copy in its user_default repository, not from this checkout.
    assert os.path.realpath(report["user_resources"]) == os.path.realpath(user_resources)
    installed_package = os.path.join(report["repository_directory"], manifest["id"])
    assert os.path.commonpath([installed_package, str(user_resources)]) == str(user_resources)
    assert report["module"] == f"bl_ext.user_default.{manifest['id']}"

    observed = dict(report["steps"])
    assert list(observed) == ["before install", "installed", "disabled", "enabled again"]
    for step, expected in [
        ("before install", NOT_REGISTERED),
        ("installed", REGISTERED),
        ("disabled", NOT_REGISTERED),
        ("enabled again", REGISTERED),
    ]:
        state = {name: observed[step][name] for name in expected}
        assert state == expected, f"{step}: {state}\n{result.stdout}{result.stderr}"
    for step in ("installed", "enabled again"):
        module_file = observed[step]["module_file"]
        assert os.path.realpath(module_file) == os.path.realpath(
            os.path.join(installed_package, "__init__.py")
        ), step
