"""Light-sampling estimators against Cycles: time, error and efficiency per scene (docs/accuracy.md).

  python -m mcrt_addon bench-estimators [--scenes cornell near_lamp caustic many_lights]
         [--resolution 96 96] [--samples 256] [--reference-samples 4096] [--max-depth 12]
         [--estimators report/random solid-angle mis/random mis] [--threads N] [--repeats K]
         [--out docs/estimators.json] [--cache-dir renders/reference] [--images DIR]

For every scene (a name from sample_blends/make_samples.py, generated afresh into the cache
directory, or a path to a .blend):

1. a Cycles reference with the fair settings of mcrt_addon/reference.py at --reference-samples,
   the same resolution and max depth, all cores, seed 4242; cached as
   ``<cache-dir>/NAME_WxH_SPP_DEPTH.exr`` plus a ``.json`` sidecar, and re-rendered when the
   sidecar does not match (scene generator or .blend changed, other Blender version);
2. Cycles (same fair settings) at --samples with --threads threads;
3. TNCG15 MC in-process at --samples, one run per estimator (exact Fresnel, the same max depth,
   Russian roulette as default), with the same thread count.

Each renderer gets one untimed warm-up render per scene (Cycles 1 spp, TNCG15 MC the full sample
count); the estimators' runs are interleaved.  Times are wall-clock seconds of the render
alone: ``bpy.ops.render.render`` for Cycles (scene sync and BVH build included, EXR write of the
small image included), ``engine.api.render`` for TNCG15 MC (BVH build included, the Blender
export excluded).  With --repeats K, errors and times are the means over K seeds.

Metrics against the reference R (x = the render; means over pixels and the 3 channels):
  MSE = mean (x - R)^2;  relMSE = mean (x - R)^2 / (R^2 + 1e-2);
  worst10 = the share of the summed squared error held by the 10 worst pixels (fireflies: near 1);
  efficiency = 1 / (MSE t);  eff/cycles = efficiency / Cycles' efficiency on the same scene;
  t(relMSE 1e-2) = t relMSE / 1e-2, i.e. relMSE extrapolated as proportional to 1/t.
The JSON also has each row's process CPU seconds (all threads) and efficiency_cpu = 1/(MSE cpu):
less sensitive than wall time to other load on a shared machine.
Caveats: MSE includes the reference's own noise (about MSE_cycles x samples / reference-samples)
and any bias (model differences such as implicit vs tessellated spheres), neither of which falls
with t, so the extrapolation is optimistic once relMSE nears that floor (``ref_noise_relmse`` in
the JSON estimates the reference's share).
"""
import dataclasses
import hashlib
import json
import os
import platform
import sys
import tempfile
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SCENES = ("cornell", "near_lamp", "caustic", "many_lights")
# An estimator, optionally with "/random": independent random numbers instead of the default
# Sobol' sampler ("report/random" is the report's estimator as first written: area sampling, no MIS).
ESTIMATORS = ("report/random", "report", "solid-angle", "mis/random", "mis")
DEFAULT_ESTIMATORS = ("report/random", "solid-angle", "mis/random", "mis")
REFERENCE_SEED = 4242
RELMSE_EPS = 1e-2
TARGET_RELMSE = 1e-2
WORST_PIXELS = 10


# ------------------------------------------------------------------------------------------ metrics
def error_metrics(image, ref):
    """MSE, relMSE and the worst-pixel share of squared error of `image` against `ref` (H, W, 3)."""
    x = np.asarray(image, dtype=np.float64)[..., :3]
    r = np.asarray(ref, dtype=np.float64)[..., :3]
    if x.shape != r.shape:
        raise ValueError(f"image shapes differ: {x.shape} vs {r.shape}")
    sq = (x - r) ** 2
    per_pixel = sq.sum(axis=-1).ravel()
    total = float(per_pixel.sum())
    k = min(WORST_PIXELS, per_pixel.size)
    worst = float(np.partition(per_pixel, per_pixel.size - k)[-k:].sum()) if total > 0 else 0.0
    return dict(mse=float(sq.mean()), relmse=float((sq / (r ** 2 + RELMSE_EPS)).mean()),
                worst10_share=worst / total if total > 0 else 0.0,
                mean=float(x.mean()), nonfinite=int((~np.isfinite(x)).sum()))


def derived(row, cycles_efficiency):
    mse, t = row["mse"], row["seconds"]
    row["efficiency"] = 1.0 / (mse * t) if mse > 0 and t > 0 else float("inf")
    row["efficiency_vs_cycles"] = (row["efficiency"] / cycles_efficiency
                                   if cycles_efficiency and np.isfinite(cycles_efficiency) else float("nan"))
    row["seconds_to_relmse_1e-2"] = t * row["relmse"] / TARGET_RELMSE
    cpu = row.get("cpu_seconds")
    if cpu:
        row["efficiency_cpu"] = 1.0 / (mse * cpu) if mse > 0 else float("inf")
    return row


