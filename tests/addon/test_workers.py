"""The add-on's render worker processes: a worker that crashes during a render in Blender is
reported by name while Blender carries on (same image), and workers die with their parent: no
orphan after SIGKILL of either command line (python -m mcrt_addon render, python -m engine render)."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import REPO
from tests.file_safety import alive, children
from mcrt_addon import render_engine as engine_module
from rendering import last_report, open_blend, render_operator


def test_a_worker_crash_in_blender_is_reported_by_name_and_the_render_completes(samples, monkeypatch):
    scene = open_blend(samples["cornell"], (64, 64))
    p = scene.tncg15
    p.samples, p.seed, p.tile_size, p.max_depth, p.threads = 32, 4, 16, 4, 2
    scene.render.engine = "TNCG15_MC"
    reference = render_operator(scene)
    killed = []

    def kill_one_worker(self):
        if not killed and getattr(self, "tiles_written", 0) > 0:
            workers = [c for c in children(os.getpid()) if b"worker" in open(f"/proc/{c}/cmdline", "rb").read()]
            os.kill(workers[0], signal.SIGKILL)
            killed.append(workers[0])
        return False

    monkeypatch.setattr(engine_module.TNCG15RenderEngine, "_cancel_requested", kill_one_worker)
    image = render_operator(scene)
    report = last_report()
    assert report.error is None and killed
    assert [w for w in report.warnings if f"(pid {killed[0]}) died: killed by SIGKILL" in w], report.warnings
    assert np.array_equal(image, reference)


@pytest.mark.parametrize("command", [
    [sys.executable, "-m", "mcrt_addon", "render", os.path.join(REPO, "sample_blends", "cornell.blend")],
    [sys.executable, "-m", "engine", "render", "--builtin", "cornell"]], ids=["mcrt_addon", "engine"])
def test_workers_die_with_a_killed_command_line(command, tmp_path):
    env = dict(os.environ, PYTHONPATH=REPO)
    proc = subprocess.Popen(command + ["-o", str(tmp_path / "out.exr"), "--samples", "4000", "--threads", "2",
                                       "--resolution", "128", "128"],
                            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    seen = b""
    while b"work units on" not in seen:
        chunk = os.read(proc.stdout.fileno(), 4096)
        assert chunk, seen[-2000:]
        seen += chunk
    deadline = time.time() + 20
    workers = []
    while len(workers) < 2 and time.time() < deadline:
        workers = children(proc.pid)
        time.sleep(0.05)
    assert len(workers) >= 2, workers
    proc.kill()
    proc.wait()
    deadline = time.time() + 15                       # a guard against a hang: they die within ms
    while any(alive(w) for w in workers) and time.time() < deadline:
        time.sleep(0.05)
    assert not [w for w in workers if alive(w)], "orphaned render workers"


@pytest.mark.slow          # 2.8 s; the cluster in `make test`: tests/pools/test_dask_cluster.py
def test_addon_cli_renders_on_a_dask_cluster_pixel_identical(tmp_path):
    """--cluster (the add-on's Render cluster preference) sends the work units to Dask workers:
    the same image as the local worker processes."""
    from engine.film.image_files import read_image
    blend = os.path.join(REPO, "sample_blends", "cornell.blend")
    images = {}
    for name, extra in (("local", []), ("dask", ["--cluster", "local"])):
        out = tmp_path / f"{name}.exr"
        r = subprocess.run([sys.executable, "-m", "mcrt_addon", "render", blend, "-o", str(out), "--samples", "8",
                            "--resolution", "48", "32", "--seed", "4", "--stats-json", str(tmp_path / f"{name}.json"),
                            *extra], cwd=REPO, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        images[name] = read_image(str(out))
    import json
    assert json.load(open(tmp_path / "dask.json"))["parallelism"].startswith("dask")
    assert np.array_equal(images["local"], images["dask"])
