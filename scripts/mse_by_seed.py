"""MSE per sample against Cycles over several seeds, per sample file, with error maps.

  .venv/bin/python scripts/mse_by_seed.py --files sky glossy_plates [--seeds 1 2 3 4] [--samples 64]
         [--resolution 96] [--cache-dir renders/reference-files] [--save DIR]
         [--set estimator=solid-angle ...] [--max-depth 0] [--only tncg15|cycles] [--load-cycles DIR]

bench_sample_files measures TNCG15 MC's and Cycles' MSE of one render each (seed 1) against the
cached 1024-spp Cycles reference; one seed moves that ratio by 10-20 %.  This renders both at S
samples for each seed (the same file settings, film and Light Paths as bench_sample_files:
file_settings, cycles_options, reference), and prints per file:

* mse_tncg15, mse_cycles: the mean over seeds of each render's MSE against the reference;
* ratio: their quotient, and ratio_net: the same with the reference's own noise taken out of both
  (about MSE_cycles x S / reference-samples, ref_noise_share in bench_sample_files);
* bias: the mean over seeds of TNCG15 MC's image minus Cycles' (both unbiased estimators of the
  same image if the models agree) as a mean over pixels and its standard error, and the share of
  TNCG15 MC's error that the mean image's difference explains;
* with --save, an .npz per file with every image and the per-pixel squared error of both over the
  seeds (error maps: where the extra error is).

--set NAME=VALUE changes a TNCG15 MC setting (a RenderSettings field) for the localisation runs
(estimator=solid-angle, backend=numpy, ...); Cycles renders as the file has it.  --max-depth sets
both renderers' depth (0: direct light only; compare var_ratio, the reference has the file's
depth).  --load-cycles DIR takes Cycles' images of the same seeds from an earlier --save DIR
(before/after runs of TNCG15 MC against the same Cycles images).
"""
import argparse
import dataclasses
import json
import os
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if REPO not in sys.path:
    sys.path.insert(0, REPO)
sys.path.insert(0, os.path.join(REPO, "scripts"))


def parse_value(text):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def summary(tnc, cyc, ref, ref_samples, samples):
    """Per-file figures from lists of images (seeds) of both renderers and the reference."""
    import numpy as np
    from mcrt_addon import bench_estimators as be
    out = {}
    if tnc:
        out["mse_tncg15_seeds"] = [be.error_metrics(x, ref)["mse"] for x in tnc]
        out["mse_tncg15"] = float(np.mean(out["mse_tncg15_seeds"]))
    if cyc:
        out["mse_cycles_seeds"] = [be.error_metrics(x, ref)["mse"] for x in cyc]
        out["mse_cycles"] = float(np.mean(out["mse_cycles_seeds"]))
    for name, images in (("tncg15", tnc), ("cycles", cyc)):
        if len(images) > 1:     # the mean over pixels of the variance over seeds: MSE without the reference
            out[f"var_{name}"] = float(np.var(np.asarray(images), axis=0, ddof=1).mean())
    if len(tnc) > 1 and len(cyc) > 1:
        out["var_ratio"] = out["var_tncg15"] / out["var_cycles"]
    if tnc and cyc:
        ref_noise = out["mse_cycles"] * samples / ref_samples
        out["ratio"] = out["mse_tncg15"] / out["mse_cycles"]
        out["ratio_net"] = (out["mse_tncg15"] - ref_noise) / (out["mse_cycles"] - ref_noise)
        diff = np.mean(tnc, axis=0) - np.mean(cyc, axis=0)
        n = len(tnc)
        # standard error of the mean difference per pixel, from the seeds' spread
        var = np.var(tnc, axis=0, ddof=1) / n + np.var(cyc, axis=0, ddof=1) / len(cyc) if n > 1 else None
        out["mean_diff"] = float(diff.mean())
        out["mean_tncg15"] = float(np.mean(tnc))
        out["mean_cycles"] = float(np.mean(cyc))
        if var is not None:
            out["mean_diff_se"] = float(np.sqrt(var.sum()) / diff.size)
            # chi^2 of the per-pixel mean differences over their variance: ~1 if only noise
            ok = var > 0
            out["diff_chi2_per_pixel"] = float(np.mean(diff[ok] ** 2 / var[ok]))
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--files", nargs="+", required=True)
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4])
    p.add_argument("--samples", type=int, default=64)
    p.add_argument("--resolution", type=int, default=96)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--reference-samples", type=int, default=1024)
    p.add_argument("--cache-dir", default=os.path.join(REPO, "renders", "reference-files"))
    p.add_argument("--save", default="", help="directory for an .npz of images per file")
    p.add_argument("--load-cycles", default="", help="directory of earlier --save .npz to take Cycles' images from")
    p.add_argument("--set", nargs="*", default=[], help="NAME=VALUE TNCG15 MC settings")
    p.add_argument("--max-depth", type=int, default=None, help="both renderers' max depth (compare var_ratio: "
                   "the reference has the file's)")
    p.add_argument("--only", choices=("tncg15", "cycles"), default=None)
    p.add_argument("--tag", default="")
    args = p.parse_args(argv)
    args.cache_dir = os.path.abspath(args.cache_dir)
    overrides = {k: parse_value(v) for k, v in (s.split("=", 1) for s in args.set)}

    import numpy as np
    import bench_sample_files as bsf
    from mcrt_addon import bench_estimators as be, bridge

    print(f"mse_by_seed {time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime())} UTC, load {bsf.load_average()}, "
          f"seeds {args.seeds}, {args.samples} spp, {args.resolution}^2, set {overrides}", flush=True)
    res = args.resolution
    results = {}
    for name in args.files:
        path = bsf.sample_files([name])[0]
        label = os.path.splitext(os.path.basename(path))[0]
        ref, _ = bsf.reference(path, (res, res), args, lambda *a: None)
        scene = be.open_blend(path, (res, res))
        settings = bsf.file_settings(scene, samples=args.samples, threads=args.threads)
        if args.max_depth is not None:
            settings = dataclasses.replace(settings, max_depth=args.max_depth)
        options = bsf.cycles_options(settings)
        cyc, tnc = [], []
        t0 = time.process_time()
        old = os.path.join(args.load_cycles, f"{label}.npz") if args.load_cycles else ""
        if old and os.path.isfile(old):
            with np.load(old) as z:
                if list(z["seeds"]) == list(args.seeds):
                    cyc = list(z["cycles"])
        if args.only != "tncg15" and not cyc:
            for seed in args.seeds:
                image, _, _ = be.render_cycles(scene, samples=args.samples, max_depth=settings.max_depth,
                                               seed=seed, threads=args.threads, **options)
                cyc.append(image)
        if args.only != "cycles":
            exported = be.export_tracer_scene(scene, (res, res))
            render = bridge.render_function()
            for seed in args.seeds:
                s = dataclasses.replace(settings, seed=seed, **overrides)
                result = render(exported.scene, s, log=lambda *a, **k: None)
                tnc.append(np.nan_to_num(np.asarray(result.image, dtype=np.float64)[..., :3]))
        row = summary(tnc, cyc, ref, args.reference_samples, args.samples)
        row["cpu_seconds"] = time.process_time() - t0
        results[label] = row
        print(f"{label}: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                       for k, v in row.items() if not k.endswith("_seeds")), flush=True)
        if args.save:
            os.makedirs(args.save, exist_ok=True)
            np.savez_compressed(os.path.join(args.save, f"{label}{args.tag}.npz"), ref=ref,
                                tncg15=np.array(tnc), cycles=np.array(cyc), seeds=np.array(args.seeds))
    print(json.dumps(results, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
