"""The material sample scenes against Cycles: time, error and efficiency per scene (docs/materials.md,
"Efficiency against Cycles"), with the machinery of mcrt_addon/bench_estimators.py.

  python -m mcrt_addon bench-materials [--scenes glossy_plates rough_diffuse ...] [--resolution 96 96]
         [--samples 256] [--reference-samples 8192] [--max-depth 12] [--threads N]
         [--out docs/materials-efficiency.json] [--cache-dir renders/reference] [--images DIR]
         [--tncg15-pool workers|threads]

For every scene (a name of sample_blends/make_samples.py, generated afresh into the cache
directory, or a .blend path):

1. the Cycles reference of bench_estimators.reference_image (fair settings, all cores, cached as
   ``<cache-dir>/NAME_WxH_SPP_DEPTH.exr`` with its sidecar);
2. Cycles (same fair settings) at --samples with --threads threads, one run after a 1-spp warm-up;
3. TNCG15 MC at --samples with the default estimator (mis) and sampler, exact Fresnel, the same
   max depth and threads, one run after a warm-up at the full sample count;
4. the same exported tracer scene with every material replaced by a Lambertian of its base
   colour (`as_lambert`: emission and textures kept, mixes by their leaves' constant weights),
   timed the same way: what the materials cost against plain diffuse ("t rough / t diffuse").

How TNCG15 MC is timed (--tncg15-pool):

* ``workers`` (the default): as F12 renders in Blender with Start Workers Ahead (the add-on's
  default preference): on the add-on's worker processes (mcrt_addon/warm.py: viewport workers of
  the worker Python, one per thread, started and given numba's kernels before the clock starts,
  as the add-on does while the user looks at the scene), taken by ``warm.render_pool`` as
  mcrt_addon/render_engine.py takes them.  The clock covers what F12 waits for: the export of
  the render depsgraph (mcrt_addon/headless.py export_as_rendered, as bench_estimators'
  Cycles time covers Cycles' scene sync), the scene's checks, the scene sent to the workers and
  their BVH build, the render, and the pool's close.  CPU seconds: Blender's process
  (time.process_time) plus the workers' own user + system seconds over the same span (Linux
  /proc/PID/stat, read before the render and in the pool's close, before the workers exit).
* ``threads``: the tracer on --threads threads inside Blender's process (engine.api.render, its
  ThreadPool), the export excluded; the GIL lets two threads reach about 1.55 cores there (the
  mode of this benchmark before 2026-12-05, docs/materials.md).

The image does not depend on the pool (engine/pools/protocol.py): both modes give the same MSE.
Times, MSE and efficiency 1/(MSE t) are bench_estimators' (`error_metrics`, `derived`); MSE over
pixels and channels against the reference, which includes the reference's own noise (about
MSE_cycles x samples / reference-samples: ``ref_noise_mse`` in the JSON) and any model difference
(bias), neither falling with t.  One run per renderer: on a shared machine the times move with the
other load (the JSON keeps the CPU seconds too).
"""
import dataclasses
import os
import platform
import sys
import time

import numpy as np

from . import bench_estimators as be

MATERIAL_SCENES = ("glossy_plates", "rough_diffuse", "principled_default", "principled_grid",
                   "principled_balls", "mix_shader")
OPTIONAL_SCENES = ("rough_glass",)          # benchmarked when sample_blends/make_samples.py has it
ESTIMATOR = "mis"                            # the default of the settings table (engine/core/settings.py)
POOLS = ("workers", "threads")               # --tncg15-pool: how TNCG15 MC is timed (module docstring)
WARM_SECONDS = 300.0                         # at most this long for the workers to start and load numba


def default_scenes(make_samples):
    return [*MATERIAL_SCENES, *(name for name in OPTIONAL_SCENES if name in make_samples.SCENES)]


# ------------------------------------------------------------------------------- diffuse stand-in
def base_colour(material):
    """The colour a Lambertian stand-in of `material` gets: its own colour; for a mix, its leaves'
    colours weighted by their constant weights (a leaf with a varying factor counts 1/2)."""
    if material.kind != "mix" or material.mix is None:
        return tuple(material.color)
    total, weight_sum = np.zeros(3), 0.0
    for leaf in material.mix.leaves:
        w = leaf.constant_weight()
        w = 0.5 if w is None else w
        total += w * np.asarray(leaf.material.color, dtype=np.float64)
        weight_sum += w
    return tuple(float(c) for c in (total / weight_sum if weight_sum > 0 else total))


