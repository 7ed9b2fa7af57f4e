"""The last speed targets per sample file: TNCG15 MC's per-sample time and efficiency against Cycles.

  .venv/bin/python scripts/bench_sample_files.py [--files cornell caustic ...] [--resolutions 96 256]
         [--samples 96=16,64 256=4,16] [--threads 2] [--efficiency-resolutions 96]
         [--reference-samples 1024] [--cache-dir renders/reference-files] [--references-only] [--repeats 3]
         [--tncg15-pool workers|in-process]
         [--out renders/bench-sample-files.json]

Targets (docs/performance.md "Against Cycles per sample file"): on every sample_blends/*.blend (used
as they are in the repository, not regenerated), at 96^2 and 256^2 with 2 threads,
  time:        TNCG15 MC's per-sample time <= 0.6 x Cycles';
  efficiency:  1/(MSE t) >= 2 x Cycles'.

Per file and resolution, each renderer renders the file as the user has it at two sample counts
S1 < S2 (seed 1) after one untimed warm-up (Cycles 1 spp; TNCG15 MC S1 spp: the first render of a
size pays for its work arrays' page faults, mcrt_addon/bench_estimators.py):
* TNCG15 MC: the file's own TNCG15 MC settings (scene.tncg15.to_settings: what F12 renders) with
  only samples, seed and threads set, engine.api.render on the exported render depsgraph (the export
  excluded from the clock, as bench_estimators does) on the pool F12 takes: one worker process per
  thread started ahead with its kernels loaded (--tncg15-pool workers, the default; their CPU
  seconds read from /proc) or in this process's threads (--tncg15-pool in-process);
* Cycles: the fair settings of mcrt_addon/reference.py (no adaptive sampling, denoising or light
  threshold; CPU) given the same max depth, Light Paths and film (filter, exposure) as TNCG15 MC,
  as `python -m mcrt_addon render --engine CYCLES` does; its clock covers bpy.ops.render.render.
With --repeats N each renderer renders S1, S2 N times alternated and each time is the median of its N.
Per-sample time = (t(S2) - t(S1)) / (S2 - S1), in wall seconds and in process CPU seconds (user +
system of this process, and of TNCG15 MC's workers read from /proc): the BVH build, scene sync and other per-render
costs cancel.  `ratio` = TNCG15 MC / Cycles; `whole` = the ratio of the whole renders at S2.

Efficiency (at --efficiency-resolutions): a Cycles reference per file at --reference-samples with
the same options, all cores, seed 4242, cached by bench_estimators.reference_image (EXR + JSON
sidecar in --cache-dir, rendered again when the file, options or Blender change; never committed).
MSE of both S2 renders against it (bench_estimators.error_metrics), efficiency = 1/(MSE t) with t
the whole render's wall seconds at S2, ratio to Cycles'.  The reference's own noise is in both
MSEs: about MSE_cycles x S2 / reference-samples (`ref_noise_share` = that over Cycles' MSE).

A file that fails in either renderer gives a row with the error.  On a shared machine wall seconds
move with other load; CPU seconds less so (with --tncg15-pool in-process TNCG15 MC's two threads
share the GIL and reach fewer cores than Cycles' two, so its CPU ratio flatters it: the target is in
wall seconds, and F12's worker processes are the default).
"""
import argparse
import dataclasses
import glob
import json
import math
import os
import platform
import resource
import sys
import time
import traceback

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)

TIME_TARGET = 0.6                  # TNCG15 MC's per-sample time / Cycles' at most this
EFFICIENCY_TARGET = 2.0            # TNCG15 MC's 1/(MSE t) / Cycles' at least this
DEFAULT_SAMPLES = {96: (16, 64), 256: (4, 16)}
SEED = 1
MSE_NOTE = 2.0                     # a note when TNCG15 MC's MSE at S2 is above this x Cycles' (bias, fireflies)
RENDERERS = ("cycles", "tncg15")


# ------------------------------------------------------------------------------ pure parts (tested)
def per_sample(t1, t2, s1, s2):
    """The slope (t2 - t1) / (s2 - s1): seconds per sample with the per-render costs cancelled."""
    if not s2 > s1:
        raise ValueError(f"need S1 < S2, got {s1}, {s2}")
    return (t2 - t1) / (s2 - s1)


def ratio(a, b):
    """a / b, NaN when either is missing or b is not a positive finite number."""
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return float("nan")
    return a / b


