"""Prints (does not assert) how TNCG15 MC agrees with Cycles on .blend files that other people made
(docs/materials.md "Files made by others"): every .blend of a directory, rendered by Cycles 5.0
(the reference, many samples, cached) and by TNCG15 MC (two seeds), both at the fair settings of
mcrt_addon/bench_estimators.py (no clamp, no glossy filter, the same max depth).

  .venv/bin/python scripts/agree_real_files.py DIR [--width 96] [--samples 256]
         [--reference-samples 2048] [--max-depth 12] [--cache-dir renders/reference-files]

Per file: the exporter's warnings, the image mean against Cycles', the 8x8-block relative
differences (median, 95th percentile), and the verdict.  A block is off when its difference from
Cycles exceeds 4 standard deviations of the noise (TNCG15's, from its two seeds' pixel differences,
plus the reference's, scaled from it by the sample counts) and 2 % of the image mean; a file agrees
when the image mean is within 2 % (or 4 sigma) and at most 2 % of the blocks are off.
"""
import argparse
import glob
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from mcrt_addon import bench_estimators as be  # noqa: E402

BLOCK = 8


def blocks(image):
    """Mean of each 8x8 block of the channel mean, and its pixels (blocks, 64)."""
    h, w = image.shape[0] // BLOCK * BLOCK, image.shape[1] // BLOCK * BLOCK
    a = image[:h, :w, :3].mean(axis=2).reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).swapaxes(1, 2)
    return a.mean(axis=(2, 3)), a.reshape(h // BLOCK, w // BLOCK, BLOCK * BLOCK)


def compare(runs, reference, samples, reference_samples):
    """Image mean ratio, block differences and the verdict.  The noise of a block's two-seed mean
    comes from its 64 pixel differences between the seeds (63 degrees of freedom, not the 1 of two
    block means): var(mean of a, b) = var(a_i - b_i) / 64 / 4 (pixels taken as independent)."""
    a, b = (np.asarray(r, dtype=np.float64) for r in runs)
    mean = 0.5 * (a + b)
    bm, _ = blocks(mean)
    br, _ = blocks(reference)
    _, pixel_diff = blocks(a - b)
    var_mean = pixel_diff.var(axis=2, ddof=1) / pixel_diff.shape[2] / 4.0
    var_ref = var_mean * 2 * samples / reference_samples
    level = max(float(reference.mean()), 1e-6)
    off = np.abs(bm - br) > np.maximum(4.0 * np.sqrt(var_mean + var_ref), 0.02 * level)
    img_t, img_r = float(mean.mean()), float(reference.mean())
    d = (a - b)[..., :3].mean(axis=2)
    img_sigma = float(np.sqrt(d.var(ddof=1) / d.size / 4.0 * (1 + 2 * samples / reference_samples)))
    mean_ok = abs(img_t - img_r) <= max(0.02 * img_r, 4.0 * img_sigma)
    rel = np.abs(bm - br) / np.maximum(br, 0.05 * level)
    return dict(mean_ratio=img_t / max(img_r, 1e-12), block_median=float(np.median(rel)),
                block_p95=float(np.percentile(rel, 95)), off_fraction=float(off.mean()),
                agrees=bool(mean_ok and off.mean() <= 0.02))


def replace_missing_images(path) -> int:
    """Every image of the open file whose file is missing or unreadable is given `path`; returns how many."""
    import bpy
    if not path:
        return 0
    n = 0
    for image in bpy.data.images:
        if image.source == "FILE" and image.packed_file is None and (
                not os.path.isfile(bpy.path.abspath(image.filepath, library=image.library))
                or tuple(image.size) == (0, 0)):          # there but unreadable (e.g. a Git LFS pointer)
            image.filepath = os.path.abspath(path)
            image.reload()
            n += 1
    return n


def with_missing_images_replaced(blend, path, cache_dir):
    """A copy of `blend` (saved beside the cache, relative paths kept absolute) whose missing images
    are `path`, so that Cycles' reference sees what the tracer sees: (the file to render, how many
    images were replaced)."""
    import bpy
    if not path:
        return blend, 0
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend), load_ui=False)
    bpy.ops.file.make_paths_absolute()
    n = replace_missing_images(path)
    if not n:
        return blend, 0
    os.makedirs(cache_dir, exist_ok=True)
    out = os.path.join(os.path.abspath(cache_dir), "with-image-" + os.path.basename(blend))
    bpy.ops.wm.save_as_mainfile(filepath=out, copy=True)
    return out, n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("directory")
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--reference-samples", type=int, default=2048)
    ap.add_argument("--max-depth", type=int, default=12)
    ap.add_argument("--only", nargs="*", help="file names (without .blend) of DIR to compare")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--cache-dir", default=os.path.join("renders", "reference-files"))
    ap.add_argument("--images", default=None, help="write TNCG15 / Cycles PNGs side by side here")
    ap.add_argument("--missing-image", default=None,
                    help="an image file put in place of every image file a .blend lacks (both renderers see it; "
                         "Cycles renders a missing image magenta, TNCG15 MC warns and uses the unlinked value)")
    args = ap.parse_args()
    import bpy
    files = sorted(glob.glob(os.path.join(args.directory, "*.blend")))
    if args.only:
        files = [f for f in files if os.path.splitext(os.path.basename(f))[0] in args.only]
    print(f"{len(files)} files, {args.width} px wide, TNCG15 MC {args.samples} spp x 2 seeds, "
          f"Cycles {args.reference_samples} spp, max depth {args.max_depth}, fair settings")
    print("| file | warnings | mean / Cycles | block median | block p95 | blocks off | agrees |")
    print("|---|---|---|---|---|---|---|")
    agree = 0
    for blend in files:
        label = os.path.splitext(os.path.basename(blend))[0]
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend), load_ui=False)
        r = bpy.context.scene.render
        aspect = (r.resolution_y * r.pixel_aspect_y) / max(r.resolution_x * r.pixel_aspect_x, 1)
        res = (args.width, max(8, int(round(args.width * aspect))))
        with open(blend, "rb") as fh:
            identity = be._sha1(fh.read())
        blend, replaced = with_missing_images_replaced(blend, args.missing_image, args.cache_dir)
        if replaced:                    # the reference of the file with the replacement image
            identity += f":{replaced} x {os.path.basename(args.missing_image)}"
        reference, _ = be.reference_image(label, blend, identity, cache_dir=args.cache_dir, resolution=res,
                                          samples=args.reference_samples, max_depth=args.max_depth,
                                          log=lambda *a: None)
        scene = be.open_blend(blend, res)
        exported = be.export_tracer_scene(scene, res)
        warnings = [f"{n} missing image file(s) replaced by {args.missing_image}" for n in [replaced] if n] + \
            list(exported.warnings)
        runs = [be.render_tncg15(exported.scene, samples=args.samples, max_depth=args.max_depth, seed=s,
                                 threads=args.threads, estimator="mis")[0] for s in (1, 2)]
        m = compare(runs, reference, args.samples, args.reference_samples)
        agree += m["agrees"]
        print(f"| {label} | {len(warnings)} | {m['mean_ratio']:.3f} | {m['block_median']:.3f} | "
              f"{m['block_p95']:.3f} | {m['off_fraction'] * 100:.1f} % | {'yes' if m['agrees'] else 'no'} |",
              flush=True)
        for w in warnings[:4]:
            print(f"|   | {w[:150]} |||||")
        if args.images:
            os.makedirs(args.images, exist_ok=True)
            side = np.concatenate([0.5 * (runs[0] + runs[1]), reference[..., :3]], axis=1)
            be.write_png(os.path.join(args.images, f"{label}.png"), side)
    print(f"{agree} of {len(files)} agree")


if __name__ == "__main__":
    main()
