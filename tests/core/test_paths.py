"""engine/core/paths.py: where the tracer package is, and a worker environment in which another
Python, started anywhere, imports this very tracer."""
import os
import subprocess
import sys

import engine
from engine.core.paths import TRACER_BASE, TRACER_DIR, worker_environment


def test_the_tracer_is_found_where_it_is():
    assert TRACER_BASE == "engine"
    assert TRACER_DIR == os.path.dirname(os.path.abspath(engine.__file__))


def test_a_worker_started_elsewhere_imports_this_tracer(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONHOME", sys.prefix)             # a Blender-style home must not leak
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    extra = tmp_path / "wheels"
    extra.mkdir()
    (extra / "bundled_marker.py").write_text("")
    env = worker_environment([str(extra)])
    assert "PYTHONHOME" not in env and env["PYTHONNOUSERSITE"] == "1" and env["OMP_NUM_THREADS"] == "1"
    paths = env["PYTHONPATH"].split(os.pathsep)
    assert paths[:2] == [os.path.dirname(TRACER_DIR), str(extra)] and len(paths) == len(set(paths))
    code = "import engine, bundled_marker, numpy; print(engine.__file__)"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == engine.__file__


def test_control_without_the_environment_the_tracer_is_not_found(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", "import engine"], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode != 0 and "No module named 'engine'" in out.stderr


def test_a_thread_count_already_set_is_kept(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "4")
    assert worker_environment()["OMP_NUM_THREADS"] == "4"
