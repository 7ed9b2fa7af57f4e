"""The material sample scenes against Cycles: time, error and efficiency per scene (docs/materials.md,
"Efficiency against Cycles"), with the machinery of mcrt_addon/bench_estimators.py.

  python -m mcrt_addon bench-materials [--scenes glossy_plates rough_diffuse ...] [--resolution 96 96]
         [--samples 256] [--reference-samples 8192] [--max-depth 12] [--threads N]
         [--out docs/materials-efficiency.json] [--cache-dir renders/reference] [--images DIR]

For every scene (a name of sample_blends/make_samples.py, generated afresh into the cache
directory, or a .blend path):

1. the Cycles reference of bench_estimators.reference_image (fair settings, all cores, cached as
   ``<cache-dir>/NAME_WxH_SPP_DEPTH.exr`` with its sidecar);
2. Cycles (same fair settings) at --samples with --threads threads, one run after a 1-spp warm-up;
3. TNCG15 MC in-process at --samples with the default estimator (mis) and sampler, exact Fresnel,
   the same max depth and threads, one run after a warm-up at the full sample count;
4. the same exported tracer scene with every material replaced by a Lambertian of its base
   colour (`as_lambert`: emission and textures kept, mixes by their leaves' constant weights),
   timed the same way: what the materials cost against plain diffuse ("t rough / t diffuse").

Times, MSE and efficiency 1/(MSE t) are bench_estimators' (`error_metrics`, `derived`): wall-clock
seconds of the render alone; MSE over pixels and channels against the reference, which includes the
reference's own noise (about MSE_cycles x samples / reference-samples: ``ref_noise_mse`` in the JSON)
and any model difference (bias), neither falling with t.  One run per renderer: on a shared machine
the times move with the other load (the JSON keeps the process CPU seconds too).
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
                                                   "rays_per_second", "nonfinite_samples") if k in stats}
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

    exported = be.export_tracer_scene(scene, args.resolution)
    diffuse_scene = as_lambert(exported.scene)
    kw = dict(samples=args.samples, max_depth=args.max_depth, threads=threads, estimator=ESTIMATOR)
    be.render_tncg15(exported.scene, seed=0, **kw)                                             # warm-up
    image, seconds, cpu, stats = be.render_tncg15(exported.scene, seed=seed, **kw)
    add("tncg15", (image, seconds, cpu), stats)
    image, seconds, cpu, stats = be.render_tncg15(diffuse_scene, seed=seed, **kw)
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
            f"{threads} threads")
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
                      tncg15=dict(fresnel="exact", russian_roulette="default"),
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


def check_arguments(parser, args):
    args.repeats = 1
    be.check_arguments(parser, args)
