"""Tiles on a Dask cluster (core.cluster): a ``distributed.LocalCluster`` of 2 worker processes
on this machine, whose workers import Glint's core as pip installs it (``pyproject.toml``,
built here into a folder of its own).  The image is the local render's bit for bit (an
article scene through render.py, a triangle scene path traced in passes through the core),
also when a worker is killed mid-frame; a wrong address, a scheduler without workers, a
worker of another Glint, a missing ``distributed`` and Ctrl-C each end the render with one
line; TLS works."""

from __future__ import annotations

import dataclasses
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from process_support import sigint_disposition

import core
from core import cluster
from core.validation import SceneError
from test_path_integrator import _box_scene

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RENDER_SCRIPT = os.path.join(REPOSITORY, "render.py")
#: Every test here starts a cluster, child processes or a pip install, and needs Dask's
#: distributed (the optional extra the default venv installs, imported where used).
pytestmark = pytest.mark.slow
#: Long enough for a worker process to start and import the core on a loaded machine.
START_SECONDS = 60


@pytest.fixture(scope="module")
def worker_site(tmp_path_factory):
    """Glint's core installed by pip from the repository's pyproject.toml, as a worker
    installs it, into a folder on this process's sys.path: LocalCluster's worker processes
    take the parent's sys.path (and the submitter imports the core as ``core``, so the
    workers' ``glint_raytracer_core`` is another name for it, as on a real cluster)."""
    source = tmp_path_factory.mktemp("core-source")
    shutil.copy(os.path.join(REPOSITORY, "pyproject.toml"), source)
    shutil.copytree(os.path.join(REPOSITORY, "core"), source / "core",
                    ignore=shutil.ignore_patterns("__pycache__"))
    site = tmp_path_factory.mktemp("worker-site")
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                    "--no-index", "--no-build-isolation", "--target", str(site), str(source)],
                   check=True, capture_output=True)
    sys.path.append(str(site))
    yield site
    sys.path.remove(str(site))


def _local_cluster(**options):
    import distributed

    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                    dashboard_address=":0", silence_logs=logging.ERROR,
                                    **options)


@pytest.fixture(scope="module")
def local_cluster(worker_site):
    with _local_cluster() as made:
        yield made
        cluster.close_clients()


def _glint_tasks(scheduler) -> list:
    return [key for key in list(scheduler.tasks) if str(key).startswith("glint-")]


def _wait_for_workers(local_cluster, count=2):
    cluster.client(local_cluster.scheduler_address).wait_for_workers(count,
                                                                     timeout=START_SECONDS)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_the_installed_core_is_this_checkout_under_its_own_name(worker_site):
    installed = os.path.join(worker_site, cluster.WORKER_PACKAGE)
    assert os.path.isfile(os.path.join(installed, "cluster.py"))
    assert not os.path.exists(os.path.join(worker_site, "core"))   # no top-level 'core'
    # Every subpackage of the checkout's core is installed (the package list is explicit).
    core_folder = os.path.join(REPOSITORY, "core")
    for folder, _, files in os.walk(core_folder):
        if "__init__.py" in files:
            relative = os.path.relpath(folder, core_folder)
            assert os.path.isfile(os.path.join(installed, relative, "__init__.py")), relative
    with open(os.path.join(REPOSITORY, "blender_manifest.toml")) as manifest:
        assert f'version = "{cluster.VERSION}"' in manifest.read()
    names = sorted(os.listdir(worker_site))
    assert f"{cluster.WORKER_DISTRIBUTION.replace('-', '_')}-{cluster.VERSION}.dist-info" \
        in names
    # The same source as this checkout's: a worker installed from it is not refused.
    import glint_raytracer_core.cluster as installed
    assert installed.identity() == cluster.identity()


def test_a_frames_tiles_are_dealt_into_a_few_tasks_per_worker():
    tiles = list(range(135))
    groups = cluster.task_groups(tiles, 2)
    assert len(groups) == 2 * cluster.TASKS_PER_WORKER
    assert sorted(sum(groups, [])) == tiles and groups[0][:3] == [0, 8, 16]
    assert cluster.task_groups(tiles[:3], 64) == [[0], [1], [2]]


def test_a_path_traced_triangle_scene_is_the_local_image_bit_for_bit(local_cluster):
    scene = _box_scene(64, 48)
    # 4 samples: passes of 1, 1 and 2 samples, each submitted as the last one lands.
    base = core.RenderSettings(samples=4, tile_size=16, threads=2)
    local = core.render(scene, dataclasses.replace(base, parallelism="processes"))
    landed = []
    remote = core.render(scene, dataclasses.replace(base, cluster=local_cluster.scheduler_address),
                         on_tile=lambda tile, rgba: landed.append(tile))
    assert remote.parallelism == "cluster"
    np.testing.assert_array_equal(remote.image, local.image)
    assert remote.stats == local.stats
    assert len(landed) == 3 * 12          # every tile of every pass handed over as it landed
    assert cluster.last_render["workers"] == 2 and cluster.last_render["tiles"] == 36


