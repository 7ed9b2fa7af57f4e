"""Where the tracer package lives, and the environment a Python needs to import it: for worker
processes (engine/pools/) and the denoiser's process (engine/film/denoise.py)."""
from __future__ import annotations

import os
import sys

TRACER_BASE = __package__.rpartition(".")[0]     # "engine", "tracer" or "<add-on package>.tracer"
TRACER_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def worker_environment(extra_paths=()) -> dict:
    """PYTHONPATH for a worker: the tracer's parent directory, bundled wheels, then the site
    directories of this process (Blender's extension wheels, a venv) so the worker finds what we do."""
    paths = [os.path.dirname(TRACER_DIR), *extra_paths]
    paths += [p for p in sys.path if p and ("site-packages" in p or "dist-packages" in p) and os.path.isdir(p)]
    env = dict(os.environ)
    env.pop("PYTHONHOME", None)
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
    env["PYTHONNOUSERSITE"] = "1"
    env.setdefault("OMP_NUM_THREADS", "1")
    return env
