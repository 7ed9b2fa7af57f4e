"""Denoising with Intel Open Image Denoise (the `pyoidn` binding), guided by the albedo and normal
passes (engine/film/passes.py), as Cycles' OIDN denoiser: the "Denoise" option of both command lines
and the add-on.

`pyoidn` (PyPI, OIDN 2.5 with its CPU device bundled) is an optional dependency: without it,
`denoise()` raises DenoiserUnavailable with one line saying what to install.  In Blender the
denoiser runs in a separate process of the worker Python (`python -m engine.film.denoise IN OUT`), never
in Blender's own: in Debian's Blender 3.4 loading OIDN next to Blender's libraries aborts the
process (docs/cluster-and-viewport.md B6).
"""
from __future__ import annotations

import sys
import time

import numpy as np

from .passes import NOISY

NEEDS = ("albedo", "normal")      # the auxiliary passes the denoiser is given


class DenoiserUnavailable(RuntimeError):
    """pyoidn cannot be imported here."""


def _pyoidn():
    try:
        import pyoidn
    except Exception as exc:                       # ImportError, or a broken native library
        raise DenoiserUnavailable(f"Denoise needs Intel Open Image Denoise: 'pip install pyoidn' for "
                                  f"{sys.executable} ({type(exc).__name__}: {exc})") from None
    return pyoidn


def available() -> str | None:
    """None when the denoiser works here, else why not (one line).  pyoidn is first imported in a
    process of its own (probe_import): a broken native library can abort the importing process
    (SIGABRT) instead of raising, and must not take the command line with it."""
    problem = probe_import()
    if problem:
        return problem
    try:
        _pyoidn()
    except DenoiserUnavailable as exc:
        return str(exc)
    return None


def probe_import(python: str | None = None, timeout: float = 120.0) -> str | None:
    """Import pyoidn in a child process of `python` (default: this one) with this process's
    sys.path; why it is unavailable when the child was killed by a signal or hung, else None (an
    ImportError is left to the import here, which names what to install)."""
    import os
    import signal
    import subprocess
    python = python or sys.executable
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    try:
        proc = subprocess.run([python, "-c", "import pyoidn"], env=env, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"denoiser unavailable: importing pyoidn did not finish within {timeout:g} s"
    except OSError as exc:
        return f"denoiser unavailable: cannot run {python} to check pyoidn: {exc.strerror or exc}"
    if proc.returncode >= 0:
        return None
    try:
        how = signal.Signals(-proc.returncode).name
    except ValueError:
        how = f"signal {-proc.returncode}"
    tail = (proc.stderr.strip().splitlines() or [""])[-1][:200]
    return (f"denoiser unavailable: importing pyoidn killed its process ({how}{': ' + tail if tail else ''}); "
            f"reinstall it ('pip install --force-reinstall pyoidn' for {python}) or render without --denoise")


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
    import os
    import subprocess
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
            raise RuntimeError(f"the denoiser process ({python}) failed: {tail}")
        with np.load(dst) as out:
            if "error" in out:
                raise DenoiserUnavailable(str(out["error"]))
            return np.array(out["image"])


def main(argv=None) -> int:
    """`python -m engine.film.denoise IN.npz OUT.npz`: IN has image (and albedo, normal); OUT gets image,
    or error (one line).  The add-on's route to OIDN in a process of its own."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        sys.stderr.write("usage: python -m engine.film.denoise IN.npz OUT.npz\n")
        return 2
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
