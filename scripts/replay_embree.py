"""How far a render is from the limit of its Embree calls: every Embree batch of a render recorded
(the rays going in, through a wrapper of the accelerator) and the same rays replayed through
embreex alone, with the render's own time beside them; a per-stage time table; 1 -> 2 workers.

  python scripts/replay_embree.py [--scenes cornell many_lights caustic] [--resolution W H]
                                  [--samples S] [--depth D] [--repeats R] [--wavefronts N ...]
                                  [--baseline REPO] [--no-profile] [--no-workers]
  make bench-speed

Per scene (the built-in Cornell box, engine/scene/builtin.py, and sample_blends/NAME.blend for any
other name, exported once by bpy in a child process and cached as a scene file under
renders/bench-scenes/):

* ms/spp of the render on one worker (CPU seconds of this process over the units, traced here
  one after the other as engine/rendering/session.py describes; best of --repeats, after a
  warm-up) against ms/spp of the Embree-alone replay (CPU seconds of `EmbreeScene.run` on the
  recorded float32 rays, tfar and query kind, nothing else), and their ratio;
* `--wavefronts`: ms/spp for each wavefront size (engine/integrators/path_tracer.py
  WAVEFRONT_SIZE), the sizes alternated within each repeat;
* the per-stage table: cProfile of one render, cumulative seconds of the bounce's stages (rows
  nest: the direct light includes its shadow rays) and own seconds grouped by module (cProfile's
  per-call cost inflates the Python-heavy rows: compare rows, not with the render's time);
* 1 -> 2 workers through engine.api.render: wall seconds and CPU seconds (this process and its
  reaped children: the forked workers);
* `--baseline REPO` (e.g. a `git worktree add /tmp/base main`): the same one-worker render of
  each scene in child processes of this repository and of REPO, alternated, median of --repeats,
  and the ratio baseline / this (> 1: this is faster).  Before and after in one run.

Only ratios within one run mean anything: these VMs drift by +-20 % from run to run.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import sys
import time
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ("cornell", "many_lights", "caustic")


def _use_repo(repo: str) -> None:
    sys.path.insert(0, repo)


# -- scenes -------------------------------------------------------------------------------------
def export_blend(blend: str, out: str, width: int, height: int) -> None:
    """(child process) the .blend's scene through the add-on's exporter, saved as a scene file."""
    import bpy
    from mcrt_addon.bench_estimators import open_blend
    from mcrt_addon.export import export_scene
    from engine.scene.files import save_scene
    open_blend(blend, (width, height))
    save_scene(export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(width, height)).scene, out)


def scene_file(name: str, resolution) -> str | None:
    """The cached scene file of sample_blends/NAME.blend at `resolution` (None: the built-in Cornell box)."""
    if name == "cornell":
        return None
    blend = os.path.join(ROOT, "sample_blends", f"{name}.blend")
    if not os.path.exists(blend):
        raise SystemExit(f"no scene {name!r}: neither built in nor sample_blends/{name}.blend")
    out = os.path.join(ROOT, "renders", "bench-scenes", f"{name}-{resolution[0]}x{resolution[1]}.json")
    if not os.path.exists(out) or os.path.getmtime(out) < os.path.getmtime(blend):
        os.makedirs(os.path.dirname(out), exist_ok=True)
        subprocess.run([sys.executable, os.path.abspath(__file__), "--export", blend, out,
                        str(resolution[0]), str(resolution[1])], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return out


def load(path: str | None, resolution):
    from engine.scene.builtin import cornell_scene
    from engine.scene.files import load_scene
    scene = cornell_scene(tuple(resolution)) if path is None else load_scene(path)
    scene.resolution = tuple(resolution)
    return scene


def settings_for(args, threads=1):
    from engine.core.settings import RenderSettings
    return RenderSettings(samples=args.samples, max_depth=args.depth, threads=threads, seed=0)


# -- one worker, in this process --------------------------------------------------------------------
class RecordingAccelerator:
    """An accelerator that keeps a copy of every batch it is asked (what embreex is given) and
    answers through the accelerator it wraps."""

    def __init__(self, inner):
        self.inner, self.batches = inner, []
        self.ray_dtype, self.name = inner.ray_dtype, inner.name

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def _keep(self, query, origins, directions, tmax):
        import numpy as np
        if len(origins) and self.inner.count:
            self.batches.append((query, np.array(origins, np.float32), np.array(directions, np.float32),
                                 self.inner._tfar(tmax)))

    def intersect(self, origins, directions, tmax):
        self._keep("INTERSECT", origins, directions, tmax)
        return self.inner.intersect(origins, directions, tmax)

    def occluded(self, origins, directions, tmax):
        self._keep("OCCLUDED", origins, directions, tmax)
        return self.inner.occluded(origins, directions, tmax)

    def intersect_rows(self, o, d, tmax, compiled=None):        # the rays as (3, N) rows
        from engine.core.vec import aos
        self._keep("INTERSECT", aos(o), aos(d), tmax)
        return self.inner.intersect_rows(o, d, tmax, compiled)

    def nearest_rows(self, o, d, t, compiled=None):
        from engine.core.vec import aos
        self._keep("INTERSECT", aos(o), aos(d), t)
        return self.inner.nearest_rows(o, d, t, compiled)

    def occluded_rows(self, o, d, tmax, compiled=None):
        from engine.core.vec import aos
        self._keep("OCCLUDED", aos(o), aos(d), tmax)
        return self.inner.occluded_rows(o, d, tmax, compiled)


def trace_units(scene, settings, prepared=None, record=False):
    """(CPU seconds, wall seconds, prepared scene, recorder or None) of the frame's units traced here."""
    from engine.core.allocator import tune_malloc
    from engine.rendering.frame import Frame
    from engine.rendering.session import PreparedScene
    tune_malloc()
    prepared = prepared or PreparedScene(scene, settings, log=lambda *a: None)
    recorder = None
    if record:
        geometry = prepared.geometry
        if geometry.accelerator is None or geometry.accelerator.name != "embree":
            raise SystemExit("the replay needs Embree triangles (accelerator embree)")
        recorder = geometry.accelerator = RecordingAccelerator(geometry.accelerator)
    frame = Frame(scene, settings, prepared.facts())
    cpu, wall = time.process_time(), time.perf_counter()
    for unit in frame.units:
        frame.add(prepared.render_unit(unit))
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    if recorder is not None:
        prepared.geometry.accelerator = recorder.inner
    return cpu, wall, prepared, recorder


