"""Exit 0 when the pip `bpy` module imports and Workbench renders headless.

scripts/setup_env.sh runs this in a child process: a missing shared library makes the
import fail, and a missing EGL driver makes Blender abort (SIGABRT) on the first
Workbench render, which no Python code could catch, so only an exit status can tell.
"""

import os
import sys
import tempfile


def main():
    import bpy

    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = 8
    scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    with tempfile.TemporaryDirectory() as directory:
        scene.render.filepath = os.path.join(directory, "probe.png")
        bpy.ops.render.render(write_still=True)
        if not os.path.isfile(scene.render.filepath):
            sys.exit("Workbench rendered no image")


if __name__ == "__main__":
    main()
