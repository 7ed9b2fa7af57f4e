"""Caustics by the photon map against path tracing (`mis`) at equal time, and both against Cycles, in one run.

  python scripts/bench_caustics.py [--resolution N] [--seconds T] [--reference-spp S] [--photons P] [--radius R]
         [--clock wall|cpu] [--pilot-spp S] [--repeats K]
         [--parts equal-time cycles photon-count] [--cycles-samples S] [--cycles-reference-samples S] [--threads N] [--tncg15-pool workers|threads]
         [--scenes ...] [--photon-counts N ...] [--count-samples S]
  make bench-caustics

Part "equal-time":

The caustic room of engine/scene/builtin.py (a glass ball on a diffuse floor under a small lamp)
at N x N: a converged reference by path tracing alone (the mean of --references renders of S
samples per pixel at independent seeds, cached in renders/reference/), then `caustics_method path`
and `caustics_method photons` with the same time limit T, each as the tracer renders by default
(2 local workers).  Printed: relMSE
(mean (x - ref)^2 / (ref^2 + 0.01)) over the whole image and inside the caustic region (the pixels
where the reference with Cycles' refractive caustics on exceeds the one with them off by 10 %),
less the reference's own noise (estimated from the spread of the independent references),
and the ratios path / photons (targets: >= 10 inside the caustic, >= 3 over the image; the machine's
load drifts between runs, only the ratios of one run mean anything).  --clock cpu gives each method
T x workers CPU seconds (this process's and its forked workers'): the samples from a pilot render's
rate, the relMSE scaled by the CPU seconds used over the budget (the error is the variance, which
falls as 1 / samples: the photon render's bias is not measurable here, docs/photons.md), so the
other jobs on a shared machine change little.  --repeats K renders K pairs (path, photons), one
after the other, at independent seeds, and prints the ratios' medians.

Part "cycles": efficiency 1 / (MSE t) against Cycles (mcrt_addon/bench_estimators.py, the machinery
of `make bench-materials`), on the sample Cornell box with its glass and mirror balls and on the
caustic room (sample_blends/make_samples.py `cornell`, `caustic`) at N x N, max depth 12: a Cycles
reference with the fair settings of mcrt_addon/reference.py (cached in renders/reference/), Cycles
at --cycles-samples with --threads threads, then TNCG15 MC at the same samples with
`caustics_method path` and with `auto` (the photon map where the effect plan turns it on), one run
each after a short warm-up, timed as F12 renders (--tncg15-pool workers, the default: the add-on's
worker processes started ahead, the export, the scene's transfer and the workers' CPU seconds
counted, as `make bench-materials`) or on threads in Blender's process (--tncg15-pool threads, the
mode of the figures before 2026-12-05).  Printed per row: wall seconds, CPU seconds (all threads
and workers), MSE, efficiency and its ratio to Cycles'; the load average
before and after.  The MSE includes the reference's own noise (about MSE_cycles x samples /
reference samples, printed; the last column takes it out of every MSE) and the model difference of
implicit against tessellated balls.

Part "photon-count" (not in the default parts): the photons per pass against the render's variance
at equal time, on the sample scenes --scenes (cornell, point_caustic, caustic: the Cornell box's
glass and mirror balls, a point light's caustic through a glass ball, the caustic room) at N x N:
for each count of --photon-counts, TNCG15 MC with `auto` at --count-samples twice, at independent
seeds (1 and 1 + 2^16: seeds s and s + 1 share camera samples, tests/addon/imagecompare.py), in
process with --threads threads; variance = mean (a - b)^2 / 2 over the pixels, CPU = the process's
CPU seconds per render; printed: each count's variance, CPU seconds and efficiency 1 / (variance
CPU) relative to the first count's.  No reference needed: the photon count changes no bias (the
radius does not depend on it).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine.api import render  # noqa: E402
from engine.core.settings import RenderSettings  # noqa: E402
from engine.scene.builtin import caustic_scene  # noqa: E402


def rel_mse(image, reference, mask=None, noise=None):
    """mean (x - ref)^2 / (ref^2 + 0.01), less the reference's own noise: `noise` (the variance of
    the reference per pixel, from two independent references)."""
    err = ((image - reference) ** 2 - (0.0 if noise is None else noise)) / (reference ** 2 + 0.01)
    err = err.mean(axis=2)
    return float(err[mask].mean() if mask is not None else err.mean())


def reference(scene, spp, tag, seed=99, **settings):
    path = os.path.join("renders", "reference", f"caustic_{scene.resolution[0]}_{spp}_{tag}_{seed}.npy")
    if os.path.exists(path):
        return np.load(path)
    start = time.perf_counter()
    image = render(scene, RenderSettings(samples=spp, seed=seed, **settings)).image
    os.makedirs(os.path.dirname(path), exist_ok=True)
    np.save(path, image)
    print(f"reference {tag}: {spp} spp in {time.perf_counter() - start:.0f} s -> {path}")
    return image


CYCLES_SCENES = ("cornell", "caustic")       # sample_blends/make_samples.py: glass and mirror balls; the caustic room
CYCLES_DEPTH = 12


def cpu_seconds() -> float:
    """CPU seconds of this process and of its reaped children (the local pool's forked workers are
    joined when a render ends), user + system."""
    import resource
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def timed_render(scene, settings):
    """(result, wall seconds, CPU seconds) of one render."""
    c0, t0 = cpu_seconds(), time.perf_counter()
    result = render(scene, settings)
    return result, time.perf_counter() - t0, cpu_seconds() - c0


def equal_time(args):
    scene = caustic_scene((args.resolution, args.resolution))
    # Independent references: their mean is the reference, their spread its noise (seeds 2^16 apart:
    # seeds s and s + 1 share camera samples a pixel row apart, tests/addon/imagecompare.py).
    refs = np.stack([reference(scene, args.reference_spp, "full", 99 + (k << 16), caustics_method="path")
                     for k in range(args.references)])
    ref = refs.mean(axis=0)
    noise = refs.var(axis=0, ddof=1) / len(refs)      # the variance of their mean, per pixel (unbiased)
    no_caustics = reference(scene, max(args.reference_spp // 8, 64), "no_refractive_caustics",
                            caustics_method="path", caustics_refractive=False)
    region = ref.mean(axis=2) > 1.1 * no_caustics.mean(axis=2)
    workers = RenderSettings().resolved_threads()
    budget = args.seconds * workers
    clock = (f"{args.seconds:g} s of wall each" if args.clock == "wall" else
             f"{budget:g} CPU s each ({args.seconds:g} s x {workers} workers; samples from a {args.pilot_spp}-spp "
             f"pilot, relMSE scaled to the budget: relMSE x CPU / budget)")
    print(f"caustic room {args.resolution}x{args.resolution}, {clock}; caustic region "
          f"{int(region.sum())} pixels; the reference's own relMSE (subtracted): image {rel_mse(ref, ref, None, -noise):.2e}, "
          f"caustic {rel_mse(ref, ref, region, -noise):.2e}")
    methods = ("path", "photons")
    ratios = []
    for k in range(args.repeats):          # path, photons, path, photons, ...: the load drifts alike for both
        rows = {}
        load = os.getloadavg()[0]
        for method in methods:
            common = dict(caustics_method=method, seed=1 + (k << 16), photons_per_pass=args.photons,
                          photon_radius=args.radius)
            if args.clock == "wall":
                r, wall, cpu = timed_render(scene, RenderSettings(samples=1 << 20, time_limit=args.seconds, **common))
                scale = 1.0
            else:
                _, _, pilot = timed_render(scene, RenderSettings(samples=args.pilot_spp, **common))
                spp = max(1, int(round(args.pilot_spp * budget / max(pilot, 1e-9))))
                r, wall, cpu = timed_render(scene, RenderSettings(samples=spp, **common))
                scale = cpu / budget           # variance ~ 1 / samples ~ 1 / CPU seconds
            spp = r.stats["samples_per_pixel"]["mean"]
            rows[method] = (scale * rel_mse(r.image, ref, noise=noise), scale * rel_mse(r.image, ref, region, noise))
            extra = ""
            if "photons" in r.stats:
                ph = r.stats["photons"]
                extra = (f"; photon passes {ph['photon_passes']}, traced {ph['photons_traced']}, stored {ph['photons_stored']}, "
                         f"radius {ph['radius_first']:.4g} -> {ph['radius_last']:.4g}, trace {ph['trace_seconds']:.1f} s, "
                         f"gather {ph['gather_seconds']:.1f} s (worker seconds)")
            print(f"  {method:8s} {wall:5.1f} s wall, {cpu:5.1f} CPU s, {spp:7.1f} spp: relMSE image {rows[method][0]:.3e}, "
                  f"caustic {rows[method][1]:.3e}{extra}", flush=True)
        whole, caustic = (rows["path"][i] / rows["photons"][i] for i in range(2))
        ratios.append((caustic, whole))
        print(f"relMSE path / photons: caustic region {caustic:.1f}x (target >= 10), whole image {whole:.1f}x "
              f"(target >= 3); load average before {load:.2f}, after {os.getloadavg()[0]:.2f}, "
              f"{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC", flush=True)
    if args.repeats > 1:
        caustic, whole = (float(np.median([r[i] for r in ratios])) for i in range(2))
        print(f"median of {args.repeats} pairs: caustic region {caustic:.1f}x, whole image {whole:.1f}x")


def render_ours(scene, method, samples, seed, threads, photons, radius):
    """One TNCG15 MC render in-process: (image, wall seconds, process CPU seconds, stats)."""
    from mcrt_addon import bridge
    settings = bridge.settings_class()(samples=samples, max_depth=CYCLES_DEPTH, seed=seed, threads=threads,
                                       fresnel="exact", caustics_method=method, photons_per_pass=photons,
                                       photon_radius=radius)
    c0, t0 = time.process_time(), time.perf_counter()
    result = bridge.render_function()(scene, settings, log=lambda *a, **k: None)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    return np.asarray(result.image, dtype=np.float64)[..., :3], seconds, cpu, dict(result.stats or {})


def against_cycles(args, log=print):
    """Efficiency 1 / (MSE t) of Cycles, TNCG15 MC path tracing and TNCG15 MC's default (auto)."""
    import platform

    from mcrt_addon import bench_estimators as be
    res = (args.resolution, args.resolution)
    cache = os.path.abspath(os.path.join("renders", "reference"))
    make_samples = be.load_make_samples()
    load_before = os.getloadavg()
    lines = ["| scene | renderer | spp | wall [s] | CPU [s] | MSE | eff. 1/(MSE t) | eff. / Cycles | eff. CPU / Cycles "
             "| eff. / Cycles, ref. noise out |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name in args.scenes:
        label, blend, identity = be.scene_blend(name, os.path.join(cache, "blends"), make_samples)
        reference, _ = be.reference_image(label, blend, identity, cache_dir=cache, resolution=res,
                                          samples=args.cycles_reference_samples, max_depth=CYCLES_DEPTH, log=log)
        scene = be.open_blend(blend, res)
        be.render_cycles(scene, samples=1, max_depth=CYCLES_DEPTH, seed=0, threads=args.threads)     # warm-up
        image, seconds, cpu = be.render_cycles(scene, samples=args.cycles_samples, max_depth=CYCLES_DEPTH, seed=1,
                                               threads=args.threads)
        rows = [("cycles", image, seconds, cpu, {})]
        exported = be.export_tracer_scene(scene, res).scene
        for method in ("path", "auto"):
            if args.tncg15_pool == "workers":       # as F12: the add-on's worker processes (bench_materials.py)
                from mcrt_addon.bench_materials import render_on_workers
                extra = dict(caustics_method=method, photons_per_pass=args.photons, photon_radius=args.radius)
                kw = dict(diffuse=False, max_depth=CYCLES_DEPTH, threads=args.threads, estimator="mis", extra=extra)
                render_on_workers(scene, res, samples=4, seed=0, **kw)                                      # warm-up
                rows.append((f"tncg15 {method}",) + render_on_workers(scene, res, samples=args.cycles_samples, seed=1,
                                                                      **kw))
                continue
            render_ours(exported, method, 4, 0, args.threads, args.photons, args.radius)                   # warm-up
            rows.append((f"tncg15 {method}",) + render_ours(exported, method, args.cycles_samples, 1, args.threads,
                                                            args.photons, args.radius))
        mse = {key: be.error_metrics(img, reference)["mse"] for key, img, *_ in rows}
        eff = {key: 1.0 / (mse[key] * t) for key, _, t, _, _ in rows}
        eff_cpu = {key: 1.0 / (mse[key] * c) for key, _, _, c, _ in rows}
        floor = mse["cycles"] * args.cycles_samples / args.cycles_reference_samples
        eff_net = {key: 1.0 / (max(mse[key] - floor, 1e-30) * t) for key, _, t, _, _ in rows}
        log(f"{label}: {res[0]}x{res[1]}, {args.cycles_samples} spp, depth {CYCLES_DEPTH}, {args.threads} threads; "
            f"reference Cycles {args.cycles_reference_samples} spp (its own noise: MSE about {floor:.2e})")
        for key, _, t, c, stats in rows:
            extra = ""
            if "photons" in stats:
                ph = stats["photons"]
                extra = (f"  photons: stored {ph['photons_stored']}, radius {ph['radius_first']:.3g} -> "
                         f"{ph['radius_last']:.3g}, trace {ph['trace_seconds']:.1f} s, gather {ph['gather_seconds']:.1f} s")
            log(f"  {key:14s} wall {t:6.2f} s  CPU {c:6.2f} s  MSE {mse[key]:.3e}  eff {eff[key]:.4g}  "
                f"eff / Cycles {eff[key] / eff['cycles']:.2f}x (CPU: {eff_cpu[key] / eff_cpu['cycles']:.2f}x; the "
                f"reference's noise out: {eff_net[key] / eff_net['cycles']:.2f}x){extra}")
            lines.append(f"| {label} | {key} | {args.cycles_samples} | {t:.2f} | {c:.2f} | {mse[key]:.3e} | "
                         f"{eff[key]:.4g} | {eff[key] / eff['cycles']:.2f} | {eff_cpu[key] / eff_cpu['cycles']:.2f} | "
                         f"{eff_net[key] / eff_net['cycles']:.2f} |")
    load_after = os.getloadavg()
    log("")
    log("\n".join(lines))
    log(f"\n{platform.node()} {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"{time.strftime('%Y-%m-%d %H:%M')}; load average (1, 5, 15 min) before "
        f"{' '.join(f'{v:.2f}' for v in load_before)}, after {' '.join(f'{v:.2f}' for v in load_after)}")


def photon_count(args, log=print):
    """Variance at equal time for each photon count of `args.photon_counts` (see the module's docstring)."""
    from mcrt_addon import bench_estimators as be
    res = (args.resolution, args.resolution)
    cache = os.path.abspath(os.path.join("renders", "reference"))
    make_samples = be.load_make_samples()
    load_before = os.getloadavg()
    lines = ["| scene | photons per pass | spp | CPU [s] (two renders) | variance | eff. 1/(var CPU) / first |",
             "|---|---:|---:|---:|---:|---:|"]
    for name in args.scenes:
        label, blend, _ = be.scene_blend(name, os.path.join(cache, "blends"), make_samples)
        exported = be.export_tracer_scene(be.open_blend(blend, res), res).scene
        render_ours(exported, "auto", 4, 0, args.threads, args.photon_counts[0], args.radius)        # warm-up
        first = None
        for count in args.photon_counts:
            runs = [render_ours(exported, "auto", args.count_samples, seed, args.threads, count, args.radius)
                    for seed in (1, 1 + (1 << 16))]
            (a, _, ca, stats), (b, _, cb, _) = runs
            variance = float(np.mean((a - b) ** 2) / 2.0)
            cpu = 0.5 * (ca + cb)
            eff = 1.0 / (variance * cpu)
            first = first or eff
            on = "photons" in stats
            log(f"{label}: {count:6d} photons per pass, {args.count_samples} spp: CPU {ca:6.2f} + {cb:6.2f} s, "
                f"variance {variance:.4e}, efficiency / first {eff / first:.2f}x" + ("" if on else " (no photon pass)"))
            lines.append(f"| {label} | {count} | {args.count_samples} | {ca:.2f} + {cb:.2f} | {variance:.4e} | "
                         f"{eff / first:.2f} |")
    load_after = os.getloadavg()
    log("")
    log("\n".join(lines))
    log(f"\n{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC; load average (1, 5, 15 min) before "
        f"{' '.join(f'{v:.2f}' for v in load_before)}, after {' '.join(f'{v:.2f}' for v in load_after)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--references", type=int, default=2,
                    help="equal-time: independent path-traced references (cached), at least 2: their mean is the "
                         "reference, their spread its noise")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="equal-time: each method gets --seconds of wall, or --seconds x workers CPU seconds "
                         "(this process's and its workers', from a pilot render's rate; robust to the machine's load)")
    ap.add_argument("--pilot-spp", type=int, default=128, help="equal-time, --clock cpu: the pilot render's samples")
    ap.add_argument("--repeats", type=int, default=1,
                    help="equal-time: pairs (path, photons) rendered one after the other at independent seeds; "
                         "the ratios' medians printed")
    ap.add_argument("--photons", type=int, default=RenderSettings().photons_per_pass,
                    help="photons per pass (0: the setting's automatic count)")
    ap.add_argument("--radius", type=float, default=0.0, help="the photon map's first radius (0: auto)")
    ap.add_argument("--parts", nargs="+", choices=("equal-time", "cycles", "photon-count"),
                    default=("equal-time", "cycles"))
    ap.add_argument("--scenes", nargs="+", default=CYCLES_SCENES, help="sample scenes of the Cycles part")
    ap.add_argument("--cycles-samples", type=int, default=256)
    ap.add_argument("--cycles-reference-samples", type=int, default=8192)
    ap.add_argument("--threads", type=int, default=2, help="threads of both renderers in the Cycles part")
    ap.add_argument("--tncg15-pool", choices=("workers", "threads"), default="workers",
                    help="the Cycles part: TNCG15 MC timed as F12 renders, on the add-on's worker processes "
                         "started ahead (export, transfer and their CPU seconds counted), or on threads in "
                         "Blender's process (the GIL lets two reach about 1.7 cores)")
    ap.add_argument("--photon-counts", nargs="+", type=int, default=(10000, 5000, 2500, 1250),
                    help="photons per pass of the photon-count part")
    ap.add_argument("--count-samples", type=int, default=64, help="samples per pixel of the photon-count part")
    args = ap.parse_args(argv)
    if "equal-time" in args.parts:
        equal_time(args)
    if "cycles" in args.parts:
        against_cycles(args)
    if "photon-count" in args.parts:
        photon_count(args)


if __name__ == "__main__":
    main()
