"""engine/core/backend.py: the choice of backend, numba missing, the per-user cache and its stamp,
and whole renders on both backends (bit-identical images; the stats and the effect plan name the
backend of each kernel)."""
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from engine import api
from engine.core import backend
from engine.core.settings import RenderSettings
from engine.scene.builtin import BUILTIN_SCENES
from tests.backend_capture import require_compiled

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture
def numba_missing(monkeypatch):
    monkeypatch.setattr(backend, "_state", {"checked": True, "module": None, "error": "ImportError: simulated",
                                            "warming": None})


def render(name, backend_name, resolution=16, samples=4):
    return api.render(BUILTIN_SCENES[name]((resolution, resolution)),
                      RenderSettings(samples=samples, threads=1, backend=backend_name), log=lambda m: None)


def test_numpy_is_numpy_and_needs_no_numba(numba_missing):
    assert backend.resolve("numpy")[0] == "numpy"


def test_numba_missing_falls_back_to_numpy(numba_missing):
    said = []
    assert backend.resolve("auto", said.append)[0] == "numpy"
    assert backend.resolve("numba", said.append)[0] == "numpy"
    assert any("warning" in s and "simulated" in s for s in said)
    result = render("many_lights", "auto", resolution=8, samples=1)
    assert result.stats["backend"] == "numpy" and set(result.stats["kernel_backends"].values()) == {"numpy"}
    assert "not available" in result.stats["backend_reason"]


def test_cache_dir_is_per_user(monkeypatch, tmp_path):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    digest = backend.sources_digest()
    assert backend.cache_dir() == str(tmp_path / "tncg15_mc" / "numba" / digest) and os.path.isdir(backend.cache_dir())
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "given"))
    assert backend.cache_dir() == str(tmp_path / "given" / digest)
    monkeypatch.setenv("NUMBA_CACHE_DIR", backend.cache_dir())           # a worker given the folder keeps it
    assert backend.cache_dir() == str(tmp_path / "given" / digest)
    # a child running other sources (replay_embree --baseline's checkout) given this folder: a sibling,
    # not a cache nested in this version's folder (which it would compile into, cold, every time)
    other = backend.DIGEST_PREFIX + "0123456789abcdef"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "given" / other))
    assert other != digest and backend.cache_dir() == str(tmp_path / "given" / digest)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "given" / "my-cache"))   # a user's own: kept
    assert backend.cache_dir() == str(tmp_path / "given" / "my-cache" / digest)