def as_lambert(scene):
    """A copy of the tracer scene with every material a Lambertian of its base colour (emission,
    colour and emission textures kept; roughness, Principled and mix fields dropped)."""
    materials = [dataclasses.replace(m, kind="diffuse", color=base_colour(m), diffuse_roughness=0.0,
                                     principled=None, mix=None)
                 for m in scene.materials]
    return dataclasses.replace(scene, materials=materials)


# ------------------------------------------------------------------------------- F12's worker pool
def process_cpu_seconds(pids):
    """User + system CPU seconds of the live processes `pids` so far (Linux /proc/PID/stat fields 14
    and 15, in clock ticks); None where /proc cannot be read."""
    ticks = os.sysconf("SC_CLK_TCK")
    total = 0.0
    try:
        for pid in pids:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rpartition(")")[2].split()      # after "(comm)": field 3 on
            total += (int(fields[11]) + int(fields[12])) / ticks
    except (OSError, IndexError, ValueError):
        return None
    return total


def warm_worker_pool(threads):
    """The pool F12 renders on when the add-on started its workers ahead (mcrt_addon/warm.py): the
    warm pool of the worker Python with one worker per thread, started and its kernels loaded,
    then taken by warm.render_pool as mcrt_addon/render_engine.py takes it (a pool for one render).
    Returns (pool, seconds the start took)."""
    from mcrt_addon import warm, worker_python
    python, why = worker_python.worker_python(worker_python.preferred_python())
    if python is None:
        raise RuntimeError(f"no worker Python for --tncg15-pool workers: {why}")
    extra = worker_python.extra_paths()
    t0 = time.perf_counter()
    warm.update(warm.pool_key(python, threads, extra), True, load_kernels=True)
    deadline = t0 + WARM_SECONDS
    while warm.pool() is None or not warm.pool().warmed():
        if time.perf_counter() > deadline:
            raise RuntimeError(f"the add-on's workers did not start within {WARM_SECONDS:.0f} s")
        time.sleep(0.02)
    pool = warm.render_pool(python, threads, extra, log=lambda *a, **k: None)
    if pool is None:
        raise RuntimeError("the add-on's warm workers could not be taken")
    return pool, time.perf_counter() - t0


def measured_warm_pool(threads):
    """warm_worker_pool's (pool, start seconds) and a dict whose "before" and "after" are its workers'
    CPU seconds now and when the pool closes (read from /proc before close() ends them; None where
    /proc cannot be read)."""
    pool, start_seconds = warm_worker_pool(threads)
    pids = [w.pid for w in pool.inner.workers]
    workers_cpu = {"before": process_cpu_seconds(pids), "after": None}
    close = pool.close

    def close_measured():
        workers_cpu["after"] = process_cpu_seconds(pids)
        close()
    pool.close = close_measured
    return pool, start_seconds, workers_cpu


def render_on_workers(blender_scene, resolution, *, diffuse, samples, max_depth, seed, threads, estimator,
                      extra=None):
    """One TNCG15 MC render timed as F12 (--tncg15-pool workers, module docstring): (image, wall
    seconds, CPU seconds of Blender's process and the workers, stats).  extra: more RenderSettings
    fields (scripts/bench_caustics.py: the caustics method and the photon map's)."""
    from mcrt_addon import bridge
    pool, start_seconds, workers_cpu = measured_warm_pool(threads)
    name, _, sampler = estimator.partition("/")
    settings = be.tracer_settings(samples=samples, max_depth=max_depth, seed=seed, threads=threads,
                                  fresnel="exact", estimator=name, sampler=sampler or "sobol", **(extra or {}))
    c0, t0 = time.process_time(), time.perf_counter()
    try:
        exported = be.export_tracer_scene(blender_scene, resolution)
        scene = as_lambert(exported.scene) if diffuse else exported.scene
        settings.validate()
        scene.validate()
        export_seconds = time.perf_counter() - t0
        result = bridge.render_function()(scene, settings, pool=pool, log=lambda *a, **k: None)
    except BaseException:
        pool.shutdown()
        raise
    seconds = time.perf_counter() - t0
    cpu = time.process_time() - c0
    stats = dict(result.stats or {})
    if workers_cpu["before"] is not None and workers_cpu["after"] is not None:
        stats["workers_cpu_seconds"] = workers_cpu["after"] - workers_cpu["before"]
        cpu += stats["workers_cpu_seconds"]
    stats.update(export_seconds=export_seconds, pool_start_seconds=start_seconds)
    return np.asarray(result.image, dtype=np.float64)[..., :3], seconds, cpu, stats


