"""Install an extension zip into headless bpy as a user would, and report what got registered.

Run by tests/test_extension_package.py in a child process:

    BLENDER_USER_RESOURCES=<tmp> python install_extension_in_bpy.py <zip> <extension id>

Blender reads BLENDER_USER_RESOURCES when bpy is imported, so the user directory (and the
'user_default' extensions repository inside it) can only be redirected in a fresh process.
The zip goes through Blender's own "Install from Disk" operator and the add-on is disabled
and enabled with the Preferences operators. The last line printed is a JSON report:
``{"user_resources": ..., "module": ..., "steps": [[step name, observations], ...]}``.
"""

import json
import sys

import bpy

REPOSITORY = "user_default"
ENGINE = "GLINT"
OPERATOR = "glint.render"


def observe(module_name):
    """What Blender currently offers of the add-on."""
    scene = bpy.context.scene
    previous_engine = scene.render.engine
    try:
        scene.render.engine = ENGINE
        engine_selectable = True
    except TypeError:  # "enum "GLINT" not found in (...)"
        engine_selectable = False
    finally:
        if scene.render.engine != previous_engine:
            scene.render.engine = previous_engine

    engine_classes = [
        cls for cls in bpy.types.RenderEngine.__subclasses__()
        if getattr(cls, "bl_idname", None) == ENGINE and cls.is_registered
    ]

    category, name = OPERATOR.split(".")
    try:
        getattr(getattr(bpy.ops, category), name).get_rna_type()
        operator_registered = True
    except KeyError:
        operator_registered = False

    module = sys.modules.get(module_name)
    return {
        "enabled": module_name in bpy.context.preferences.addons,
        "module_file": getattr(module, "__file__", None),
        "engine_selectable": engine_selectable,
        "engine_class_registered": len(engine_classes) == 1,
        "operator_registered": operator_registered,
        "scene_property": isinstance(getattr(scene, "glint", None), bpy.types.PropertyGroup),
    }


def main():
    zip_path, extension_id = sys.argv[1:3]
    module_name = f"bl_ext.{REPOSITORY}.{extension_id}"
    steps = [("before install", observe(module_name))]

    bpy.ops.extensions.package_install_files(
        repo=REPOSITORY, filepath=zip_path, enable_on_install=True,
    )
    steps.append(("installed", observe(module_name)))

    bpy.ops.preferences.addon_disable(module=module_name)
    steps.append(("disabled", observe(module_name)))

    bpy.ops.preferences.addon_enable(module=module_name)
    steps.append(("enabled again", observe(module_name)))

    repository = next(
        repo for repo in bpy.context.preferences.extensions.repos if repo.module == REPOSITORY
    )
    print(json.dumps({
        "user_resources": bpy.utils.resource_path("USER"),
        "repository_directory": repository.directory,
        "module": module_name,
        "steps": steps,
    }))
    # The bpy module before 5.0 cannot exit with the add-on's classes registered
    # (addon/compat.py): leave it disabled.
    bpy.ops.preferences.addon_disable(module=module_name)


if __name__ == "__main__":
    main()