def replay(recorder, repeats: int) -> tuple[float, int]:
    """(best CPU seconds of the recorded batches through EmbreeScene.run alone, rays)."""
    scene, best = recorder.inner.scene, float("inf")
    rays = sum(len(b[1]) for b in recorder.batches)
    for _ in range(repeats):
        tfar = [b[3].copy() for b in recorder.batches]          # embreex writes into tfar
        start = time.process_time()
        for (query, o, d, _), dists in zip(recorder.batches, tfar):
            if query == "INTERSECT":
                scene.run(o, d, dists=dists, output=1)
            else:
                scene.run(o, d, dists=dists, query="OCCLUDED")
        best = min(best, time.process_time() - start)
    return best, rays


STAGES = (                       # (row, function name, file ending): cumulative seconds in the profile
    ("bounce (all)", "bounce", "path_tracer.py"),
    ("  intersect: nearest_hits", "nearest_hits", "scene_geometry.py"),
    ("  seen lamps", "lamps_seen", "path_tracer.py"),
    ("  surface data", "surface", "scene_geometry.py"),
    ("  emission", "emission", "path_tracer.py"),
    ("  direct light (with shadow rays)", "direct_light", "path_tracer.py"),
    ("    light sampling (pick + shape)", "sample", "light_set.py"),
    ("    shadow rays: occluded", "occluded", "scene_geometry.py"),
    ("  scatter (BSDF sampling)", "scatter", "path_tracer.py"),
    ("  Sobol' points (SobolSampler.pair, every caller)", "pair", "qmc.py"),
    ("  take / extend of the path state", "take", "path_tracer.py"),
    ("Embree calls (EmbreeAccelerator: EmbreeScene.run and its casts)", "intersect occluded", "accel/embree.py"),
)


def profile_table(scene, settings) -> list[tuple[str, float]]:
    """Rows of (label, seconds): the stages (cumulative) and the modules (own time), of one render."""
    profiler = cProfile.Profile()
    from engine.rendering.session import PreparedScene
    prepared = PreparedScene(scene, settings, log=lambda *a: None)
    profiler.enable()
    trace_units(scene, settings, prepared)
    profiler.disable()
    stats = pstats.Stats(profiler).stats
    total = sum(v[2] for v in stats.values())
    stages = defaultdict(float)
    modules = defaultdict(float)
    for (path, _, name), (_, _, own, cumulative, _) in stats.items():
        for label, functions, ending in STAGES:     # nested functions of one name: the outermost
            if name in functions.split() and path.endswith(ending):
                stages[label, name] = max(stages[label, name], cumulative)
        if path == "~":
            group = ("embreex (C)" if "embreex" in name else "numpy and builtins (C)")
        else:
            rel = os.path.relpath(path, ROOT) if path.startswith(ROOT) else path
            group = rel if rel.startswith(("engine", "scripts")) else (
                "numpy (Python)" if "numpy" in rel else "other Python")
        modules[group] += own
    rows = [("total (profiled)", total)] + [(label, sum(stages[label, f] for f in functions.split()))
                                             for label, functions, _ in STAGES]
    rows.append(("-- own time by module --", 0.0))
    rows += sorted(modules.items(), key=lambda kv: -kv[1])[:14]
    return rows


# -- workers and children -------------------------------------------------------------------------
def workers_row(scene, settings_of) -> dict:
    """Wall and CPU seconds (this process and its reaped children) of engine.api.render on 1 and 2 workers."""
    from engine.api import render
    out = {}
    for threads in (1, 2):
        before, wall = os.times(), time.perf_counter()
        render(scene, settings_of(threads), log=lambda *a: None)
        after, wall = os.times(), time.perf_counter() - wall
        cpu = sum(after[i] - before[i] for i in range(4))
        out[threads] = (wall, cpu)
    return out


