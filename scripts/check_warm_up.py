"""Does backend.warm_up compile every kernel a render calls, for the types the render calls it with?

A compiled twin whose warm_up misses a type a render passes (a float32 array, a non-contiguous
view, a new keyword) is compiled by numba at the first call of that render, in every worker
process: seconds in the way of the first tile (docs/performance.md "Compiled kernels": at most 1 s
of compile or cache load after the first run).
This script loads the kernels as a worker does (engine/core/backend.py load_kernels), counts each
dispatcher's compiled signatures, renders the built-in scenes and every sample_blends/*.blend
(exported by bpy as F12 exports it, the file's own TNCG15 MC settings, backend numba, in this
process) and prints, per scene, each dispatcher that gained a signature.  Exit code 1 when any did.

  .venv/bin/python scripts/check_warm_up.py [--files cornell principled ...] [--no-builtins]
         [--builtins cornell ...] [--resolution 16] [--samples 2] [--each]

In one process a kernel compiled for one scene is no longer new for the next: --each renders every
scene in a process of its own (about 3 s each: bpy and the kernels loaded again), so that each
scene's report is what a worker's first render of it compiles.

--control first calls one kernel (wavefront_jit._take_1d) with float32 rows, a type no render
passes: its compilation must be reported (the check's own control).
"""
import argparse
import dataclasses
import glob
import importlib
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)


def dispatchers() -> dict:
    """{module.name: numba dispatcher} of every compiled twin module (backend.JIT_MODULES)."""
    from numba.core.registry import CPUDispatcher
    from engine.core import backend
    found = {}
    for name in backend.JIT_MODULES:
        module = importlib.import_module(f"{backend.TRACER_BASE}.{name}")
        for attr, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == module.__name__:
                found[f"{name}.{attr}"] = obj
    return found


def signatures(found: dict) -> dict:
    return {key: set(map(str, d.signatures)) for key, d in found.items()}


def render_here(scene, settings) -> None:
    """The frame's units traced in this process (no worker: a compilation would be hidden in it)."""
    from engine.rendering.frame import Frame
    from engine.rendering.session import PreparedScene
    prepared = PreparedScene(scene, settings, log=lambda *a: None)
    frame = Frame(scene, settings, prepared.facts())
    for unit in frame.units:
        frame.add(prepared.render_unit(unit))


def scenes(args):
    """(label, scene, settings) of the built-in scenes and the sample files asked for."""
    from engine.core.settings import RenderSettings
    size = (args.resolution, args.resolution)
    if not args.no_builtins:
        from engine.scene.builtin import BUILTIN_SCENES
        for name, make in sorted(BUILTIN_SCENES.items()):
            if args.builtins is not None and name not in args.builtins:
                continue
            yield f"builtin:{name}", make(size), RenderSettings(samples=args.samples, threads=1, backend="numba")
    paths = sorted(glob.glob(os.path.join(REPO, "sample_blends", "*.blend")))
    if args.files is not None:
        paths = [p for p in paths if os.path.basename(p)[:-6] in args.files]
    for path in paths:
        from mcrt_addon import bench_estimators as be, bridge
        blend = be.open_blend(path, size)
        settings = blend.tncg15.to_settings(bridge.settings_class())
        settings = dataclasses.replace(settings, samples=args.samples, min_samples=0, threads=1, backend="numba",
                                       time_limit=0.0, noise_target=0.0)
        yield os.path.basename(path)[:-6], be.export_tracer_scene(blend, size).scene, settings


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--files", nargs="*", default=None, help="sample file names (default: all)")
    parser.add_argument("--no-builtins", action="store_true")
    parser.add_argument("--builtins", nargs="*", default=None, help="built-in scene names (default: all)")
    parser.add_argument("--each", action="store_true", help="every scene in a process of its own")
    parser.add_argument("--resolution", type=int, default=16)
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--control", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.each and not args.control:
        return each_in_own_process(args)
    import numpy as np
    from engine.core import backend
    backend.load_kernels()
    found = dispatchers()
    seen = signatures(found)
    if args.control:                       # a type no render passes (float32 rows): must be reported
        from engine.integrators import wavefront_jit
        wavefront_jit._take_1d(np.zeros(1, np.float32), np.zeros(0, np.int64), np.zeros(0, np.float32))
    compiled = {}
    for label, scene, settings in ([("control", None, None)] if args.control else []) + list(scenes(args)):
        if scene is not None:
            render_here(scene, settings)
        now = signatures(found)
        new = {key: sorted(now[key] - seen[key]) for key in now if now[key] - seen[key]}
        seen = now
        if new:
            compiled[label] = new
        print(f"{label}: " + ("; ".join(f"{k} {v}" for k, v in new.items()) if new else "nothing compiled"),
              flush=True)
    print(f"{len(compiled)} scene(s) compiled kernels that warm_up did not")
    return 1 if compiled else 0


def each_in_own_process(args) -> int:
    """main() once per scene, each in a child process (the same options); 1 when any compiled."""
    import subprocess
    from engine.scene.builtin import BUILTIN_SCENES
    names = [] if args.no_builtins else [n for n in sorted(BUILTIN_SCENES)
                                         if args.builtins is None or n in args.builtins]
    files = [os.path.basename(p)[:-6] for p in sorted(glob.glob(os.path.join(REPO, "sample_blends", "*.blend")))]
    files = [f for f in files if args.files is None or f in args.files]
    common = ["--resolution", str(args.resolution), "--samples", str(args.samples)]
    runs = [["--no-builtins", "--files", f] for f in files] + [["--files", "--builtins", n] for n in names]
    failed = 0
    for extra in runs:
        r = subprocess.run([sys.executable, os.path.abspath(__file__), *extra, *common], capture_output=True,
                           text=True, cwd=REPO)
        lines = [line for line in r.stdout.splitlines() if ":" in line and not line.startswith(("Read ", "["))]
        print("\n".join(lines[-1:]) if r.returncode in (0, 1) else f"{extra}: failed ({r.returncode}) "
              + r.stderr[-500:], flush=True)
        failed += r.returncode != 0
    print(f"{failed} scene(s) compiled kernels that warm_up did not (or failed)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
