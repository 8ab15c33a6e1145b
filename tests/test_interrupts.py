"""Ctrl-C (SIGINT) and SIGTERM during a render: render.py and ``python -m core`` stop within
a couple of seconds, say so in one line, write nothing and exit 128 + the signal's number.

Each test starts a render that would take far longer than the test waits (1920 x 1080 with
64 samples a pixel: about a minute here), signals it after a few seconds and times the exit.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from process_support import sigint_disposition

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Enough for the child to import bpy and be rendering (bpy's import takes ~1-2 s here).
SETTLE_SECONDS = 4.0
#: How long a cancel may take: the core stops between tiles, a tile takes well under this.
CANCEL_SECONDS = 2.5

COMMANDS = {
    "render.py": [os.path.join(REPOSITORY, "render.py"), "--width", "1920", "--height", "1080",
                  "--samples", "64"],
    "python -m core": ["-m", "core", "--width", "1920", "--height", "1080",
                       "--anti-aliasing", "fixed", "--samples", "64"],
}


def start(command, output, ignore_sigint=False):
    # ignore_sigint: what a shell does for 'command &' without job control.
    return subprocess.Popen([sys.executable, *COMMANDS[command], "--output", str(output)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=REPOSITORY, preexec_fn=sigint_disposition(ignore_sigint))


def stop_within(process, seconds):
    start_time = time.monotonic()
    try:
        out, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        raise
    return time.monotonic() - start_time, out, err


@pytest.mark.parametrize("command", COMMANDS)
def test_ctrl_c_cancels_promptly_writes_nothing_and_exits_130(tmp_path, command):
    output = tmp_path / "out.png"
    output.write_bytes(b"previous render")
    process = start(command, output)
    time.sleep(SETTLE_SECONDS)
    assert process.poll() is None, "the render ended before the signal: make it bigger"

    process.send_signal(signal.SIGINT)
    elapsed, out, err = stop_within(process, CANCEL_SECONDS)

    assert process.returncode == 130, err
    assert elapsed < CANCEL_SECONDS
    (line,) = err.strip().splitlines()
    assert "cancelled by SIGINT" in line and "nothing written" in line
    assert output.read_bytes() == b"previous render"
    assert os.listdir(tmp_path) == ["out.png"]


@pytest.mark.parametrize("command", COMMANDS)
def test_in_the_background_sigint_is_ignored_and_sigterm_cancels_with_143(tmp_path, command):
    output = tmp_path / "out.png"
    process = start(command, output, ignore_sigint=True)
    time.sleep(SETTLE_SECONDS)
    process.send_signal(signal.SIGINT)
    time.sleep(0.5)
    assert process.poll() is None, "SIGINT was ignored by the shell and must stay ignored"

    process.send_signal(signal.SIGTERM)
    elapsed, out, err = stop_within(process, CANCEL_SECONDS)

    assert process.returncode == 143, err
    assert elapsed < CANCEL_SECONDS
    (line,) = err.strip().splitlines()
    assert "cancelled by SIGTERM" in line
    assert os.listdir(tmp_path) == []