# --------------------------------------------------------------------------------------- renderers
def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise IOError(buf.geterror())
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)[..., :3]


def write_exr(path, image):
    import OpenImageIO as oiio
    a = np.ascontiguousarray(np.asarray(image, dtype=np.float32)[..., :3])
    buf = oiio.ImageBuf(oiio.ImageSpec(a.shape[1], a.shape[0], 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), a)
    if not buf.write(path):
        raise IOError(buf.geterror())


def write_png(path, image):
    import OpenImageIO as oiio
    a = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)[..., :3]), 0, 1)
    a = np.where(a <= 0.0031308, 12.92 * a, 1.055 * a ** (1 / 2.4) - 0.055)
    buf = oiio.ImageBuf(oiio.ImageSpec(a.shape[1], a.shape[0], 3, oiio.UINT8))
    buf.set_pixels(oiio.ROI(), (a * 255 + 0.5).astype(np.uint8))
    buf.write(path)


def open_blend(path, resolution):
    import bpy
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    ensure_registered(mcrt_addon)
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.use_border = False
    return scene


def render_cycles(scene, *, samples, max_depth, seed, threads, **cycles_options):
    """One Cycles render with the fair reference settings: (image, wall seconds, process CPU seconds).
    `cycles_options`: setup_cycles_reference's film and Light Paths options (mcrt_addon/reference.py)."""
    import bpy
    from mcrt_addon.headless import set_exr_output
    from mcrt_addon.reference import setup_cycles_reference
    setup_cycles_reference(scene, samples=samples, max_depth=max_depth, seed=seed, threads=threads,
                           **cycles_options)
    fd, path = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    os.remove(path)
    set_exr_output(scene, path)
    try:
        c0, t0 = time.process_time(), time.perf_counter()
        bpy.ops.render.render(write_still=True)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        image = read_exr(path)
    finally:
        if os.path.exists(path):
            os.remove(path)
    return image, seconds, cpu


def export_tracer_scene(scene, resolution):
    """The scene as F12 exports it (the render depsgraph, as Cycles renders it)."""
    from mcrt_addon.headless import export_as_rendered
    return export_as_rendered(scene, resolution=tuple(resolution))


def tracer_settings(**kw):
    from mcrt_addon import bridge
    Settings = bridge.settings_class()
    names = {f.name for f in dataclasses.fields(Settings)}
    if "estimator" in kw and "estimator" not in names:
        raise RuntimeError("this tracer's RenderSettings has no 'estimator' field")
    return Settings(**kw)


def render_tncg15(tracer_scene, *, samples, max_depth, seed, threads, estimator):
    """One TNCG15 MC render (in-process): (image, wall seconds, process CPU seconds, stats)."""
    from mcrt_addon import bridge
    render = bridge.render_function()
    name, _, sampler = estimator.partition("/")
    settings = tracer_settings(samples=samples, max_depth=max_depth, seed=seed, threads=threads,
                               fresnel="exact", estimator=name, sampler=sampler or "sobol")
    c0, t0 = time.process_time(), time.perf_counter()
    result = render(tracer_scene, settings, log=lambda *a, **k: None)
    seconds = time.perf_counter() - t0
    cpu = time.process_time() - c0
    return np.asarray(result.image, dtype=np.float64)[..., :3], seconds, cpu, dict(result.stats or {})


# ----------------------------------------------------------------------------------------- scenes
def _sha1(data):
    return hashlib.sha1(data).hexdigest()[:12]


