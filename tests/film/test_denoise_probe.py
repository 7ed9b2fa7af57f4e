"""A pyoidn whose import aborts its process (a broken native library: SIGABRT, no exception) is
probed in a child process first (engine/film/denoise.py probe_import): both command lines refuse
--denoise with one line "denoiser unavailable: ..." instead of dying without a message."""
import os
import subprocess
import sys

import pytest

from engine.film import denoise

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture
def aborting_pyoidn(tmp_path):
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "pyoidn.py").write_text("import os\nos.abort()\n")
    return fake


def test_an_aborting_pyoidn_is_named_without_killing_this_process(aborting_pyoidn, monkeypatch):
    # A pyoidn imported here by an earlier test is one that works (it is used as it is): forget it.
    monkeypatch.delitem(sys.modules, "pyoidn", raising=False)
    monkeypatch.setattr(denoise, "_PROBES", {})
    monkeypatch.syspath_prepend(str(aborting_pyoidn))
    problem = denoise.available()           # today's main: imported here, and this process aborted
    assert problem.startswith("denoiser unavailable: importing pyoidn killed its process (SIGABRT)"), problem
    assert "\n" not in problem and "pip install" in problem


def test_a_pyoidn_that_imports_passes_the_probe(tmp_path, monkeypatch):
    fine = tmp_path / "fine"
    fine.mkdir()
    (fine / "pyoidn.py").write_text("VERSION = 'fake'\n")
    monkeypatch.delitem(sys.modules, "pyoidn", raising=False)
    monkeypatch.setattr(denoise, "_PROBES", {})
    monkeypatch.syspath_prepend(str(fine))
    assert denoise.probe_import() is None


@pytest.mark.parametrize("cli", ["engine", pytest.param("mcrt_addon", marks=pytest.mark.slow)])   # bpy: ~5 s
def test_both_command_lines_refuse_an_aborting_pyoidn_in_one_line(cli, aborting_pyoidn, tmp_path):
    out = tmp_path / "d.exr"
    scene = ["--builtin", "cornell"] if cli == "engine" else [os.path.join(ROOT, "sample_blends", "cornell.blend")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(aborting_pyoidn), ROOT]))
    proc = subprocess.run([sys.executable, "-m", cli, "render", *scene, "--resolution", "16", "16", "--samples", "2",
                           "--denoise", "-o", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])      # today's main: -6 (SIGABRT)
    lines = [line for line in proc.stderr.splitlines() if "error:" in line]
    assert len(lines) == 1 and "denoiser unavailable: importing pyoidn killed its process" in lines[0], proc.stderr
    assert not out.exists()