def median_timing(runs):
    """{wall, cpu} of repeated timings of one render: each clock's median (a disturbed run, e.g. another
    process's burst or a worker's page faults, moves a per-sample slope of two such renders by its whole
    size; the median of 3 does not follow one), with the runs kept under `runs`."""
    if not runs:
        raise ValueError("no timings")
    out = {}
    for clock in ("wall", "cpu"):
        values = sorted(r[clock] for r in runs)
        n = len(values)
        out[clock] = values[n // 2] if n % 2 else 0.5 * (values[n // 2 - 1] + values[n // 2])
    if len(runs) > 1:
        out["runs"] = [dict(r) for r in runs]
    return out


def efficiency(mse, seconds):
    return 1.0 / (mse * seconds) if mse > 0 and seconds > 0 else float("inf")


def meets_time(r):
    """The time target on a ratio TNCG15 / Cycles: True, False or None (not measured)."""
    return None if r is None or not math.isfinite(r) else r <= TIME_TARGET


def meets_efficiency(r):
    return None if r is None or not math.isfinite(r) else r >= EFFICIENCY_TARGET


def samples_for(resolution, table):
    """(S1, S2) at this resolution: the table's, else the nearest one's scaled by the pixel count."""
    if resolution in table:
        return table[resolution]
    near = min(table, key=lambda r: abs(r - resolution))
    scale = (near / resolution) ** 2
    s1, s2 = (max(1, round(s * scale)) for s in table[near])
    return (s1, max(s2, s1 + 1))


def summarise(row):
    """Add the slopes, ratios and met flags to a row with `cycles`/`tncg15` {S: {wall, cpu}} timings."""
    s1, s2 = row["samples"]
    for clock in ("wall", "cpu"):
        for r in RENDERERS:
            t = row[r]
            row[f"{r}_per_sample_{clock}"] = per_sample(t[str(s1)][clock], t[str(s2)][clock], s1, s2)
        row[f"ratio_{clock}"] = ratio(row[f"tncg15_per_sample_{clock}"], row[f"cycles_per_sample_{clock}"])
        row[f"whole_ratio_{clock}"] = ratio(row["tncg15"][str(s2)][clock], row["cycles"][str(s2)][clock])
        row[f"time_met_{clock}"] = meets_time(row[f"ratio_{clock}"])
    if "cycles_mse" in row:
        for clock in ("wall", "cpu"):
            for r in RENDERERS:
                row[f"{r}_efficiency_{clock}"] = efficiency(row[f"{r}_mse"], row[r][str(s2)][clock])
            row[f"efficiency_ratio_{clock}"] = ratio(row[f"tncg15_efficiency_{clock}"],
                                                     row[f"cycles_efficiency_{clock}"])
        row["efficiency_met"] = meets_efficiency(row["efficiency_ratio_wall"])
        row["efficiency_met_cpu"] = meets_efficiency(row["efficiency_ratio_cpu"])
        row["mse_ratio"] = ratio(row["tncg15_mse"], row["cycles_mse"])
        note = f"MSE {row['mse_ratio']:.1f}x Cycles' at S2"
        if row["mse_ratio"] > MSE_NOTE and note not in row["notes"]:    # more than noise: a bias?
            row["notes"].append(note)
    return row


def _f(x, spec):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return format(x, spec)


def _met(flag):
    return {True: "yes", False: "**no**", None: "–"}[flag]


def markdown_table(rows):
    """One line per (file, resolution): ms per sample wall (CPU), ratios, met flags, notes."""
    lines = ["| file | res | S1→S2 | Cycles ms/spp wall (CPU) | TNCG15 ms/spp wall (CPU) | ratio wall (CPU) "
             f"| ≤ {TIME_TARGET} wall (CPU) | whole at S2 wall (CPU) | eff. ratio wall (CPU) "
             f"| ≥ {EFFICIENCY_TARGET:g} wall (CPU) | notes |",
             "|---|---:|---|---:|---:|---:|---|---:|---:|---|---|"]
    for row in rows:
        head = f"| {row['file']} | {row['resolution']} | {row['samples'][0]}→{row['samples'][1]} "
        if row.get("error"):
            lines.append(head + "| – | – | – | – | – | – | – | error: "
                         + row["error"].replace("|", "/").replace("\n", " ")[:160] + " |")
            continue
        ms = {k: 1e3 * row[k] for k in ("cycles_per_sample_wall", "cycles_per_sample_cpu",
                                         "tncg15_per_sample_wall", "tncg15_per_sample_cpu")}
        eff = (f"{_f(row['efficiency_ratio_wall'], '.2f')} ({_f(row['efficiency_ratio_cpu'], '.2f')})"
               if "efficiency_ratio_wall" in row else "–")
        lines.append(head + f"| {ms['cycles_per_sample_wall']:.2f} ({ms['cycles_per_sample_cpu']:.2f}) "
                     f"| {ms['tncg15_per_sample_wall']:.2f} ({ms['tncg15_per_sample_cpu']:.2f}) "
                     f"| {_f(row['ratio_wall'], '.2f')} ({_f(row['ratio_cpu'], '.2f')}) "
                     f"| {_met(row['time_met_wall'])} ({_met(row['time_met_cpu'])}) "
                     f"| {_f(row['whole_ratio_wall'], '.2f')} ({_f(row['whole_ratio_cpu'], '.2f')}) "
                     f"| {eff} | {_met(row.get('efficiency_met'))} ({_met(row.get('efficiency_met_cpu'))}) "
                     f"| {'; '.join(row.get('notes', []))} |")
    return "\n".join(lines)


def header(meta):
    return (f"bench_sample_files: {meta['utc']} UTC, load average {meta['load_start']} at the start, "
            f"{meta.get('load_end', '?')} at the end; {meta['cpu_count']} cores, {meta['platform']}; "
            f"Blender {meta['blender']}; {meta['threads']} threads; TNCG15 MC {meta.get('tncg15_pool', 'in-process')}; "
            f"reference {meta['reference_samples']} spp; median of {meta.get('repeats', 1)} render(s) per point")


def summary_lines(rows):
    """Which rows miss which target."""
    out = []
    for key, label in (("time_met_wall", f"per-sample time ≤ {TIME_TARGET} x Cycles (wall)"),
                       ("efficiency_met", f"efficiency ≥ {EFFICIENCY_TARGET:g} x Cycles (wall)")):
        done = [r for r in rows if r.get(key) is not None]
        missed = [f"{r['file']}@{r['resolution']}" for r in done if not r[key]]
        out.append(f"{label}: met on {len(done) - len(missed)} of {len(done)} measured rows"
                   + (f"; missed: {', '.join(missed)}" if missed else ""))
    errors = [f"{r['file']}@{r['resolution']}" for r in rows if r.get("error")]
    if errors:
        out.append(f"errors: {', '.join(errors)}")
    return out


# ------------------------------------------------------------------------------------ measurement
def cpu_seconds():
    """User + system seconds of this process (all its threads: Cycles renders in them).  Not its
    waited-for children: the worker processes of an earlier TNCG15 MC render are reaped by a thread
    when they exit (engine/pools/transport.py close_all(wait=False)), whose seconds would land in
    whatever clock runs then (Cycles' 16-spp render took 3.4 CPU s in 0.14 s of wall that way);
    TNCG15 MC's workers are read from /proc instead (on_workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def timed(fn):
    c0, t0 = cpu_seconds(), time.perf_counter()
    value = fn()
    return value, dict(wall=time.perf_counter() - t0, cpu=cpu_seconds() - c0)


def on_workers(render, spp, threads):
    """render(spp, pool) on the pool F12 takes when the add-on started its workers ahead (one worker
    process per thread, kernels loaded: mcrt_addon/bench_materials.py measured_warm_pool), started
    before the clock; (image, {wall, cpu}) with cpu = this process's and the workers' CPU seconds
    of the render (read from /proc before the pool closes)."""
    from mcrt_addon import bench_materials as bm
    pool, _, workers = bm.measured_warm_pool(threads)
    c0, t0 = time.process_time(), time.perf_counter()
    try:
        image = render(spp, pool)
    except BaseException:
        pool.shutdown()
        raise
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if workers["after"] is None:            # the render did not close it (it always does)
        pool.close()
    if workers["before"] is None or workers["after"] is None:
        raise RuntimeError("the workers' CPU seconds cannot be read (/proc)")
    return image, dict(wall=wall, cpu=cpu + workers["after"] - workers["before"])


def load_average():
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def file_settings(scene, *, samples, threads):
    """The file's TNCG15 MC settings as F12 renders them, with samples, seed and threads set (stopping
    rules other than the sample count off, so that both counts are rendered in full)."""
    from mcrt_addon import bridge
    settings = scene.tncg15.to_settings(bridge.settings_class())
    return dataclasses.replace(settings, samples=samples, min_samples=0, seed=SEED, threads=threads,
                               time_limit=0.0, noise_target=0.0)


def cycles_options(settings):
    """setup_cycles_reference's options for the same Light Paths and film as `settings`."""
    from mcrt_addon.reference import LIGHT_PATHS, FilmSettings
    return dict(film=FilmSettings.of(settings), **{name: getattr(settings, name) for name in LIGHT_PATHS})