def test_cache_follows_the_sources_a_twin_calls(monkeypatch, tmp_path):
    """numba's index checks a module's own source only: the cache folder must change when a module
    a twin imports (its callee's kernels, constants) changes, and not for a module it does not import."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "callee_jit.py").write_text("K = 1.0\n")
    (pkg / "caller_jit.py").write_text("from .callee_jit import K\nfrom . import (\n    consts,\n)\n")
    (pkg / "consts.py").write_text("C = 2.0\n")
    (pkg / "unrelated.py").write_text("U = 3.0\n")
    monkeypatch.setattr(backend, "jit_files", lambda: [str(pkg / "caller_jit.py")])

    def digest():
        monkeypatch.delitem(backend._state, "digest", raising=False)
        return backend.sources_digest()
    before = digest()
    (pkg / "unrelated.py").write_text("U = 4.0\n")
    assert digest() == before                                          # control: not imported
    (pkg / "callee_jit.py").write_text("K = 1.5\n")
    after_callee = digest()
    assert after_callee != before
    (pkg / "consts.py").write_text("C = 2.5\n")
    assert digest() != after_callee


def test_old_caches_of_other_sources_are_pruned(monkeypatch, tmp_path):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    here = backend.cache_dir()
    old, recent = tmp_path / "twins-0000000000000000", tmp_path / "twins-1111111111111111"
    other = tmp_path / "not-ours"
    for folder in (old, recent, other):
        folder.mkdir()
        (folder / "warm-x.stamp").write_text("1\n")
    long_ago = time.time() - 40 * 86400
    for path in (old, old / "warm-x.stamp", other, other / "warm-x.stamp"):
        os.utime(path, (long_ago, long_ago))
    assert backend.prune_old_caches() == [str(old)]
    assert not old.exists() and recent.exists() and other.exists() and os.path.isdir(here)


def test_auto_on_a_cold_cache_renders_numpy_and_warms_in_the_background(monkeypatch, tmp_path):
    require_compiled()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))          # no stamp there
    started = []
    monkeypatch.setattr(backend, "start_warm_up", lambda log: started.append(1))
    assert not backend.is_warm()
    assert backend.resolve("auto")[0] == "numpy" and started


def test_stamp_follows_the_twins_sources(monkeypatch, tmp_path):
    twin = tmp_path / "x_jit.py"
    twin.write_text("pass\n")
    monkeypatch.setattr(backend, "jit_files", lambda: [str(twin)])
    stamp = backend.stamp_path()
    os.utime(twin, ns=(0, 10**18))                                   # numba would recompile it
    assert backend.stamp_path() != stamp


@pytest.mark.parametrize("name", ["cornell", "many_lights"])
def test_renders_are_bit_identical_on_both_backends(name):
    require_compiled()
    a, b = render(name, "numpy"), render(name, "numba")
    assert b.stats["backend"] == "numba" and a.stats["backend"] == "numpy"
    expected = {"cornell": {"spheres", "quads", "sobol", "emission", "wavefront"},
                "many_lights": {"spheres", "light_tree", "sobol", "emission", "wavefront"}}[name]
    assert set(b.stats["kernel_backends"]) == expected and set(b.stats["kernel_backends"].values()) == {"numba"}
    assert np.array_equal(a.image, b.image)


@pytest.mark.slow
def test_render_in_a_python_where_numba_cannot_be_imported(tmp_path):
    code = ("import sys; sys.modules['numba'] = None\n"
            "from engine import api; from engine.core.settings import RenderSettings\n"
            "from engine.scene.builtin import many_lights_scene\n"
            "r = api.render(many_lights_scene((8, 8)), RenderSettings(samples=1, threads=1, backend='numba'))\n"
            "print('BACKEND', r.stats['backend'])\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=str(tmp_path)))
    assert out.returncode == 0, out.stderr
    assert "BACKEND numpy" in out.stdout and "warning: backend numba asked for" in out.stdout


@pytest.mark.slow
def test_cold_compile_then_cache_load(tmp_path):
    """python -m engine.core.backend in an empty cache compiles and stamps; a second run loads."""
    env = dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=str(tmp_path))
    for _ in range(2):
        out = subprocess.run([sys.executable, "-m", "engine.core.backend"], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        assert f"kernels {len(backend.JIT_MODULES)}/{len(backend.JIT_MODULES)} ready" in out.stdout
    folder = tmp_path / backend.sources_digest()
    assert any(n.startswith("warm-") and n.endswith(".stamp") for n in os.listdir(folder))


@pytest.mark.slow
def test_background_warm_up_stamps_the_cache(monkeypatch, tmp_path):
    """auto on a cold cache: NumPy now, a Python process compiling into the cache, numba next time."""
    require_compiled()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(backend, "_state", dict(backend._state, warming=None))
    said = []
    assert backend.resolve("auto", said.append)[0] == "numpy"
    worker = backend._state["warming"]
    assert worker is not None and any("background" in s for s in said)
    assert backend.start_warm_up(said.append) is None                # one at a time
    worker.wait(timeout=300)
    assert worker.returncode == 0 and backend.is_warm()
    assert not os.path.exists(backend.stamp_path() + ".lock")
    assert backend.resolve("auto")[0] == "numba"


def test_a_scene_without_compiled_kernels_never_imports_numba(numba_missing):
    assert backend.resolve("numba", kernels=["triangles", "diffuse"]) == (
        "numpy", "no kernel of this scene has a compiled twin")


def test_a_cold_compile_shares_the_modules_with_a_second_python(monkeypatch):
    """load_kernels(parallel=True) on a cold cache: a child compiles the second half of the modules
    while this process compiles the first; this process waits for it before loading the second
    half (from the cache), in JIT_MODULES' order.  Control: parallel=False starts no child."""
    events = []

    class Child:
        def wait(self):
            events.append("wait")

    names = list(backend.JIT_MODULES)
    half = set(names[names.index(backend.SECOND_HALF_FROM):])
    monkeypatch.setattr(backend, "numba_module", lambda: object())
    monkeypatch.setattr(backend, "is_warm", lambda: False)
    monkeypatch.setattr(backend, "load_modules", lambda ns: events.extend(ns))
    for parallel in (True, False):
        events.clear()
        started = []
        monkeypatch.setattr(backend, "_compile_second_half", lambda: started.append(1) or (Child(), half))
        monkeypatch.setattr(backend, "_state", dict(backend._state, loaded=False))
        backend.load_kernels(parallel=parallel)
        assert [e for e in events if e != "wait"] == names
        if parallel:
            assert started and events.count("wait") == 1 and 0 < len(half) < len(names)
            assert events.index("wait") == names.index(backend.SECOND_HALF_FROM)   # just before its half
        else:
            assert not started and "wait" not in events
