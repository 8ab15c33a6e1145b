"""core.allocator: glibc's thresholds raised where Glint owns the process, and only there."""

import os
import subprocess
import sys
import textwrap

import pytest

import core
from core import allocator

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GLIBC = allocator._glibc() is not None


def _child(code: str, **environment) -> list[str]:
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, cwd=REPOSITORY, timeout=120,
                          env={**os.environ, "PYTHONPATH": REPOSITORY, **environment})
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


FAULTS = """
    import resource, sys
    import core
    from core import allocator
    if sys.argv[-1] == "tuned":
        assert allocator.configure()
    scene, settings = core.article_scene(256, 256), core.article_settings(threads=1)
    core.render(scene, settings)                      # warm-up: the heap grows once
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    core.render(scene, settings)                      # the same 4 tiles again
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.slow
@pytest.mark.skipif(not GLIBC, reason="mallopt settings exist only with glibc on Linux")
def test_tuned_malloc_stops_a_render_from_faulting():
    def faults(mode):
        done = subprocess.run([sys.executable, "-c", textwrap.dedent(FAULTS), mode],
                              capture_output=True, text=True, cwd=REPOSITORY, timeout=120,
                              env={**os.environ, "PYTHONPATH": REPOSITORY})
        assert done.returncode == 0, done.stderr
        return int(done.stdout)

    plain, tuned = faults("plain"), faults("tuned")
    # glibc's defaults map and unmap a tile's temporaries: ~6,500 minor faults for four
    # 128 x 128 tiles here; tuned, the second render reuses the first one's pages.
    assert plain > 1000
    assert tuned < plain / 20


def test_a_render_leaves_the_allocator_alone_unless_opted_in():
    code = """
        import core
        from core import allocator
        core.render(core.article_scene(32, 24))
        print(allocator._applied)
    """
    assert _child(code) == ["None"]
    assert _child(code, GLINT_MALLOC_TUNING="1") == [str(GLIBC)]


def test_core_main_tunes_only_as_the_program(tmp_path):
    code = f"""
        from core import allocator
        from core.__main__ import main
        main(["--width", "8", "--height", "8", "--output", {str(tmp_path / 'a.npy')!r}])
        print(allocator._applied)
    """
    assert _child(code)[-1] == "None"     # called from other code: not its process


def test_opt_in_values():
    assert allocator.opted_in({"GLINT_MALLOC_TUNING": "1"})
    assert allocator.opted_in({"GLINT_MALLOC_TUNING": " Yes "})
    assert not allocator.opted_in({"GLINT_MALLOC_TUNING": "0"})
    assert not allocator.opted_in({})


def test_small_pages_turns_numpy_huge_pages_off_while_held_and_restores_them():
    # NumPy 1.26 and 2.x both have the switch (returning the previous setting).
    switch = allocator._switch
    assert switch is not None
    before = switch(True)
    try:
        with allocator.small_pages():
            assert switch(False) is False        # off inside (and left so)
            with allocator.small_pages():
                assert switch(False) is False
            assert switch(False) is False        # an inner holder leaving keeps it off
        assert switch(True) is True              # the setting before is back
        with pytest.raises(RuntimeError):
            with allocator.small_pages():
                raise RuntimeError("a failed build")
        assert switch(True) is True              # restored after an error too
    finally:
        switch(before)


@pytest.mark.parametrize("parallelism", ["threads", "processes"])
def test_renders_run_on_small_pages_and_leave_the_setting_as_it_was(monkeypatch, parallelism):
    """A render allocates without huge-page advice in this process (tiles, tree, image; the
    workers keep it off for good), and the caller's setting is back afterwards."""
    from core import workers

    monkeypatch.setattr(workers, "MIN_PIXELS", 0)
    switch = allocator._switch
    before = switch(True)
    seen = []
    try:
        result = core.render(core.article_scene(64, 48),
                             core.RenderSettings(threads=2, tile_size=16,
                                                 parallelism=parallelism),
                             on_tile=lambda tile, pixels: seen.append(switch(False)))
        assert result.parallelism == parallelism
        assert seen and not any(seen)     # off while the tiles landed here
        assert switch(True) is True       # the caller's setting is back
    finally:
        switch(before)