def test_an_article_frame_through_render_py_is_the_local_png_bit_for_bit(local_cluster,
                                                                          tmp_path):
    arguments = [RENDER_SCRIPT, "--width", "240", "--height", "160", "--quiet"]
    local, remote = tmp_path / "local.png", tmp_path / "remote.png"
    subprocess.run([sys.executable, *arguments, "--output", str(local)], check=True,
                   capture_output=True, cwd=REPOSITORY)
    run = subprocess.run([sys.executable, *arguments, "--output", str(remote), "--cluster",
                          local_cluster.scheduler_address],
                         capture_output=True, text=True, cwd=REPOSITORY)
    assert run.returncode == 0, run.stderr
    assert remote.read_bytes() == local.read_bytes()


def test_a_worker_killed_mid_frame_changes_nothing(local_cluster):
    _wait_for_workers(local_cluster)
    scene = _box_scene(96, 64)
    base = core.RenderSettings(samples=4, tile_size=16, threads=2, parallelism="threads")
    reference = core.render(scene, base)
    connection = cluster.client(local_cluster.scheduler_address)
    victim = sorted(connection.run(os.getpid).values())[0]
    killed = []

    def kill_once(tile, rgba):
        if not killed:
            os.kill(victim, signal.SIGKILL)   # mid-frame: 143 of 144 jobs still to land
            killed.append(tile)

    remote = core.render(scene, dataclasses.replace(base, cluster=local_cluster.scheduler_address),
                         on_tile=kill_once)
    assert killed
    np.testing.assert_array_equal(remote.image, reference.image)
    assert victim not in connection.run(os.getpid).values()
    _wait_for_workers(local_cluster)     # (its nanny starts another, for the next tests)


def test_ctrl_c_cancels_the_frames_tasks_on_the_cluster(local_cluster):
    _wait_for_workers(local_cluster)
    scene = core.article_scene(640, 480)
    settings = core.RenderSettings(semantics="article", anti_aliasing="fixed", samples=16,
                                   tile_size=32, cluster=local_cluster.scheduler_address)

    def interrupt(tile, rgba):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        core.render(scene, settings, on_tile=interrupt)
    # 300 tiles were submitted; after the cancel none stays on the scheduler.
    deadline = time.monotonic() + 10
    while _glint_tasks(local_cluster.scheduler) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _glint_tasks(local_cluster.scheduler) == []


def test_ctrl_c_in_render_py_cancels_the_tasks_and_writes_nothing(local_cluster, tmp_path):
    _wait_for_workers(local_cluster)
    output = tmp_path / "out.png"
    process = subprocess.Popen(
        [sys.executable, RENDER_SCRIPT, "--width", "1920", "--height", "1080", "--samples",
         "64", "--output", str(output), "--cluster", local_cluster.scheduler_address],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPOSITORY,
        preexec_fn=sigint_disposition())
    try:
        deadline = time.monotonic() + START_SECONDS
        while not _glint_tasks(local_cluster.scheduler) and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()
            time.sleep(0.1)
        assert _glint_tasks(local_cluster.scheduler), "the render never reached the cluster"
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == \
        "render.py: error: cancelled by SIGINT (Ctrl-C); nothing written"
    assert not output.exists()
    deadline = time.monotonic() + 10
    while _glint_tasks(local_cluster.scheduler) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _glint_tasks(local_cluster.scheduler) == []


def test_a_worker_of_another_glint_is_refused_with_one_line(local_cluster, monkeypatch):
    settings = core.RenderSettings(cluster=local_cluster.scheduler_address)
    scene = core.article_scene(32, 24)
    version, source = cluster.identity()
    monkeypatch.setattr(cluster, "_identity", ("9.9.9", source))
    with pytest.raises(cluster.ClusterError, match=rf"^cluster worker tcp://\S+ runs Glint "
                                                   rf"{version}, this is Glint 9\.9\.9: "
                                                   rf"install the same version"):
        core.render(scene, settings)
    monkeypatch.setattr(cluster, "_identity", (version, "0" * 16))
    with pytest.raises(cluster.ClusterError, match=r"runs another build of Glint"):
        core.render(scene, settings)


