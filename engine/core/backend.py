"""Which backend runs the hot kernels: NumPy (the reference, always there) or numba (compiled twins).

The setting `backend` (engine/core/settings.py) is "numpy", "numba" or "auto".  The compiled twins
are the modules named `*_jit.py` beside their NumPy modules (JIT_MODULES below); each has a
`warm_up()` that calls its kernels once on small arrays of the types a render passes, so numba
compiles them and writes them to its cache (`cache=True`).

* numba is imported only here (`numba_module`), after NUMBA_CACHE_DIR is set to a writable
  per-user directory (`cache_dir`: $NUMBA_CACHE_DIR if set, else $XDG_CACHE_HOME or ~/.cache,
  then tncg15_mc/numba; in it a folder named by the digest of the twins' sources), so every
  process of a render (threads, forked and worker processes) reads and writes the same cache.
  numba's own index checks only each module's own source: a twin calling another module's kernel
  (principled_jit -> microfacet_jit) or reading its constants (parallelograms_jit -> trig) would
  keep machine code built from the old callee.  The digest (`sources_digest`: the twins and the
  tracer modules they import) gives every version of the sources a cache of its own.
* Compiling takes 20-35 s once per machine (about 19 s on two cores: `load_kernels(parallel=True)`;
  and again when a kernel's source or numba changes);
  loading from the cache well under a second.  A stamp file in the cache directory
  (`stamp_path`: named by numba's and Python's versions and the twins' paths, sizes and
  modification times, which is what numba's own cache index checks) says the cache is warm.
* "auto" takes numba only when the cache is warm; otherwise that render runs on NumPy and a
  warm-up starts in the background (`start_warm_up`: a separate Python process, or a thread where
  this process is not a Python interpreter), with a progress line, so the compile never holds up
  a render or its Esc.  "numba" compiles first when needed (saying so) and falls back to NumPy
  with a warning when numba cannot be imported.

The NumPy kernels give the same images bit for bit: the twins repeat the same float operations in
the same order (tests/core/test_backend.py and the tests of each twin check it on captured inputs).
"""
from __future__ import annotations

import hashlib
import importlib
import os
import re
import subprocess
import sys
import threading
import time

from .paths import TRACER_BASE, TRACER_DIR

NUMPY, NUMBA, AUTO = "numpy", "numba", "auto"        # the setting's values (engine/core/settings.py)

# The compiled twins, relative to the tracer package, and the kernels each one serves: effects of
# the plan (engine/integrators/effects.py), "sobol" for the Sobol' sampler and "wavefront" for the
# path tracer's own glue that every render runs (the hit sort, the compaction of the paths).
JIT_MODULES = {
    "lights.selection_jit": ("light_tree",),
    "geometry.shapes.spheres_jit": ("spheres",),
    "geometry.shapes.quads_jit": ("quads",),
    "geometry.shapes.light_polygons_jit": ("area_lights",),
    "sampling.sobol_jit": ("sobol",),
    "materials.lambert_jit": ("wavefront",),
    "materials.glass_jit": ("wavefront",),
    "materials.microfacet_jit": ("glossy", "principled", "mix"),
    "materials.dielectric_jit": ("rough_glass", "refraction", "filter_glossy", "principled", "mix"),
    "materials.principled_jit": ("principled", "mix"),
    "materials.principled_v1_jit": ("principled", "mix"),
    "materials.mix_jit": ("mix",),
    "lights.parallelograms_jit": ("emission",),
    "geometry.hits_jit": ("wavefront",),
    "geometry.shading_normals_jit": ("wavefront",),
    "nodes.normals_jit": ("wavefront",),
    "geometry.accel.embree_jit": ("wavefront",),
    "integrators.wavefront_jit": ("wavefront",),
    "scene.camera_rays_jit": ("wavefront",),
    "lights.light_set_jit": ("emission", "wavefront"),
    "lights.environment_jit": ("wavefront",),
    "sampling.warps_jit": ("wavefront",),
    "integrators.photons.gather_jit": ("photon_caustics",),
    "materials.textures_jit": ("textures",),
    "nodes.context_jit": ("textures",),
}
KERNELS = tuple(k for names in JIT_MODULES.values() for k in names)

