"""engine/film/denoise.py probe (the trial before the import; tests/film/test_denoise_probe.py has
the import-only probe_import): a pyoidn that aborts while loading ends only the trial process,
never the caller (the command lines, Blender); the answer is kept per Python and path; a pyoidn
that works is then imported here.  Fake pyoidn packages, no OIDN needed."""
import sys

import numpy as np
import pytest

from engine.film import denoise

ABORTS = "import os\nos.abort()\n"
WORKS = ("import numpy as np\n"
         "def denoise(color, hdr=True, albedo=None, normal=None):\n"
         "    return np.full_like(color, color.mean())\n")


def fake_pyoidn(tmp_path, body):
    pkg = tmp_path / "pyoidn"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(body)
    return str(tmp_path)


@pytest.fixture
def fresh(monkeypatch):
    """No pyoidn imported and no probe remembered, and both as before afterwards (a fake pyoidn
    imported by a test does not stay in sys.modules)."""
    before = sys.modules.pop("pyoidn", None)
    monkeypatch.setattr(denoise, "_PROBES", {})
    monkeypatch.setattr(denoise, "_TRUSTED", [False])
    yield
    sys.modules.pop("pyoidn", None)
    if before is not None:
        sys.modules["pyoidn"] = before


def test_an_aborting_pyoidn_is_reported_and_this_process_lives(tmp_path, monkeypatch, fresh):
    path = fake_pyoidn(tmp_path, ABORTS)
    problem = denoise.probe(sys.executable, (path,))
    assert problem.startswith("denoiser unavailable: importing pyoidn killed its process (SIGABRT)"), problem
    assert "Install Denoiser" in problem and "\n" not in problem
    monkeypatch.syspath_prepend(path)                 # this process would import the aborting one
    assert "SIGABRT" in denoise.available()           # ... but it is tried elsewhere first
    with pytest.raises(denoise.DenoiserUnavailable, match="SIGABRT"):
        denoise.denoise(np.zeros((4, 4, 3), np.float32))
    assert "pyoidn" not in sys.modules


def test_a_working_pyoidn_is_probed_once_then_imported_here(tmp_path, monkeypatch, fresh):
    path = fake_pyoidn(tmp_path, WORKS)
    monkeypatch.syspath_prepend(path)
    runs = []
    real = denoise._run_probe
    monkeypatch.setattr(denoise, "_run_probe", lambda *a, **k: runs.append(a) or real(*a, **k))
    assert denoise.available() is None and denoise.available() is None
    assert len(runs) == 1, "the probe is cached"
    out = denoise.denoise(np.arange(48, dtype=np.float32).reshape(4, 4, 3))
    assert np.allclose(out, 23.5)                     # the fake's answer: it was imported here
    assert sys.modules["pyoidn"].__file__.startswith(path)


def test_probe_cached_never_waits(tmp_path, fresh):
    path = fake_pyoidn(tmp_path, WORKS)
    done, problem = denoise.probe_cached(sys.executable, (path,))
    assert (done, problem) == (False, None)           # started on a thread
    denoise._PROBING[(sys.executable, (path,))].join(60)
    assert denoise.probe_cached(sys.executable, (path,)) == (True, None)