def load_make_samples():
    import importlib.util
    path = os.path.join(REPO, "sample_blends", "make_samples.py")
    spec = importlib.util.spec_from_file_location("make_samples", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with open(path, "rb") as fh:
        module.SOURCE_SHA = _sha1(fh.read())
    return module


def scene_blend(name, blend_dir, make_samples):
    """(label, .blend path, identity hash) for a scene name or a .blend path."""
    if name.endswith(".blend"):
        if not os.path.isfile(name):
            raise FileNotFoundError(name)
        with open(name, "rb") as fh:
            return os.path.splitext(os.path.basename(name))[0], os.path.abspath(name), _sha1(fh.read())
    if name not in make_samples.SCENES:
        raise KeyError(f"unknown scene '{name}' (known: {', '.join(sorted(make_samples.SCENES))})")
    os.makedirs(blend_dir, exist_ok=True)
    path = make_samples.make(name, blend_dir)
    return name, path, make_samples.SOURCE_SHA


def reference_image(label, blend, identity, *, cache_dir, resolution, samples, max_depth, log,
                    cycles_options=None):
    """The cached Cycles reference (image, sidecar dict); `cycles_options` as render_cycles', kept in
    the sidecar (a reference made with other options is rendered again)."""
    import bpy
    cycles_options = dict(cycles_options or {})
    w, h = resolution
    stem = os.path.join(cache_dir, f"{label}_{w}x{h}_{samples}_{max_depth}")
    meta = dict(scene=label, scene_sha=identity, resolution=[w, h], samples=samples, max_depth=max_depth,
                seed=REFERENCE_SEED, blender=bpy.app.version_string)
    if cycles_options:
        meta["cycles_options"] = json.loads(json.dumps(cycles_options, default=_json_default))
    exr, side = stem + ".exr", stem + ".json"
    if os.path.isfile(exr) and os.path.isfile(side):
        with open(side) as fh:
            cached = json.load(fh)
        if {k: cached.get(k) for k in meta} == meta:
            log(f"  reference: cached {os.path.relpath(exr)}")
            return read_exr(exr), dict(cached, path=exr, cached=True)
    log(f"  reference: Cycles {samples} spp at {w}x{h}, depth {max_depth} ...")
    scene = open_blend(blend, resolution)
    image, seconds, _ = render_cycles(scene, samples=samples, max_depth=max_depth, seed=REFERENCE_SEED,
                                      threads=0, **cycles_options)
    os.makedirs(cache_dir, exist_ok=True)
    write_exr(exr, image)
    meta["seconds"] = seconds
    with open(side, "w") as fh:
        json.dump(meta, fh, indent=2)
    log(f"  reference: {seconds:.1f} s -> {os.path.relpath(exr)}")
    return image, dict(meta, path=exr, cached=False)


# ------------------------------------------------------------------------------------------ driver
def bench_scene(label, blend, identity, args, threads, log):
    reference, ref_info = reference_image(label, blend, identity, cache_dir=args.cache_dir,
                                          resolution=args.resolution, samples=args.reference_samples,
                                          max_depth=args.max_depth, log=log)
    if not np.isfinite(reference).all():
        raise RuntimeError(f"{label}: the Cycles reference has non-finite pixels")
    seeds = [1 + k for k in range(args.repeats)]
    rows = []

    def add(renderer, estimator, runs, extra=None):
        metrics = [error_metrics(r[0], reference) for r in runs]
        row = dict(renderer=renderer, estimator=estimator, samples=args.samples,
                   seconds=float(np.mean([r[1] for r in runs])),
                   seconds_all=[r[1] for r in runs], cpu_seconds=float(np.mean([r[2] for r in runs])))
        for key in ("mse", "relmse", "worst10_share", "mean"):
            row[key] = float(np.mean([m[key] for m in metrics]))
        row["nonfinite"] = int(sum(m["nonfinite"] for m in metrics))
        row.update(extra or {})
        rows.append(row)
        if args.images:
            os.makedirs(args.images, exist_ok=True)
            tag = renderer if estimator is None else f"{renderer}_{estimator.replace('/', '-')}"
            write_png(os.path.join(args.images, f"{label}_{tag}.png"), runs[0][0])
        log(f"  {renderer:9s} {estimator or '':11s} {row['seconds']:7.2f} s  MSE {row['mse']:.3e}  "
            f"relMSE {row['relmse']:.3e}  worst10 {row['worst10_share']:.2f}")
        return row

    # Cycles at the benchmark's sample count
    scene = open_blend(blend, args.resolution)
    render_cycles(scene, samples=1, max_depth=args.max_depth, seed=0, threads=threads)   # warm-up
    cycles_runs = [render_cycles(scene, samples=args.samples, max_depth=args.max_depth, seed=s,
                                 threads=threads) for s in seeds]
    cycles = add("cycles", None, cycles_runs)

    # TNCG15 MC, one run set per estimator
    exported = export_tracer_scene(scene, args.resolution)
    # warm-up at the full sample count: the first render of a size pays for page faults of its
    # work arrays (measured: up to 2x the time of the next one at 32x32..64x64)
    render_tncg15(exported.scene, samples=args.samples, max_depth=args.max_depth, seed=0, threads=threads,
                  estimator=args.estimators[0])
    runs = {e: [] for e in args.estimators}
    stats = {}
    for s in seeds:                              # estimators interleaved: drift spreads over all
        for estimator in args.estimators:
            img, seconds, cpu, stats[estimator] = render_tncg15(
                exported.scene, samples=args.samples, max_depth=args.max_depth, seed=s, threads=threads,
                estimator=estimator)
            runs[estimator].append((img, seconds, cpu))
    for estimator in args.estimators:
        add("tncg15", estimator, runs[estimator],
            dict(stats={k: stats[estimator][k] for k in ("render_seconds", "setup_seconds", "build_seconds",
                                                          "rays_per_second", "nonfinite_samples")
                        if k in stats[estimator]}))

    cycles_eff = 1.0 / (cycles["mse"] * cycles["seconds"]) if cycles["mse"] > 0 else float("inf")
    for row in rows:
        derived(row, cycles_eff)
    return dict(reference=dict(ref_info, mean=float(reference.mean())),
                ref_noise_relmse=cycles["relmse"] * args.samples / args.reference_samples,
                export_warnings=list(exported.warnings), rows=rows)


def _fmt(x, spec):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    return format(x, spec)


def markdown_table(results):
    lines = ["| scene | renderer | t [s] | MSE | relMSE | worst-10 share | eff. 1/(MSE·t) | eff. vs Cycles "
             "| t to relMSE 1e-2 [s] |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for label, res in results.items():
        for row in res["rows"]:
            name = "Cycles" if row["renderer"] == "cycles" else f"TNCG15 {row['estimator']}"
            lines.append(f"| {label} | {name} | {_fmt(row['seconds'], '.2f')} | {_fmt(row['mse'], '.3e')} "
                         f"| {_fmt(row['relmse'], '.3e')} | {_fmt(row['worst10_share'], '.2f')} "
                         f"| {_fmt(row['efficiency'], '.3g')} | {_fmt(row['efficiency_vs_cycles'], '.3g')} "
                         f"| {_fmt(row['seconds_to_relmse_1e-2'], '.3g')} |")
    return "\n".join(lines)


def bench_estimators(args, log=print):
    import bpy
    threads = args.threads or (os.cpu_count() or 1)
    args.resolution = tuple(int(v) for v in args.resolution)
    args.cache_dir = os.path.abspath(args.cache_dir)
    make_samples = load_make_samples()
    blend_dir = os.path.join(args.cache_dir, "blends")
    results = {}
    for name in args.scenes:
        label, blend, identity = scene_blend(name, blend_dir, make_samples)
        log(f"{label}: {args.resolution[0]}x{args.resolution[1]}, {args.samples} spp, depth {args.max_depth}, "
            f"{threads} threads")
        results[label] = bench_scene(label, blend, identity, args, threads, log)
    table = markdown_table(results)
    log("")
    log(table)
    report = dict(
        settings=dict(resolution=list(args.resolution), samples=args.samples,
                      reference_samples=args.reference_samples, max_depth=args.max_depth,
                      estimators=list(args.estimators), threads=threads, repeats=args.repeats,
                      reference_seed=REFERENCE_SEED, relmse_eps=RELMSE_EPS, target_relmse=TARGET_RELMSE,
                      tncg15=dict(fresnel="exact", russian_roulette="default"),
                      cycles="mcrt_addon/reference.py fair settings"),
        machine=dict(cpu_count=os.cpu_count(), platform=platform.platform(), date=time.strftime("%Y-%m-%d"),
                     python=sys.version.split()[0], blender=bpy.app.version_string),
        scenes=results, table=table)
    if args.out:
        out = os.path.abspath(args.out)
        os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
        with open(out, "w") as fh:
            json.dump(report, fh, indent=2, default=_json_default)
        log(f"\nwrote {out}")
    return 0


def _json_default(value):
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def add_arguments(parser):
    parser.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES),
                        help="sample scene names (sample_blends/make_samples.py) or .blend paths")
    parser.add_argument("--resolution", type=int, nargs=2, default=(96, 96), metavar=("W", "H"))
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--reference-samples", type=int, default=4096)
    parser.add_argument("--max-depth", type=int, default=12)
    parser.add_argument("--estimators", nargs="+", default=list(DEFAULT_ESTIMATORS), choices=ESTIMATORS,
                        help="estimators; NAME/random: with independent random numbers")
    parser.add_argument("--threads", type=int, default=0, help="threads for both renderers (0 = all cores)")
    parser.add_argument("--repeats", type=int, default=1, help="runs (seeds) per renderer; means reported")
    parser.add_argument("--out", default=os.path.join("docs", "estimators.json"),
                        help="JSON report (empty string: none)")
    parser.add_argument("--cache-dir", default=os.path.join("renders", "reference"),
                        help="reference EXRs (and the generated .blend files) are cached here")
    parser.add_argument("--images", help="also write an sRGB PNG of every render into this directory")


def check_arguments(parser, args):
    for name in ("samples", "reference_samples", "repeats"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1")
    if args.max_depth < 0 or args.threads < 0:
        parser.error("--max-depth and --threads must be >= 0")
    if min(args.resolution) < 1:
        parser.error("--resolution must be positive")
