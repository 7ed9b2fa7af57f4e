"""Agreement with Cycles 3.4: Debian's Blender 3.4 (`/usr/bin/blender`, whose Python has no numpy)
builds a scene, exports it with the add-on to a scene file and renders Cycles 3.4 references
(tests/addon/blender34_reference.py); the tracer then renders the scene file in this process and
tests/addon/imagecompare.py compares the two.  The method's settings are the agreement tests'
(tests/addon/rendering.py: 64 x 64, 32 spp, depth 8, K seeds), without importing bpy here.

    run = blender34_run("startup_cube", tmp_dir)       # once per scene and session (cached)
    run.scene, run.warnings, run.cycles                 # the exported Scene, its warnings, (K, H, W, 3)
    compare_runs(tracer_runs(run.scene), run.cycles)
"""
import json
import os
import shutil
import subprocess
import sysconfig
from dataclasses import dataclass

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
BLENDER34 = os.environ.get("BLENDER_BIN") or shutil.which("blender")
RES, SPP, DEPTH, K = (64, 64), 32, 8, 4          # tests/addon/rendering.py's method
SEEDS = tuple(range(1, K + 1))
_runs = {}


@dataclass
class Blender34Run:
    scene: object            # engine.scene.model.Scene read back from the scene file
    warnings: list           # the exporter's warnings
    cycles: np.ndarray       # (K, H, W, 3) Cycles 3.4 renders, one per seed
    blender: tuple           # the version of the Blender that ran (3, 4, 1)
    seconds: float           # the Blender run's wall time


def blender_environment() -> dict:
    """PYTHONPATH = the repository and this venv's site-packages (numpy, embreex for Blender's Python)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([REPO, sysconfig.get_paths()["purelib"]])
    return env


def blender34_run(name, outdir, distribution=None, timeout=900, no_light_sampling=(), edit=None,
                  light_paths=None) -> Blender34Run:
    """Scene `name` ("startup_cube" or a make_samples.py scene) built, exported and rendered by Cycles
    in Blender 3.4, once per session for each (name, distribution, no_light_sampling: materials whose
    emission Cycles does not light-sample, edit: an edit of the scene before the export, light_paths:
    the references' Light Paths options as {name: value}; tests/addon/blender34_reference.py)."""
    import time

    from engine.scene.files import load_scene
    options = sorted((light_paths or {}).items())
    key = (name, distribution, tuple(no_light_sampling), edit, tuple(options))
    if key in _runs:
        return _runs[key]
    tag = name + (f"-{distribution.lower()}" if distribution else "") + (f"-{edit}" if edit else "") + \
        "".join(f"-{k}{v:g}" for k, v in options)
    out = os.path.join(str(outdir), tag)
    args = [BLENDER34, "-b", "--factory-startup", "--python-use-system-env",
            "--python", os.path.join(HERE, "blender34_reference.py"), "--",
            "--scene", name, "--outdir", out, "--resolution", *map(str, RES), "--samples", str(SPP),
            "--depth", str(DEPTH), "--seeds", *map(str, SEEDS)]
    if distribution:
        args += ["--distribution", distribution]
    if no_light_sampling:
        args += ["--no-light-sampling", *no_light_sampling]
    if edit:
        args += ["--edit", edit]
    if options:
        args += ["--light-paths", *(f"{k}={v!r}" for k, v in options)]
    t0 = time.perf_counter()
    r = subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=blender_environment())
    seconds = time.perf_counter() - t0
    stem = os.path.join(out, name)
    if r.returncode != 0 or not os.path.exists(stem + ".json"):
        raise RuntimeError(f"Blender 3.4 run of {tag} failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    info = json.load(open(stem + ".warnings.json"))
    cycles = np.stack([read_exr(f"{stem}.cycles.{seed}.exr") for seed in SEEDS])
    _runs[key] = Blender34Run(load_scene(stem + ".json"), info["warnings"], cycles, tuple(info["blender"]), seconds)
    return _runs[key]


def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise IOError(buf.geterror())
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)[..., :3]


def tracer_runs(scene, first_seed=1000, threads=0, **options):
    """The tracer's K runs of `scene` with the method's settings (exact Fresnel, as Cycles) and
    `options` (RenderSettings fields, e.g. Light Paths options)."""
    from engine import RenderSettings, render
    from imagecompare import independent_seed
    out = []
    for seed in range(first_seed, first_seed + K):
        settings = RenderSettings(samples=SPP, max_depth=DEPTH, seed=independent_seed(seed), fresnel="exact",
                                  threads=threads, **options)
        out.append(np.asarray(render(scene, settings, log=lambda *a: None).image, dtype=np.float64))
    return np.stack(out)