def blend_identity(path):
    from mcrt_addon import bench_estimators as be
    return be.scene_blend(path, None, None)


def reference(path, resolution, args, log):
    """The cached Cycles reference of a file at `resolution` (bench_estimators.reference_image)."""
    from mcrt_addon import bench_estimators as be
    label, blend, identity = blend_identity(path)
    scene = be.open_blend(blend, resolution)
    settings = file_settings(scene, samples=args.reference_samples, threads=0)
    return be.reference_image(label, blend, identity, cache_dir=args.cache_dir, resolution=resolution,
                              samples=args.reference_samples, max_depth=settings.max_depth, log=log,
                              cycles_options=cycles_options(settings))


def measure(path, res, args, log):
    """One row: both renderers at S1 and S2 (after their warm-ups), and the efficiency when asked."""
    import numpy as np
    from mcrt_addon import bench_estimators as be, bridge
    label = os.path.splitext(os.path.basename(path))[0]
    s1, s2 = samples_for(res, args.samples)
    row = dict(file=label, resolution=res, samples=[s1, s2], notes=[])
    try:
        ref = None
        if res in args.efficiency_resolutions:
            ref, ref_info = reference(path, (res, res), args, log)
            row["reference"] = {k: ref_info.get(k) for k in ("path", "samples", "seconds", "cached")}
        scene = be.open_blend(path, (res, res))
        settings = file_settings(scene, samples=s1, threads=args.threads)
        options = cycles_options(settings)
        row["max_depth"] = settings.max_depth
        images = {}

        def cycles(spp):
            image, _, _ = be.render_cycles(scene, samples=spp, max_depth=settings.max_depth, seed=SEED,
                                           threads=args.threads, **options)
            return image

        cycles(1)                                                  # warm-up
        runs = {spp: [] for spp in (s1, s2)}
        for _ in range(args.repeats):
            for spp in (s1, s2):
                images[("cycles", spp)], t = timed(lambda: cycles(spp))
                runs[spp].append(t)
        cyc = {str(spp): median_timing(runs[spp]) for spp in (s1, s2)}
        row["cycles"] = cyc

        exported = be.export_tracer_scene(scene, (res, res))
        if exported.warnings:
            row["notes"].append(f"{len(exported.warnings)} export warning(s)")
        render = bridge.render_function()
        stats = {}

        def tncg15(spp, pool=None):
            result = render(exported.scene, dataclasses.replace(settings, samples=spp), pool=pool,
                            log=lambda *a, **k: None)
            stats.update(result.stats or {})
            return np.asarray(result.image, dtype=np.float64)[..., :3]

        if args.tncg15_pool == "workers":
            tncg15_timed = lambda spp: on_workers(tncg15, spp, args.threads)       # noqa: E731
        else:
            tncg15_timed = lambda spp: timed(lambda: tncg15(spp))                  # noqa: E731
        tncg15_timed(s1)                                           # warm-up
        runs = {spp: [] for spp in (s1, s2)}
        for _ in range(args.repeats):
            for spp in (s1, s2):
                images[("tncg15", spp)], t = tncg15_timed(spp)
                runs[spp].append(t)
        tnc = {str(spp): median_timing(runs[spp]) for spp in (s1, s2)}
        row["tncg15"] = tnc
        if stats.get("photons"):
            row["notes"].append("photons on")
        row["tncg15_stats"] = {k: stats[k] for k in ("parallelism", "build_seconds", "setup_seconds",
                                                      "render_seconds", "nonfinite_samples") if k in stats}
        for r in RENDERERS:
            bad = int((~np.isfinite(images[(r, s2)])).sum())
            if bad:
                row["notes"].append(f"{r}: {bad} non-finite values")
        if ref is not None:
            for r in RENDERERS:
                m = be.error_metrics(np.nan_to_num(images[(r, s2)]), ref)
                row[f"{r}_mse"], row[f"{r}_relmse"] = m["mse"], m["relmse"]
            row["ref_noise_share"] = s2 / args.reference_samples    # of Cycles' MSE
        summarise(row)
    except Exception as exc:                                       # a row, not a crash
        row["error"] = f"{type(exc).__name__}: {exc}"
        row["traceback"] = traceback.format_exc()
        log(row["traceback"])
    return row


