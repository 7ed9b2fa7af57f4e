"""Denoising with Intel Open Image Denoise (the `pyoidn` binding), guided by the albedo and normal
passes (engine/film/passes.py), as Cycles' OIDN denoiser: the "Denoise" option of both command lines
and the add-on.

`pyoidn` (PyPI, OIDN 2.5 with its CPU device bundled) is an optional dependency: without it,
`denoise()` raises DenoiserUnavailable with one line saying what to install.  In Blender the
denoiser runs in a separate process of the worker Python (`python -m engine.film.denoise IN OUT`), never
in Blender's own: in Debian's Blender 3.4 loading OIDN next to Blender's libraries aborts the
process (docs/cluster-and-viewport.md B6).

A pyoidn that aborts or crashes while loading must not take the caller with it: before this
process imports pyoidn, `probe()` imports it and denoises a tiny image in a process of its own
(`python -m engine.film.denoise --probe`), once per Python and path (cached); only then does
`denoise()` import it here.  The processes that exist to denoise (main(), the viewport's denoiser
process engine/pools/denoiser.py) call `trust_this_process()`: if pyoidn aborts there, only they end.
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np

from .passes import NOISY

NEEDS = ("albedo", "normal")      # the auxiliary passes the denoiser is given
# Where a user gets it: the add-on's button (mcrt_addon/denoiser_install.py), or pip for a Python of their own.
INSTALL_HINT = ("in Blender: Preferences > Add-ons > TNCG15 MC > Install Denoiser; for your own Python: "
                "python -m pip install pyoidn")
PROBE_SECONDS = 120.0             # import + a 4x4 denoise; OIDN's first device creation takes ~0.5 s
_PROBES: dict = {}                # (python, paths) -> None (works) | one line (why not)
_PROBING: dict = {}               # (python, paths) -> the thread probing it (probe_cached)
_LOCK = threading.Lock()
_TRUSTED = [False]                # this process is a denoiser's own: import pyoidn without a probe


class DenoiserUnavailable(RuntimeError):
    """pyoidn cannot be imported here."""


def missing_message(python: str, exc) -> str:
    return f"Denoise needs Intel Open Image Denoise (pyoidn) for {python}: {INSTALL_HINT} ({exc})"


def trust_this_process() -> None:
    """This process exists to denoise: denoise() imports pyoidn without probing first."""
    _TRUSTED[0] = True


def _pyoidn():
    if "pyoidn" not in sys.modules and not _TRUSTED[0]:
        problem = probe()
        if problem:
            raise DenoiserUnavailable(problem)
    try:
        import pyoidn
    except Exception as exc:                       # ImportError, or a broken native library
        raise DenoiserUnavailable(missing_message(sys.executable, f"{type(exc).__name__}: {exc}")) from None
    return pyoidn


def available() -> str | None:
    """None when the denoiser works here, else why not (one line); never aborts this process."""
    try:
        _pyoidn()
    except DenoiserUnavailable as exc:
        return str(exc)
    return None


def _own_paths() -> tuple:
    return tuple(p for p in sys.path if p and os.path.isdir(p))


def probe(python: str | None = None, extra_paths=(), refresh: bool = False) -> str | None:
    """None when `python` (default: this process's, with its sys.path) imports pyoidn and denoises a
    tiny image, else why not (one line); in a process of its own, so an abort there ends only that
    process.  Once per (python, paths); `refresh` asks again (after an install)."""
    key = (python or sys.executable, tuple(extra_paths) if python else _own_paths())
    with _LOCK:
        if key in _PROBES and not refresh:
            return _PROBES[key]
    result = _run_probe(*key, own=python is None)
    with _LOCK:
        _PROBES[key] = result
    return result


def probe_cached(python: str, extra_paths=()):
    """(done, problem) without waiting: the cached probe of `python`, else (False, None) and the probe
    starts on a thread (for a panel's draw, which must not block)."""
    key = (python, tuple(extra_paths))
    with _LOCK:
        if key in _PROBES:
            return True, _PROBES[key]
        if key not in _PROBING or not _PROBING[key].is_alive():
            _PROBING[key] = threading.Thread(target=probe, args=(python, extra_paths), daemon=True,
                                             name="denoiser probe")
            _PROBING[key].start()
    return False, None


def forget_probes() -> None:
    with _LOCK:
        _PROBES.clear()


def probe_import(python: str | None = None, timeout: float = PROBE_SECONDS) -> str | None:
    """Only the import of pyoidn, in a process of `python` (default: this one, with its sys.path):
    why it is unavailable when that process was killed by a signal or hung, else None (an
    ImportError is left to the import here, which names what to install).  probe() also
    denoises: OIDN can abort when it creates its device, after a clean import."""
    key = ("import", python or sys.executable, _own_paths())
    with _LOCK:
        if key in _PROBES:
            return _PROBES[key]
    result = _run_probe(python or sys.executable, _own_paths(), own=True, mode="--probe-import", timeout=timeout)
    with _LOCK:
        _PROBES[key] = result
    return result


def _run_probe(python: str, paths: tuple, own: bool, mode: str = "--probe",
               timeout: float = PROBE_SECONDS) -> str | None:
    from ..core.paths import TRACER_DIR, worker_environment
    env = worker_environment(() if own else paths)
    if own:                                          # this process's whole path, the tracer first
        env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys((os.path.dirname(TRACER_DIR),) + paths))
    module = os.path.basename(TRACER_DIR) + ".film.denoise"
    try:
        proc = subprocess.run([python, "-m", module, mode], env=env, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"denoiser unavailable: trying pyoidn with {python} did not finish within {timeout:g} s"
    except OSError as exc:
        return f"denoiser unavailable: cannot run {python} to try pyoidn: {exc.strerror or exc}"
    lines = [line for line in proc.stdout.splitlines() if line.strip()]
    if proc.returncode == 0 and lines and lines[-1] == "ok":
        return None
    if proc.returncode == 0 and lines:
        return None if mode == "--probe-import" else lines[-1]     # DenoiserUnavailable's one line
    tail = (proc.stderr.strip().splitlines() or [""])[-1][:200]
    if proc.returncode < 0:
        from signal import Signals
        try:
            how = Signals(-proc.returncode).name
        except ValueError:
            how = f"signal {-proc.returncode}"
        return (f"denoiser unavailable: importing pyoidn killed its process ({how}{': ' + tail if tail else ''}) "
                f"with {python}; {INSTALL_HINT}")
    return (f"denoiser unavailable: pyoidn does not work with {python} (exit code {proc.returncode}"
            f"{': ' + tail if tail else ''}); {INSTALL_HINT}")


def _probe_import_main() -> int:
    """--probe-import: import pyoidn; print "ok" (or the ImportError, exit 0: not a crash)."""
    try:
        import pyoidn  # noqa: F401
    except ImportError as exc:
        print(f"ImportError: {exc}")
        return 0
    print("ok")
    return 0


def _probe_main() -> int:
    """--probe: import pyoidn, denoise a 4x4 image; print "ok" or the one-line reason."""
    trust_this_process()
    try:
        denoise(np.full((4, 4, 3), 0.5, np.float32))
    except DenoiserUnavailable as exc:
        print(exc)
        return 0
    print("ok")
    return 0


def denoise(image, albedo=None, normal=None) -> np.ndarray:
    """OIDN's RT filter in HDR mode on a linear (H, W, 3) image; albedo in [0, 1], normals in
    [-1, 1] (either may be None).  Returns float32 (H, W, 3)."""
    pyoidn = _pyoidn()
    color = np.ascontiguousarray(np.nan_to_num(np.asarray(image, dtype=np.float32)[..., :3]))
    aux = {}
    if albedo is not None:
        aux["albedo"] = np.ascontiguousarray(np.clip(np.asarray(albedo, dtype=np.float32)[..., :3], 0.0, 1.0))
        if normal is not None:                       # OIDN takes a normal only together with an albedo
            aux["normal"] = np.ascontiguousarray(np.clip(np.asarray(normal, dtype=np.float32)[..., :3], -1.0, 1.0))
    out = pyoidn.denoise(color, hdr=True, **aux)
    return np.asarray(out, dtype=np.float32).reshape(color.shape)


def denoise_result(result) -> None:
    """Denoise a RenderResult in place: the image becomes the denoised one, the raw image is kept
    as the `noisy` pass, stats get `denoised` and `denoise_seconds`."""
    start = time.perf_counter()
    result.passes[NOISY] = np.asarray(result.image, dtype=np.float32)
    result.image = denoise(result.image, result.passes.get("albedo"), result.passes.get("normal"))
    result.stats["denoised"] = True
    result.stats["denoise_seconds"] = time.perf_counter() - start


def denoise_in_subprocess(python: str, image, albedo=None, normal=None, extra_paths=(), timeout: float = 300.0):
    """denoise() in a process of `python` (`python -m <tracer>.denoise`); raises
    DenoiserUnavailable with its one-line reason, or RuntimeError when the process fails."""
    import tempfile
    from ..core.paths import TRACER_DIR, worker_environment
    with tempfile.TemporaryDirectory(prefix="tncg15-denoise-") as tmp:
        src, dst = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        data = {"image": np.asarray(image, dtype=np.float32)}
        if albedo is not None:
            data["albedo"] = np.asarray(albedo, dtype=np.float32)
        if normal is not None:
            data["normal"] = np.asarray(normal, dtype=np.float32)
        np.savez(src, **data)
        proc = subprocess.run([python, "-m", os.path.basename(TRACER_DIR) + ".film.denoise", src, dst],
                              env=worker_environment(extra_paths), capture_output=True, text=True, timeout=timeout)
        if proc.returncode != 0 or not os.path.isfile(dst):
            tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"the denoiser process ({python}) failed: {tail}; {INSTALL_HINT}")
        with np.load(dst) as out:
            if "error" in out:
                raise DenoiserUnavailable(str(out["error"]))
            return np.array(out["image"])


def main(argv=None) -> int:
    """`python -m engine.film.denoise IN.npz OUT.npz`: IN has image (and albedo, normal); OUT gets image,
    or error (one line).  The add-on's route to OIDN in a process of its own."""
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--probe"]:
        return _probe_main()
    if argv == ["--probe-import"]:
        return _probe_import_main()
    if len(argv) != 2:
        sys.stderr.write("usage: python -m engine.film.denoise IN.npz OUT.npz | --probe\n")
        return 2
    trust_this_process()
    data = np.load(argv[0])
    try:
        out = {"image": denoise(data["image"], data["albedo"] if "albedo" in data else None,
                                data["normal"] if "normal" in data else None)}
    except DenoiserUnavailable as exc:
        out = {"error": np.array(str(exc))}
    np.savez(argv[1], **out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