PRUNE_AFTER_DAYS = 30.0                           # another twin-source cache unused this long is removed
STALE_LOCK_SECONDS = 600.0                        # a warm-up lock older than this was left by a dead process

_state = {"checked": False, "module": None, "error": None, "warming": None}
_lock = threading.Lock()


DIGEST_PREFIX = "twins-"         # the cache folders' names: this prefix and a digest of the sources


def cache_root() -> str:
    """The per-user directory holding numba's caches, one folder per version of the twins' sources:
    $NUMBA_CACHE_DIR, else $XDG_CACHE_HOME or ~/.cache, then tncg15_mc/numba.  A process started
    with NUMBA_CACHE_DIR already naming a twins folder (a worker, the warm-up's Python, or a child
    running another checkout's sources: scripts/replay_embree.py --baseline) gets its parent, never a
    cache nested inside another version's folder."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "tncg15_mc", "numba")
    root = os.path.normpath(root)
    return os.path.dirname(root) if os.path.basename(root).startswith(DIGEST_PREFIX) else root


def cache_dir() -> str:
    """The directory of numba's cache for today's twin sources (created when missing): the folder
    `sources_digest()` in `cache_root()`."""
    path = os.path.join(cache_root(), sources_digest())
    os.makedirs(path, exist_ok=True)
    return path


_RELATIVE_IMPORT = re.compile(r"^[ \t]*from[ \t]+(\.+)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)", re.M)


def _imported_tracer_files(path: str) -> list:
    """The tracer's own modules a source file imports (relative imports: `from . import trig`,
    `from .microfacet_jit import vndf`, `from ..core.backend import numba_module`).  A regular
    expression, not the ast module: this runs in every process that imports numba."""
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    found = []
    for dots, module, names in _RELATIVE_IMPORT.findall(text):
        base = os.path.dirname(path)
        for _ in range(len(dots) - 1):
            base = os.path.dirname(base)
        if module:
            targets = [module.split(".")]
        else:
            targets = [[name.split()[0]] for name in names.strip("()").replace("\n", " ").split(",") if name.strip()]
        for target in targets:
            candidate = os.path.join(base, *target) + ".py"
            if os.path.isfile(candidate):
                found.append(os.path.normpath(candidate))
    return found


def sources_digest() -> str:
    """"twins-" and a digest of the twins' sources and of the tracer modules they import (their
    contents and paths), computed once per process."""
    if "digest" not in _state:
        files = []
        for path in jit_files():
            files += [path] + _imported_tracer_files(path)
        digest = hashlib.sha1()
        for path in sorted(set(files)):
            with open(path, "rb") as fh:
                digest.update(path.encode() + b"\0" + fh.read() + b"\0")
        _state["digest"] = DIGEST_PREFIX + digest.hexdigest()[:16]
    return _state["digest"]


def numba_module():
    """The numba module, imported once with NUMBA_CACHE_DIR set; None when it cannot be imported
    (not installed, no wheel for this platform, a broken llvmlite): `numba_error()` says why."""
    with _lock:
        if not _state["checked"]:
            _state["checked"] = True
            try:
                os.environ["NUMBA_CACHE_DIR"] = cache_dir()
                _state["module"] = importlib.import_module("numba")
            except Exception as exc:           # ImportError, or OSError of an unwritable cache / a bad llvmlite
                _state["error"] = f"{type(exc).__name__}: {exc}"
        return _state["module"]


def numba_available() -> bool:
    return numba_module() is not None


def numba_error() -> str | None:
    numba_module()
    return _state["error"]


def _numba_version() -> str:
    """numba's installed version, read once per process (reading the package metadata costs 3 ms,
    paid by every preparation of a kept worker otherwise: backend.resolve asks is_warm)."""
    if "numba_version" not in _state:
        try:
            from importlib.metadata import version
            _state["numba_version"] = version("numba")
        except Exception:
            _state["numba_version"] = "unknown"
    return _state["numba_version"]


def jit_files() -> list:
    """Source files of the compiled twins."""
    return [os.path.join(TRACER_DIR, *name.split(".")) + ".py" for name in JIT_MODULES]


def stamp_path() -> str:
    """The file whose presence says the cache holds every twin compiled from today's sources."""
    key = [_numba_version(), sys.version, sys.platform]
    for path in jit_files():                   # numba's cache index: a source's path, size and time
        st = os.stat(path)
        key.append(f"{path}:{st.st_size}:{st.st_mtime_ns}")
    digest = hashlib.sha1("\n".join(key).encode()).hexdigest()[:16]
    return os.path.join(cache_dir(), f"warm-{digest}.stamp")