def child_time(args) -> None:
    """(child process, --repo first on sys.path) best CPU seconds of a one-worker render: JSON on stdout."""
    scene = load(args.child_scene or None, args.resolution)
    settings = settings_for(args)
    trace_units(scene, settings)                        # warm-up
    best = min(trace_units(scene, settings)[0] for _ in range(max(1, args.child_repeats)))
    print(json.dumps({"cpu": best}))


def time_in(repo: str, path, args) -> float:
    cmd = [sys.executable, os.path.abspath(__file__), "--child", "--repo", repo, "--child-scene", path or "",
           "--resolution", *map(str, args.resolution), "--samples", str(args.samples), "--depth", str(args.depth),
           "--child-repeats", "1"]
    env = dict(os.environ, PYTHONPATH=repo)
    done = subprocess.run(cmd, check=True, cwd=repo, env=env, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])["cpu"]


def median(values):
    values = sorted(values)
    n = len(values)
    return values[n // 2] if n % 2 else 0.5 * (values[n // 2 - 1] + values[n // 2])


# -- the report ---------------------------------------------------------------------------------------
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--resolution", nargs=2, type=int, default=[128, 128])
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--depth", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--wavefronts", nargs="*", type=int, default=[])
    parser.add_argument("--baseline", help="another checkout to time against (before / after in one run)")
    parser.add_argument("--no-profile", action="store_true")
    parser.add_argument("--no-workers", action="store_true")
    parser.add_argument("--export", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--repo", default=ROOT, help=argparse.SUPPRESS)
    parser.add_argument("--child-scene", default="", help=argparse.SUPPRESS)
    parser.add_argument("--child-repeats", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    _use_repo(args.repo)
    if args.export:
        blend, out, w, h = args.export
        export_blend(blend, out, int(w), int(h))
        return 0
    if args.child:
        child_time(args)
        return 0

    import engine.integrators.path_tracer as path_tracer
    spp = args.samples
    print(f"# replay_embree: {args.resolution[0]}x{args.resolution[1]}, {spp} spp, depth {args.depth}, "
          f"default settings (mis, Sobol'), load {os.getloadavg()[0]:.1f}, {time.strftime('%Y-%m-%d %H:%M')}")
    for name in args.scenes:
        path = scene_file(name, args.resolution)
        scene = load(path, args.resolution)
        settings = settings_for(args)
        print(f"\n## {name}")
        trace_units(scene, settings)                                        # warm-up
        cpu = min(trace_units(scene, settings)[0] for _ in range(args.repeats))
        _, _, _, recorder = trace_units(scene, settings, record=True)
        embree, rays = replay(recorder, args.repeats)
        print(f"render, one worker: {1e3 * cpu / spp:.1f} ms/spp (CPU, best of {args.repeats}); Embree alone on "
              f"the same {rays / 1e6:.2f} M rays ({len(recorder.batches)} batches): {1e3 * embree / spp:.1f} ms/spp; "
              f"render / Embree alone = {cpu / embree:.2f}")
        del recorder
        if args.wavefronts:
            default, times = path_tracer.WAVEFRONT_SIZE, defaultdict(list)
            try:
                for _ in range(args.repeats):
                    for size in args.wavefronts:
                        path_tracer.WAVEFRONT_SIZE = size
                        times[size].append(trace_units(scene, settings)[0])
            finally:
                path_tracer.WAVEFRONT_SIZE = default
            print("| wavefront paths | ms/spp (CPU, median) | / the default's |\n|---:|---:|---:|")
            ref = median(times[default]) if default in times else median(times[args.wavefronts[0]])
            for size in args.wavefronts:
                print(f"| {size} | {1e3 * median(times[size]) / spp:.1f} | {median(times[size]) / ref:.3f} |")
        if not args.no_profile:
            rows = profile_table(scene, settings)
            total = rows[0][1]
            print("| stage or module (cProfile) | s | % |\n|---|---:|---:|")
            for label, seconds in rows:
                print(f"| {label} | {seconds:.2f} | {100 * seconds / total:.0f} |" if seconds else f"| {label} | | |")
        if not args.no_workers:
            w = workers_row(scene, lambda threads: settings_for(args, threads))
            (w1, c1), (w2, c2) = w[1], w[2]
            print(f"1 -> 2 workers (engine.api.render): wall {w1:.2f} -> {w2:.2f} s (speed-up {w1 / w2:.2f}x), "
                  f"CPU {c1:.2f} -> {c2:.2f} s ({c2 / c1:.2f}x the CPU seconds)")
        if args.baseline:
            base, this = [], []
            for _ in range(args.repeats):
                base.append(time_in(os.path.abspath(args.baseline), path, args))
                this.append(time_in(ROOT, path, args))
            b, t = median(base), median(this)
            print(f"before / after (one worker, CPU, median of {args.repeats} alternated): {args.baseline} "
                  f"{1e3 * b / spp:.1f} ms/spp, this {1e3 * t / spp:.1f} ms/spp: {b / t:.3f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