# ------------------------------------------------------------------------------------------ driver
def bench_scene(label, blend, identity, args, threads, log):
    reference, ref_info = be.reference_image(label, blend, identity, cache_dir=args.cache_dir,
                                             resolution=args.resolution, samples=args.reference_samples,
                                             max_depth=args.max_depth, log=log)
    if not np.isfinite(reference).all():
        raise RuntimeError(f"{label}: the Cycles reference has non-finite pixels")
    seed = 1
    rows = {}

    def add(key, run, stats=None):
        image, seconds, cpu = run
        row = dict(renderer=key, samples=args.samples, seconds=seconds, cpu_seconds=cpu,
                   **be.error_metrics(image, reference))
        if stats:
            row["stats"] = {k: stats[k] for k in ("render_seconds", "setup_seconds", "build_seconds",
                                                   "rays_per_second", "nonfinite_samples", "export_seconds",
                                                   "workers_cpu_seconds", "pool_start_seconds") if k in stats}
        rows[key] = row
        if args.images:
            os.makedirs(args.images, exist_ok=True)
            be.write_png(os.path.join(args.images, f"{label}_{key}.png"), image)
        log(f"  {key:14s} {seconds:7.2f} s  MSE {row['mse']:.3e}  relMSE {row['relmse']:.3e}  "
            f"mean {row['mean']:.4f}")
        return row

    scene = be.open_blend(blend, args.resolution)
    be.render_cycles(scene, samples=1, max_depth=args.max_depth, seed=0, threads=threads)      # warm-up
    cycles = add("cycles", be.render_cycles(scene, samples=args.samples, max_depth=args.max_depth, seed=seed,
                                            threads=threads))

    kw = dict(samples=args.samples, max_depth=args.max_depth, threads=threads, estimator=ESTIMATOR)
    exported = be.export_tracer_scene(scene, args.resolution)
    if args.tncg15_pool == "workers":
        def tncg15(diffuse, seed):                  # exports again, timed (render_on_workers)
            return render_on_workers(scene, args.resolution, diffuse=diffuse, seed=seed, **kw)
    else:
        scenes = {False: exported.scene, True: as_lambert(exported.scene)}

        def tncg15(diffuse, seed):
            return be.render_tncg15(scenes[diffuse], seed=seed, **kw)
    tncg15(False, 0)                                                                           # warm-up
    image, seconds, cpu, stats = tncg15(False, seed)
    add("tncg15", (image, seconds, cpu), stats)
    image, seconds, cpu, stats = tncg15(True, seed)
    diffuse = add("tncg15_diffuse", (image, seconds, cpu), stats)

    cycles_eff = 1.0 / (cycles["mse"] * cycles["seconds"]) if cycles["mse"] > 0 else float("inf")
    for row in rows.values():
        be.derived(row, cycles_eff)
    ours = rows["tncg15"]
    return dict(reference=dict(ref_info, mean=float(reference.mean())),
                ref_noise_mse=cycles["mse"] * args.samples / args.reference_samples,
                export_warnings=list(exported.warnings), rows=list(rows.values()),
                efficiency_vs_cycles=ours["efficiency_vs_cycles"],
                rough_over_diffuse_seconds=ours["seconds"] / diffuse["seconds"])