def is_warm() -> bool:
    return os.path.exists(stamp_path())


def load_modules(names) -> None:
    """Compile or load from the cache the kernels of the twin modules `names` (warm_up of each)."""
    for name in names:
        importlib.import_module(f"{TRACER_BASE}.{name}").warm_up()


# A cold compile on two cores: the modules from this one on are compiled by a second Python into the
# shared cache while this process compiles the ones before (about half the compile time each,
# numba's import and LLVM's start paid by both), then loaded from the cache here.
SECOND_HALF_FROM = "materials.principled_v1_jit"


def _compile_second_half():
    """A child Python compiling the second half of JIT_MODULES into the cache (None where this
    process is not a Python interpreter, or has one core)."""
    if "python" not in os.path.basename(sys.executable).lower() or (os.cpu_count() or 1) < 2:
        return None
    names = list(JIT_MODULES)
    half = names[names.index(SECOND_HALF_FROM):]
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir())
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(TRACER_DIR)] + [p for p in sys.path if p])
    code = f"import {TRACER_BASE}.core.backend as b\nb.load_modules({half!r})\n"
    try:
        return subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), set(half)
    except OSError:
        return None


def load_kernels(log=None, parallel: bool = False) -> float:
    """Compile or load from the cache every twin's kernels in this process, once (before the local
    pool forks, so its workers inherit them); returns the seconds it took.  parallel: a cold cache
    is compiled by this process and a second Python at once (`_compile_second_half`), whose half
    this process then loads from the cache (or compiles, if the child failed).  Raises ImportError
    when numba is missing."""
    if numba_module() is None:
        raise ImportError(f"numba cannot be imported ({numba_error()})")
    start = time.perf_counter()
    if not _state.get("loaded"):
        helper = _compile_second_half() if parallel and not is_warm() else None
        for i, name in enumerate(JIT_MODULES, 1):
            if helper is not None and name in helper[1]:
                helper[0].wait()               # its half is in the cache now (or compiled below)
                helper = None
            load_modules([name])
            if log:
                log(f"numba: kernels {i}/{len(JIT_MODULES)} ready ({name}, {time.perf_counter() - start:.1f} s)")
        _state["loaded"] = True
    return time.perf_counter() - start


def warm_up(log=print) -> float:
    """Compile (or load from the cache) every twin's kernels in this process and stamp the cache
    warm; returns the seconds it took (on two cores or more two Pythons compile: load_kernels'
    `parallel`).  Raises ImportError when numba is missing."""
    seconds = load_kernels(log, parallel=True)
    stamp = stamp_path()
    with open(stamp + ".tmp", "w") as fh:
        fh.write(f"{seconds:.3f}\n")
    os.replace(stamp + ".tmp", stamp)
    prune_old_caches()
    return seconds


