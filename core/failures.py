"""How a render ends other than with its image: cancelled, or failed with a bug."""

from __future__ import annotations

#: How often a scheduler waiting on its tiles (threads, worker processes, a cluster) polls
#: ``should_cancel`` (seconds): a cancel is honoured within about this.
CANCEL_POLL_SECONDS = 0.1


class RenderCancelled(Exception):
    """``should_cancel()`` answered True; the render stopped between tiles."""


class RenderError(RuntimeError):
    """The tracer produced something no accepted scene should (a bug); the message is one
    line saying where."""
