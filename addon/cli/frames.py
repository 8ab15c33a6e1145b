"""Frames: Blender's frame numbering of output paths (``frame_path``), the frames an
animation renders (``animation_frames``) and Blender's Output > Overwrite and Placeholders,
with which several processes share one animation (``FrameClaim``)."""

from __future__ import annotations

import os
import re

from .report import RenderScriptError


def frame_path(template: str, frame: int, animation: bool = False) -> str:
    """Blender's frame numbering of output paths: the last run of '#' in the file name becomes
    the frame number, zero-padded to its length (``frame_####.png``, frame 7 ->
    ``frame_0007.png``; frame -3 -> ``frame_-0003.png``).  Without '#', an animation's frame
    number goes before the extension in four digits (``out.png`` -> ``out0007.png``), a single
    frame's path is the template itself."""
    folder, name = os.path.split(template)
    runs = list(re.finditer(r"#+", name))
    if runs:
        run = runs[-1]
        digits = _digits(frame, len(run.group()))
        return os.path.join(folder, name[:run.start()] + digits + name[run.end():])
    if not animation:
        return template
    stem, extension = os.path.splitext(name)
    return os.path.join(folder, f"{stem}{_digits(frame, 4)}{extension}")


def _digits(frame: int, width: int) -> str:
    """Blender's frame number: zero-padded to ``width`` digits, the sign before them."""
    return f"{'-' if frame < 0 else ''}{abs(frame):0{width}d}"


def animation_frames(scene, args) -> range:
    """The frames --frames asks for: its START-END, or the scene's range and step; made one
    at a time (a range: two million frames cost no more than two)."""
    if args.frame_range is not None:
        start, end = args.frame_range
        return range(start, end + 1)
    return range(scene.frame_start, scene.frame_end + 1, scene.frame_step)


class FrameClaim:
    """Blender's Output > Overwrite and Placeholders, as several processes or machines sharing
    one output folder use them to split an animation:

    * overwrite off: a frame whose file exists is skipped;
    * placeholders on: a frame is claimed by creating its empty file before it is rendered.
      The claim is atomic (``O_CREAT | O_EXCL``), so of two processes reaching a free frame at
      once exactly one renders it; the other skips it when overwrite is off (with overwrite
      on, as in Blender, everyone renders every frame).

    ``release`` removes this process's placeholder if the frame was not written (a failure or
    a cancel), so another run picks the frame up, as Blender does on a cancelled render."""

    def __init__(self, path: str, overwrite: bool, placeholder: bool):
        self.path, self.placeholder_created = path, False
        self.claimed = self._claim(overwrite, placeholder)

    def _claim(self, overwrite: bool, placeholder: bool) -> bool:
        target = os.path.realpath(self.path)
        if not overwrite and os.path.exists(target):
            return False
        if not placeholder:
            return True
        try:
            descriptor = os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            return overwrite
        except OSError as error:
            raise RenderScriptError(f"cannot create placeholder {self.path}: "
                                    f"{error.strerror or error}") from None
        os.close(descriptor)
        self.placeholder_created = True
        return True

    def release(self) -> None:
        target = os.path.realpath(self.path)
        if self.placeholder_created and os.path.isfile(target) and \
                os.path.getsize(target) == 0:
            os.remove(target)