def prune_old_caches(days: float = PRUNE_AFTER_DAYS) -> list:
    """Remove the caches of other twin sources (sibling `twins-*` folders: an older version of the
    add-on, a checkout since edited) whose warm stamps are all older than `days`; returns their
    paths.  Runs after a warm-up, the one moment a new folder fills."""
    import shutil
    here = cache_dir()
    root, cutoff, removed = cache_root(), time.time() - days * 86400.0, []
    for name in os.listdir(root):
        path = os.path.join(root, name)
        if not name.startswith(DIGEST_PREFIX) or path == here or not os.path.isdir(path):
            continue
        try:
            used = max([os.path.getmtime(path)] + [os.path.getmtime(os.path.join(path, f))
                                                   for f in os.listdir(path) if f.startswith("warm-")])
        except OSError:
            continue
        if used < cutoff:
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def _take_lock() -> bool:
    """One background warm-up per machine at a time (the workers of a render all ask)."""
    lock = stamp_path() + ".lock"
    try:
        if time.time() - os.path.getmtime(lock) > STALE_LOCK_SECONDS:
            os.remove(lock)
    except OSError:
        pass
    try:
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return True
    except OSError:
        return False


def start_warm_up(log=print):
    """Compile the twins in the background (once per process and per machine); returns the process
    or thread started, or None when one is already running.  This process keeps running NumPy."""
    with _lock:
        running = _state["warming"]
        if isinstance(running, subprocess.Popen) and running.poll() is not None:
            running = _state["warming"] = None          # it ended (and is reaped): the stamp says how
        if running is not None or not _take_lock():
            return None
        log("numba: compiling the kernels in the background (once per machine, 20-35 s); "
            "until then renders use NumPy")
        lock = stamp_path() + ".lock"
        if "python" in os.path.basename(sys.executable).lower():
            env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir())
            env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(TRACER_DIR)] + [p for p in sys.path if p])
            code = (f"import os, {TRACER_BASE}.core.backend as b\n"
                    f"try:\n    b.warm_up(log=lambda m: None)\nfinally:\n    os.path.exists({lock!r}) and os.remove({lock!r})\n")
            worker = subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        else:                                   # inside Blender without a worker Python: a thread
            def run():
                try:
                    warm_up(log=lambda m: None)
                finally:
                    if os.path.exists(lock):
                        os.remove(lock)
            worker = threading.Thread(target=run, name="numba-warm-up", daemon=True)
            worker.start()
        _state["warming"] = worker
        return worker


def resolve(setting: str, log=print, kernels=KERNELS) -> tuple:
    """(backend, reason) of a render for the setting "auto" | "numpy" | "numba"; kernels: the names
    (KERNELS) the render runs (none: numba is not even imported)."""
    if setting == NUMPY:
        return NUMPY, "backend numpy (as set)"
    if not set(kernels) & set(KERNELS):
        return NUMPY, "no kernel of this scene has a compiled twin"
    if numba_module() is None:
        why = f"numba is not available ({numba_error()})"
        if setting == NUMBA:
            log(f"warning: backend numba asked for, but {why}: the NumPy kernels run")
        return NUMPY, why
    if is_warm():
        seconds = load_kernels()
        return NUMBA, (f"numba, compiled kernels from the cache ({seconds:.2f} s)"
                       + (" (as set)" if setting == NUMBA else ""))
    if setting == NUMBA:
        log("numba: compiling the kernels (once per machine, 20-35 s)...")
        seconds = warm_up(log)
        return NUMBA, f"numba (as set; compiled in {seconds:.1f} s)"
    start_warm_up(log)
    return NUMPY, "numba's kernels are not compiled yet (compiling in the background): NumPy this time"


if __name__ == "__main__":                 # python -m engine.core.backend: compile now, in the foreground
    print(f"numba cache: {cache_dir()}")
    print(f"warmed up in {warm_up():.1f} s")
