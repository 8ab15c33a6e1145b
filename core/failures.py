"""How a render ends other than with its image: cancelled, or failed with a bug."""

from __future__ import annotations


class RenderCancelled(Exception):
    """``should_cancel()`` answered True; the render stopped between tiles."""


class RenderError(RuntimeError):
    """The tracer produced something no accepted scene should (a bug); the message is one
    line saying where."""