def markdown_table(results):
    """One line per scene: Cycles' and our time, MSE and efficiency, their ratio, and our time
    against the Lambertian stand-in's."""
    f = be._fmt
    lines = ["| scene | Cycles t [s] | Cycles MSE | Cycles eff. | TNCG15 t [s] | TNCG15 MSE | TNCG15 eff. "
             "| eff. TNCG15 / Cycles | t diffuse [s] | t / t diffuse |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for label, res in results.items():
        rows = {row["renderer"]: row for row in res["rows"]}
        c, o, d = rows["cycles"], rows["tncg15"], rows["tncg15_diffuse"]
        lines.append(f"| {label} | {f(c['seconds'], '.2f')} | {f(c['mse'], '.3e')} | {f(c['efficiency'], '.3g')} "
                     f"| {f(o['seconds'], '.2f')} | {f(o['mse'], '.3e')} | {f(o['efficiency'], '.3g')} "
                     f"| {f(res['efficiency_vs_cycles'], '.3g')} | {f(d['seconds'], '.2f')} "
                     f"| {f(res['rough_over_diffuse_seconds'], '.2f')} |")
    return "\n".join(lines)


def bench_materials(args, log=print):
    import json

    import bpy
    threads = args.threads or (os.cpu_count() or 1)
    args.resolution = tuple(int(v) for v in args.resolution)
    args.cache_dir = os.path.abspath(args.cache_dir)
    make_samples = be.load_make_samples()
    blend_dir = os.path.join(args.cache_dir, "blends")
    load_before = os.getloadavg()
    results = {}
    for name in args.scenes or default_scenes(make_samples):
        label, blend, identity = be.scene_blend(name, blend_dir, make_samples)
        log(f"{label}: {args.resolution[0]}x{args.resolution[1]}, {args.samples} spp, depth {args.max_depth}, "
            f"{threads} threads, TNCG15 MC on {args.tncg15_pool}")
        results[label] = bench_scene(label, blend, identity, args, threads, log)
    table = markdown_table(results)
    log("")
    log(table)
    load_after = os.getloadavg()
    log(f"\nload average (1, 5, 15 min) before: {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}, "
        f"after: {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}")
    report = dict(
        settings=dict(resolution=list(args.resolution), samples=args.samples,
                      reference_samples=args.reference_samples, max_depth=args.max_depth, threads=threads,
                      estimator=ESTIMATOR, reference_seed=be.REFERENCE_SEED,
                      tncg15=dict(fresnel="exact", russian_roulette="default", pool=args.tncg15_pool),
                      cycles="mcrt_addon/reference.py fair settings"),
        machine=dict(cpu_count=os.cpu_count(), platform=platform.platform(), date=time.strftime("%Y-%m-%d"),
                     python=sys.version.split()[0], blender=bpy.app.version_string,
                     load_average_before=list(load_before), load_average_after=list(load_after)),
        scenes=results, table=table)
    if args.out:
        out = os.path.abspath(args.out)
        os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
        with open(out, "w") as fh:
            json.dump(report, fh, indent=2, default=be._json_default)
        log(f"\nwrote {out}")
    return 0


def add_arguments(parser):
    parser.add_argument("--scenes", nargs="+", default=None,
                        help="sample scene names (sample_blends/make_samples.py) or .blend paths "
                             f"(default: {', '.join(MATERIAL_SCENES)}, and {', '.join(OPTIONAL_SCENES)} "
                             "when it exists)")
    parser.add_argument("--resolution", type=int, nargs=2, default=(96, 96), metavar=("W", "H"))
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--reference-samples", type=int, default=8192)
    parser.add_argument("--max-depth", type=int, default=12)
    parser.add_argument("--threads", type=int, default=0, help="threads for both renderers (0 = all cores)")
    parser.add_argument("--out", default=os.path.join("docs", "materials-efficiency.json"),
                        help="JSON report (empty string: none)")
    parser.add_argument("--cache-dir", default=os.path.join("renders", "reference"),
                        help="reference EXRs (and the generated .blend files) are cached here")
    parser.add_argument("--images", help="also write an sRGB PNG of every render into this directory")
    parser.add_argument("--tncg15-pool", choices=POOLS, default="workers",
                        help="workers: TNCG15 MC timed as F12 renders, on the add-on's worker processes started "
                             "ahead, export included, CPU seconds with the workers'; threads: on threads inside "
                             "Blender's process, the render alone (the mode before 2026-12-05)")


def check_arguments(parser, args):
    args.repeats = 1
    be.check_arguments(parser, args)
