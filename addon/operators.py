"""The Render button: render the scene with Glint into an Image datablock.

With a window (``invoke``), the render runs on a worker thread while a modal handler shows
progress (wm.progress_*) and listens for Esc; Blender stays responsive.  Without one (background
mode, scripts calling ``bpy.ops.glint.render()``), ``execute`` renders synchronously.  Either
way the image is written only when the render succeeded: a failed or cancelled render leaves
the previous image untouched and says why through ``self.report``.

The scene is exported on the main thread before the worker starts, so edits made while it
runs do not affect the render.  The panel render uses the viewport's evaluated scene (see
``addon.export.scene`` for what that means for visibility); F12 uses Blender's render
evaluation.
"""

from __future__ import annotations

import time

import bpy

from .engine.job import ThreadedRender, failure_message, prepare_job
from .utils.image import ImageError, check_image_name, write_image

#: How often the modal handler looks at the worker, in seconds.
POLL_INTERVAL = 0.1


class GLINT_OT_render(bpy.types.Operator):
    """Render the scene with Glint into the Image named in the Glint settings"""

    bl_idname = "glint.render"
    bl_label = "Render with Glint"
    bl_options = {'REGISTER'}

    # Only one Render-button render at a time: a second would race for the same image.
    _running = False

    @classmethod
    def poll(cls, context):
        if cls._running:
            cls.poll_message_set("A Glint render is already running")
            return False
        return context.scene is not None

    def _prepare(self, context):
        """(job, image name), or None after reporting why the render cannot start."""
        image_name = context.scene.glint.image_name
        try:
            check_image_name(image_name)
            job = prepare_job(context.evaluated_depsgraph_get())
        except ImageError as error:
            self.report({'ERROR'}, str(error))
            return None
        except Exception as error:  # anything, so the user sees one line, not a traceback
            self.report({'ERROR'}, failure_message(error))
            return None
        for warning in job.warnings:
            self.report({'WARNING'}, warning)
        return job, image_name

    def _store(self, job, result, image_name: str, seconds: float):
        try:
            write_image(image_name, job.scene_linear(result.image))
        except ImageError as error:
            self.report({'ERROR'}, str(error))
            return {'CANCELLED'}
        except Exception as error:
            self.report({'ERROR'}, f"Glint could not store the render in image "
                                   f"'{image_name}': {failure_message(error)}")
            return {'CANCELLED'}
        width, height = job.size
        self.report({'INFO'}, f"Glint rendered {width}x{height} ({result.precision}) in "
                              f"{seconds:.2f} s into image '{image_name}'")
        return {'FINISHED'}

    def execute(self, context):
        prepared = self._prepare(context)
        if prepared is None:
            return {'CANCELLED'}
        job, image_name = prepared
        window_manager = context.window_manager
        start = time.perf_counter()
        window_manager.progress_begin(0, 100)
        try:
            result = job.run(progress=lambda fraction: window_manager.progress_update(
                round(100 * fraction)), reserve_bytes=job.frame_bytes)  # the Image's buffer
        except BaseException as error:  # any failure keeps the image and says so in one line
            self.report({'ERROR'}, f"Glint render failed, image '{image_name}' unchanged: "
                                   f"{failure_message(error)}")
            return {'CANCELLED'}
        finally:
            window_manager.progress_end()
        return self._store(job, result, image_name, time.perf_counter() - start)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        prepared = self._prepare(context)
        if prepared is None:
            return {'CANCELLED'}
        self._job, self._image_name = prepared
        self._start = time.perf_counter()
        self._worker = ThreadedRender.of_job(self._job)
        window_manager = context.window_manager
        window_manager.progress_begin(0, 100)
        self._timer = window_manager.event_timer_add(POLL_INTERVAL, window=context.window)
        window_manager.modal_handler_add(self)
        type(self)._running = True
        self.report({'INFO'}, "Glint rendering... (Esc cancels)")
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            self._worker.cancel()
            return {'RUNNING_MODAL'}
        if event.type != 'TIMER' or event.timer is not self._timer:
            return {'PASS_THROUGH'}
        context.window_manager.progress_update(round(100 * self._worker.fraction))
        if not self._worker.done:
            return {'PASS_THROUGH'}
        self._stop_modal(context)
        worker = self._worker
        if worker.cancelled:
            self.report({'WARNING'}, f"Glint render cancelled, image '{self._image_name}' "
                                     f"unchanged")
            return {'CANCELLED'}
        if worker.error is not None:
            self.report({'ERROR'}, f"Glint render failed, image '{self._image_name}' "
                                   f"unchanged: {failure_message(worker.error)}")
            return {'CANCELLED'}
        return self._store(self._job, worker.result, self._image_name,
                           time.perf_counter() - self._start)

    def cancel(self, context):
        # Blender ends the modal operator (file load, window closed): stop the worker too.
        self._worker.cancel()
        self._worker.wait()
        self._stop_modal(context)

    def _stop_modal(self, context):
        window_manager = context.window_manager
        window_manager.event_timer_remove(self._timer)
        window_manager.progress_end()
        type(self)._running = False


classes = (GLINT_OT_render,)
