"""mcrt_addon/worker_python.py: which Python runs the render workers and what it gets on its path."""
import os
import sys

import pytest

import mcrt_addon  # noqa: F401
from mcrt_addon import worker_python as wp


def test_in_the_bpy_module_the_workers_run_this_python():
    assert wp.in_bpy_module() and wp.candidates() == [sys.executable]
    assert wp.worker_python() == (sys.executable, None)


def test_a_preferred_python_must_be_an_executable_file(tmp_path):
    assert wp.worker_python(sys.executable) == (sys.executable, None)
    missing = str(tmp_path / "python9")
    path, why = wp.worker_python(missing)
    assert path is None and "not an executable file" in why and missing in why
    script = tmp_path / "python"
    script.write_text("#!/bin/sh\n")
    assert wp.worker_python(str(script))[0] is None                       # not executable
    os.chmod(script, 0o755)
    assert wp.worker_python(str(script)) == (str(script), None)


def test_no_interpreter_is_a_message(monkeypatch):
    monkeypatch.setattr(wp, "candidates", lambda: ["/nonexistent/python3"])
    assert wp.worker_python() == (None, "no Python interpreter found next to Blender")


def test_extra_paths_are_the_bundled_wheels_only_when_bundled(monkeypatch, tmp_path):
    assert wp.extra_paths() == []                                         # the repository: nothing bundled
    worker = tmp_path / "vendor" / "worker"
    worker.mkdir(parents=True)
    monkeypatch.setattr(wp, "VENDOR_WORKER", str(worker))
    monkeypatch.setattr(wp, "VENDOR_NUMPY", str(tmp_path / "vendor" / "numpy"))
    monkeypatch.setattr(sys, "path", sys.path + [str(tmp_path / "vendor" / "numpy")])
    assert wp.extra_paths() == [str(tmp_path / "vendor" / "numpy"), str(worker)]


def test_numpy_is_found_and_the_cluster_comes_from_the_environment(monkeypatch):
    assert wp.ensure_numpy() is None and wp.NUMPY_PROBLEM is None
    monkeypatch.setenv("TNCG15_CLUSTER", "tcp://10.0.0.1:8786")
    assert wp.render_cluster() == "tcp://10.0.0.1:8786"


@pytest.mark.parametrize("vendored", [False, True])
def test_missing_numpy_names_what_to_install(monkeypatch, tmp_path, vendored):
    import builtins
    real_import = builtins.__import__

    def no_numpy(name, *args, **kwargs):
        if name == "numpy":
            raise ImportError("No module named 'numpy'")
        return real_import(name, *args, **kwargs)
    monkeypatch.setattr(builtins, "__import__", no_numpy)
    vendor = tmp_path / "numpy_vendor"
    if vendored:
        vendor.mkdir()
    monkeypatch.setattr(wp, "VENDOR_NUMPY", str(vendor))
    problem = wp._numpy_problem()
    assert "apt-get install python3-numpy" in problem
    assert ("bundled numpy does not load" in problem) == vendored
    assert str(vendor) not in sys.path
