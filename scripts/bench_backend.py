"""NumPy against numba's compiled twins (engine/core/backend.py), measured in one run, printed as ratios.

    python scripts/bench_backend.py [--resolution 96] [--samples 16] [--repeats 3] [--no-blend]

1. Per kernel, on inputs recorded from real renders (tests/backend_capture.py: the light tree's
   picks and walks in the built-in many-lights room, the parallelogram samples, shadow rays, sphere
   and quad tests and the Sobol' points of the built-in Cornell box): CPU time
   of every recorded call through the NumPy kernel and through its twin, best of --repeats, and
   the speed-up NumPy / numba.  The twin run alone on two threads with `prange` as well (an upper
   bound of what `parallel=True` could give; a render already keeps both cores busy with two
   worker processes).
2. Per render: CPU ms per sample pass (one worker, engine.api.render, after a warm-up render in
   the same process) on the built-in Cornell box, the built-in many-lights room and, with bpy,
   sample_blends/many_lights.blend exported; the backends alternate, median of --repeats.
3. Compile time: `python -m engine.core.backend` in a fresh Python with an empty cache (cold),
   then again with that cache (the load), wall seconds, numba's import included.
docs/performance.md ("Compiled kernels") keeps the figures.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from engine import api  # noqa: E402
from engine.core import backend  # noqa: E402
from engine.core.settings import RenderSettings  # noqa: E402
from engine.scene.builtin import BUILTIN_SCENES  # noqa: E402
from tests.backend_capture import capture  # noqa: E402


def best_cpu(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def best_wall(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def parallel_tree_sample():
    """selection_jit.tree_sample with prange over the rays (compiled here, not cached)."""
    from engine.lights import selection_jit as sj
    nb = backend.numba_module()

    @nb.njit(parallel=True, error_model="numpy", nogil=True)
    def tree_sample(x, n, u, nodes, power, empty, oriented, base, depth, count, light_at):
        m = u.shape[0]
        light, node, pmf = np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m, np.float64)
        for c in nb.prange((m + 4095) // 4096):          # chunks of blocks (sj._walks) on the threads
            a, b = c * 4096, min(m, (c + 1) * 4096)
            sj._walks(x[:, a:b], n[:, a:b], u[a:b].copy(), np.full(b - a, -1, np.int64), nodes, power, empty,
                      oriented, base, depth, count, node[a:b], pmf[a:b])
        for i in range(m):
            light[i] = light_at[(count * node[i]) >> depth]
        return light, pmf
    return tree_sample


def kernels(args):
    from engine.geometry.shapes.spheres import intersect_sphere
    from engine.geometry.shapes.spheres_jit import intersect_sphere as sphere_jit
    from engine.geometry.shapes.quads import QuadSet
    from engine.lights.selection_jit import TreeTables
    many = capture("many_lights", resolution=args.kernel_resolution, samples=args.kernel_samples, limit=10**6)
    cornell = capture("cornell", resolution=args.kernel_resolution, samples=args.kernel_samples, limit=10**6)
    tables = {id(t): TreeTables(t) for t, *_ in many["sample"] + many["pmf"]}
    rows = []
    samples = [(t, x, n, u) for t, x, n, u in many["sample"]]
    pmfs = [(t, x, n, light) for t, x, n, light in many["pmf"]]
    spheres = cornell["sphere"]
    quads = cornell["quad"]
    sobol = cornell["sobol"]
    from engine.sampling.qmc import sample_2d
    from engine.sampling.sobol_jit import sample_2d as sample_2d_jit

    def run_numpy_sobol():
        for index, seeds, dim, count in sobol:
            sample_2d(index, seeds, dim, count)

    def run_jit_sobol():
        for index, seeds, dim, count in sobol:
            sample_2d_jit(index, seeds, dim, count)
    from engine.sampling.sobol_jit import sample_2d_seeded
    seeded = [(index, np.arange(len(seeds)), np.ascontiguousarray(seeds, np.uint32), dim, count)
              for index, seeds, dim, count in sobol]

    def run_seeded_sobol():                 # the render's kernel (its seeds read through the pixel numbers)
        for index, pixel, table, dim, count in seeded:
            sample_2d_seeded(index, pixel, table, dim, count)
    rays = lambda calls, i: sum(len(c[i]) if np.ndim(c[i]) == 1 else c[i].shape[1] for c in calls)  # noqa: E731

    def run_numpy_sample():
        for t, x, n, u in samples:
            t._tree_sample(x, n, u)          # the captured trees walk in NumPy

    def run_jit_sample():
        for t, x, n, u in samples:
            tables[id(t)].sample(x, n, u)

    def run_numpy_pmf():
        for t, x, n, light in pmfs:
            t._tree_pmf(x, n, light)

    def run_jit_pmf():
        for t, x, n, light in pmfs:
            tables[id(t)].pmf(x, n, light)

    def run_numpy_sphere():
        for o, d, c, r, b in spheres:
            intersect_sphere(o, d, c, r, b)

    def run_jit_sphere():
        for o, d, c, r, b in spheres:
            sphere_jit(o, d, c, r, b)
    def run_numpy_quad():
        for q, k, prim, o, d, b in quads:
            q.intersect_one(k, o, d, b) if prim is None else q.intersect_pairs(prim, o, d, b)
    compiled_quads = {id(q): QuadSet(np.stack([q.v00, q.v10, q.v11, q.v01], axis=1), backend="numba")
                      for q, *_ in quads}

    def run_jit_quad():
        for q, k, prim, o, d, b in quads:
            c = compiled_quads[id(q)]
            c.intersect_one(k, o, d, b) if prim is None else c.intersect_pairs(prim, o, d, b)
    from engine.lights import light_set_jit
    from engine.lights.selection import DEFENSIVE
    picks, rectangles, shadows = many["pick"], cornell["rectangle"], cornell["shadow"]

    def run_numpy_pick():
        for t, x, n, u in picks:
            t.sample(x, n, u)

    def run_jit_pick():
        for t, x, n, u in picks:
            tables[id(t)].select(x, n, u, DEFENSIVE)
    for t, *_ in picks:
        tables.setdefault(id(t), TreeTables(t))

    def run_rectangles(backend):
        for lights, x, idx, u1, u2 in rectangles:
            lights.use_backend(backend)
            lights.sample_li(x, idx, u1, u2)
            lights.use_backend("numpy")

    def run_numpy_shadows():
        for light_set, call in shadows:
            saved, light_set.compiled_shadows = light_set.compiled_shadows, None
            light_set.shadow_rays(*call)
            light_set.compiled_shadows = saved

    def run_jit_shadows():
        for _, call in shadows:
            light_set_jit.shadow_rays(*call)
    from engine.materials import textures_jit
    from engine.materials.textures import lookup as numpy_lookup
    rng = np.random.default_rng(0)                 # image lookups: no built-in scene has textures
    texels = rng.random((512, 512, 4)).astype(np.float32)
    lookups = [(texels, rng.uniform(-1.0, 2.0, 20000), rng.uniform(-1.0, 2.0, 20000), interpolation)
               for interpolation in ("Linear", "Closest")]

    def run_numpy_lookup():
        for pixels, u, v, interpolation in lookups:
            numpy_lookup(pixels, u, v, interpolation, "REPEAT")

    def run_jit_lookup():
        for pixels, u, v, interpolation in lookups:
            textures_jit.lookup(pixels, u, v, interpolation, "REPEAT")
    for name, calls, a, b, count in (("image lookup (512^2 RGBA float32, Linear and Closest)", lookups,
                                      run_numpy_lookup, run_jit_lookup, sum(len(c[1]) for c in lookups)),
                                     ("light pick (tree walk and defensive mixing)", picks, run_numpy_pick,
                                      run_jit_pick, rays(picks, 3)),
                                     ("parallelogram sample_li", rectangles, lambda: run_rectangles("numpy"),
                                      lambda: run_rectangles("numba"), rays(rectangles, 3)),
                                     ("shadow rays (LightSet.shadow_rays)", shadows, run_numpy_shadows, run_jit_shadows,
                                      sum(c[1][2].shape[1] for c in shadows)),
                                     ("light tree sample", samples, run_numpy_sample, run_jit_sample, rays(samples, 3)),
                                     ("light tree pmf", pmfs, run_numpy_pmf, run_jit_pmf, rays(pmfs, 3)),
                                     ("sphere test", spheres, run_numpy_sphere, run_jit_sphere, rays(spheres, 0)),
                                     ("quad test", quads, run_numpy_quad, run_jit_quad, rays(quads, 3)),
                                     ("Sobol' sample_2d", sobol, run_numpy_sobol, run_jit_sobol, rays(sobol, 0)),
                                     ("Sobol' sample_2d_seeded (uint32)", sobol, run_numpy_sobol, run_seeded_sobol,
                                      rays(sobol, 0))):
        b()                                               # loaded from the cache before timing
        t_np, t_nb = best_cpu(a, args.repeats), best_cpu(b, args.repeats)
        rows.append((name, len(calls), count, t_np, t_nb))
    print(f"\n## Kernels on captured inputs ({args.kernel_resolution}^2 x {args.kernel_samples} spp renders), "
          f"CPU s, best of {args.repeats}")
    print("| kernel | calls | rays | NumPy [ms] | numba [ms] | speed-up |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, calls, count, t_np, t_nb in rows:
        print(f"| {name} | {calls} | {count} | {1e3 * t_np:.1f} | {1e3 * t_nb:.1f} | {t_np / t_nb:.2f} |")
    try:
        par = parallel_tree_sample()
        args_of = [(tables[id(t)], x, n, u) for t, x, n, u in samples]

        def run(fn):
            for tb, x, n, u in args_of:
                fn(np.ascontiguousarray(x, np.float32), np.ascontiguousarray(n, np.float32), u, tb.nodes, tb.power,
                   tb.empty, tb.oriented, tb.base, tb.depth, tb.count, tb.light_at)
        from engine.lights.selection_jit import tree_sample
        run(par)
        serial, parallel = best_wall(lambda: run(tree_sample), args.repeats), best_wall(lambda: run(par), args.repeats)
        print(f"\nprange (light tree sample alone, wall, {os.cpu_count()} cores): serial {1e3 * serial:.1f} ms, "
              f"parallel {1e3 * parallel:.1f} ms ({serial / parallel:.2f}x)")
    except Exception as exc:                             # a numba without a threading layer
        print(f"\nprange: not measured ({exc})")


def blend_scene(path, resolution):
    """sample_blends/many_lights.blend exported by bpy (None without bpy)."""
    try:
        from tests.addon.rendering import export_blend
    except Exception as exc:
        print(f"(no {os.path.basename(path)}: {exc})")
        return None
    return export_blend(path, (resolution, resolution)).scene


def renders(args):
    scenes = [(name, BUILTIN_SCENES[name]((args.resolution, args.resolution))) for name in ("cornell", "many_lights")]
    blend = os.path.join(ROOT, "sample_blends", "many_lights.blend")
    if args.blend and os.path.exists(blend):
        scene = blend_scene(blend, args.resolution)
        if scene is not None:
            scenes.append(("many_lights.blend", scene))
    print(f"\n## Renders: {args.resolution}^2, {args.samples} spp, 1 worker, CPU ms per sample pass, "
          f"median of {args.repeats} (alternating)")
    print("| scene | NumPy [ms/spp] | numba [ms/spp] | NumPy / numba | same image |")
    print("|---|---:|---:|---:|---|")
    for name, scene in scenes:
        times = {"numpy": [], "numba": []}
        images = {}
        for b in ("numpy", "numba"):                      # warm-up
            api.render(scene, RenderSettings(samples=1, threads=1, backend=b), log=lambda m: None)
        for _ in range(args.repeats):
            for b in ("numpy", "numba"):
                settings = RenderSettings(samples=args.samples, threads=1, backend=b)
                t0 = time.process_time()
                result = api.render(scene, settings, log=lambda m: None)
                times[b].append((time.process_time() - t0) / args.samples)
                images[b] = result.image
                assert result.stats["backend"] == b, result.stats["backend_reason"]
        a, c = statistics.median(times["numpy"]), statistics.median(times["numba"])
        print(f"| {name} | {1e3 * a:.1f} | {1e3 * c:.1f} | {a / c:.3f} | "
              f"{'bit for bit' if np.array_equal(images['numpy'], images['numba']) else 'NO'} |")


def compile_times():
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=cache)
        seconds = []
        for _ in range(2):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "engine.core.backend"], cwd=ROOT, env=env, check=True,
                           stdout=subprocess.DEVNULL)
            seconds.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import numpy"], env=env, check=True)
        python = time.perf_counter() - t0
    print(f"\n## Compile: cold {seconds[0]:.2f} s, from the cache {seconds[1]:.2f} s "
          f"(wall, a fresh Python each; Python + numpy alone {python:.2f} s)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--kernel-resolution", type=int, default=128)
    ap.add_argument("--kernel-samples", type=int, default=4)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-blend", dest="blend", action="store_false")
    args = ap.parse_args()
    if not backend.numba_available():
        raise SystemExit(f"numba is not available: {backend.numba_error()}")
    if not backend.is_warm():
        backend.warm_up()
    print(f"numba {backend._numba_version()}, numpy {np.__version__}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}, {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC")
    kernels(args)
    renders(args)
    compile_times()
    print(f"\nload at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