# ------------------------------------------------------------------------------------------ driver
def parse_samples(items):
    table = {}
    for item in items:
        res, _, counts = item.partition("=")
        s1, s2 = (int(v) for v in counts.split(","))
        if not 0 < s1 < s2:
            raise argparse.ArgumentTypeError(f"--samples {item}: need 0 < S1 < S2")
        table[int(res)] = (s1, s2)
    return table


def sample_files(names):
    every = sorted(glob.glob(os.path.join(REPO, "sample_blends", "*.blend")))
    if not names:
        return every
    chosen = []
    for name in names:
        path = name if name.endswith(".blend") else os.path.join(REPO, "sample_blends", name + ".blend")
        chosen.append(os.path.abspath(path))
    return chosen


def build_parser():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--files", nargs="+", help="sample file names (sample_blends/NAME.blend) or .blend paths; "
                   "default all")
    p.add_argument("--resolutions", type=int, nargs="+", default=[96, 256], help="square sizes")
    p.add_argument("--samples", nargs="+", default=[f"{r}={a},{b}" for r, (a, b) in DEFAULT_SAMPLES.items()],
                   help="RES=S1,S2 per resolution (others: the nearest one's, scaled by the pixel count)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=1,
                   help="renders of each sample count per renderer (S1, S2 alternated); each clock's median "
                        "is used (3: a single disturbed render no longer makes a row's slope)")
    p.add_argument("--tncg15-pool", choices=("workers", "in-process"), default="workers",
                   help="TNCG15 MC on F12's worker processes started ahead (default: what a user's F12 "
                        "gets, one process per thread) or in this process's threads (the GIL: about "
                        "1.5 cores of 2)")
    p.add_argument("--efficiency-resolutions", type=int, nargs="*", default=[96],
                   help="resolutions with the efficiency against a cached Cycles reference (none: timing only)")
    p.add_argument("--reference-samples", type=int, default=1024,
                   help="Cycles reference samples (1024 at 96^2: 15-60 CPU s a file here, 33 files about "
                        "20 CPU minutes; its noise is S2/1024 = 6 %% of Cycles' MSE at 64 spp)")
    p.add_argument("--cache-dir", default=os.path.join(REPO, "renders", "reference-files"))
    p.add_argument("--references-only", action="store_true", help="only make the cached references")
    p.add_argument("--out", default=os.path.join(REPO, "renders", "bench-sample-files.json"),
                   help="JSON report (empty: none)")
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    args.samples = parse_samples(args.samples)
    args.cache_dir = os.path.abspath(args.cache_dir)
    files = sample_files(args.files)

    def log(*a):
        print(*a, flush=True)

    import bpy
    meta = dict(utc=time.strftime("%Y-%m-%d %H:%M", time.gmtime()), load_start=load_average(),
                cpu_count=os.cpu_count(), platform=platform.platform(), blender=bpy.app.version_string,
                threads=args.threads, reference_samples=args.reference_samples, tncg15_pool=args.tncg15_pool,
                samples={str(k): v for k, v in args.samples.items()}, resolutions=args.resolutions,
                repeats=args.repeats,
                efficiency_resolutions=args.efficiency_resolutions)
    log(header(meta))
    if args.references_only:
        for res in args.efficiency_resolutions:
            for path in files:
                t0 = time.perf_counter()
                try:
                    reference(path, (res, res), args, log)
                except Exception as exc:
                    log(f"{os.path.basename(path)}@{res}: reference failed: {type(exc).__name__}: {exc}")
                log(f"{os.path.basename(path)}@{res}: {time.perf_counter() - t0:.1f} s, load {load_average()}")
        return 0
    rows = []
    for res in args.resolutions:
        for path in files:
            log(f"{os.path.basename(path)} {res}x{res} (load {load_average()})")
            row = measure(path, res, args, log)
            rows.append(row)
            log(markdown_table([row]).splitlines()[-1])
    meta["load_end"] = load_average()
    meta["utc_end"] = time.strftime("%Y-%m-%d %H:%M", time.gmtime())
    table = markdown_table(rows)
    log("\n" + header(meta) + "\n\n" + table + "\n\n" + "\n".join(summary_lines(rows)))
    if args.out:
        from mcrt_addon.bench_estimators import _json_default
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out, "w") as fh:
            json.dump(dict(meta=meta, rows=rows, table=table, summary=summary_lines(rows)), fh, indent=1,
                      default=_json_default)
        log(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