def test_an_unreachable_scheduler_is_one_line_and_render_py_writes_nothing(tmp_path,
                                                                           monkeypatch):
    address = f"tcp://127.0.0.1:{_free_port()}"
    monkeypatch.setenv(cluster.TIMEOUT_VARIABLE, "1")
    with pytest.raises(cluster.ClusterError,
                       match=rf"^cannot reach the Dask scheduler at {address} within 1 s"):
        core.render(core.article_scene(32, 24), core.RenderSettings(cluster=address))
    output = tmp_path / "out.png"
    run = subprocess.run([sys.executable, RENDER_SCRIPT, "--width", "32", "--height", "24",
                          "--output", str(output), "--cluster", address],
                         capture_output=True, text=True, cwd=REPOSITORY,
                         env={**os.environ, cluster.TIMEOUT_VARIABLE: "1"})
    assert run.returncode == 1
    assert run.stderr.strip().splitlines()[-1].startswith(
        f"render.py: error: cannot reach the Dask scheduler at {address}")
    assert not output.exists()


def test_a_scheduler_without_workers_is_one_line(worker_site, monkeypatch):
    monkeypatch.setenv(cluster.TIMEOUT_VARIABLE, "1")
    import distributed

    with distributed.LocalCluster(n_workers=0, protocol="tcp://", dashboard_address=":0",
                                  silence_logs=logging.ERROR) as empty:
        address = empty.scheduler_address
        try:
            with pytest.raises(cluster.ClusterError,
                               match=rf"^the Dask scheduler at {address} has no workers "
                                     rf"\(waited 1 s\): start some with 'dask worker"):
                core.render(core.article_scene(32, 24), core.RenderSettings(cluster=address))
        finally:
            cluster.close_clients()


def test_without_distributed_the_line_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)   # (import fails)
    with pytest.raises(cluster.ClusterError, match=r'pip install "dask\[distributed\]"$'):
        core.render(core.article_scene(32, 24),
                    core.RenderSettings(cluster="tcp://127.0.0.1:8786"))


def test_the_core_and_local_renders_do_not_import_distributed():
    code = ("import sys; sys.modules['distributed'] = None; sys.modules['dask'] = None\n"
            "import core, core.cluster\n"
            "result = core.render(core.article_scene(40, 30))\n"
            "assert result.parallelism == 'threads' and result.image.shape == (30, 40, 4)\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPOSITORY)


@pytest.mark.parametrize("address", ["8786", "localhost:8786", "http://host:8786",
                                     "tcp://host", "tcp://host:99999", "tcp://a b:1"])
def test_a_malformed_address_names_the_setting(address):
    with pytest.raises(SceneError, match=r"^settings\.cluster must be a Dask scheduler "
                                         r"address such as tcp://HOST:8786"):
        core.RenderSettings(cluster=address)


def test_tls_renders_with_dasks_security_configuration(worker_site, tmp_path):
    """A scheduler and workers that accept only TLS, with a self-signed certificate; this
    process reads its certificate from Dask's configuration (as DASK_DISTRIBUTED__COMM__TLS__*
    variables or a YAML file would set it)."""
    import dask
    from distributed.security import Security

    key, certificate = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                    "-subj", "/CN=localhost", "-keyout", str(key), "-out", str(certificate)],
                   check=True, capture_output=True)
    paths = dict(tls_ca_file=str(certificate), require_encryption=True)
    for role in ("scheduler", "worker", "client"):
        paths[f"tls_{role}_cert"], paths[f"tls_{role}_key"] = str(certificate), str(key)
    scene = core.article_scene(120, 80)
    settings = core.RenderSettings(semantics="article", tile_size=32)
    local = core.render(scene, settings)
    with _local_cluster(protocol="tls://", security=Security(**paths)) as secure:
        address = secure.scheduler_address
        assert address.startswith("tls://")
        try:
            with dask.config.set({"distributed.comm.tls.ca-file": str(certificate),
                                  "distributed.comm.tls.client.cert": str(certificate),
                                  "distributed.comm.tls.client.key": str(key),
                                  "distributed.comm.require-encryption": True}):
                remote = core.render(scene, dataclasses.replace(settings, cluster=address))
        finally:
            cluster.close_clients()
    np.testing.assert_array_equal(remote.image, local.image)


def test_a_tls_address_without_certificates_is_one_line():
    with pytest.raises(cluster.ClusterError, match=r"^tls://127\.0\.0\.1:9 is a TLS scheduler, "
                                                   r"but Dask's configuration gives this "
                                                   r"process no TLS certificate"):
        core.render(core.article_scene(32, 24),
                    core.RenderSettings(cluster="tls://127.0.0.1:9"))
