"""Caustics by the photon map against path tracing (`mis`) at equal time, in one run.

  python scripts/bench_caustics.py [--resolution N] [--seconds T] [--reference-spp S] [--photons P] [--radius R]
  make bench-caustics

The caustic room of engine/scene/builtin.py (a glass ball on a diffuse floor under a small lamp)
at N x N: a converged reference by path tracing alone (S samples per pixel, cached in
renders/reference/), then `caustics_method path` and `caustics_method photons` with the same time
limit T, each as the tracer renders by default (2 local workers).  Printed: relMSE
(mean (x - ref)^2 / (ref^2 + 0.01)) over the whole image and inside the caustic region (the pixels
where the reference with Cycles' refractive caustics on exceeds the one with them off by 10 %),
less the reference's own noise (estimated from two independent references),
and the ratios path / photons (targets: >= 10 inside the caustic, >= 3 over the image; the machine's
load drifts between runs, only the ratios of one run mean anything).
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--photons", type=int, default=RenderSettings().photons_per_pass)
    ap.add_argument("--radius", type=float, default=0.0, help="the photon map's first radius (0: auto)")
    args = ap.parse_args(argv)
    scene = caustic_scene((args.resolution, args.resolution))
    # Two independent references: their mean is the reference, their difference its noise.
    a, b = (reference(scene, args.reference_spp, "full", seed, caustics_method="path") for seed in (99, 98))
    ref, noise = 0.5 * (a + b), 0.25 * (a - b) ** 2
    no_caustics = reference(scene, max(args.reference_spp // 8, 64), "no_refractive_caustics",
                            caustics_method="path", caustics_refractive=False)
    region = ref.mean(axis=2) > 1.1 * no_caustics.mean(axis=2)
    print(f"caustic room {args.resolution}x{args.resolution}, {args.seconds:g} s each; caustic region "
          f"{int(region.sum())} pixels; the reference's own relMSE (subtracted): image {rel_mse(ref, ref, None, -noise):.2e}, "
          f"caustic {rel_mse(ref, ref, region, -noise):.2e}")
    rows = {}
    for method in ("path", "photons"):
        s = RenderSettings(samples=1 << 20, time_limit=args.seconds, caustics_method=method, seed=1,
                           photons_per_pass=args.photons, photon_radius=args.radius)
        r = render(scene, s)
        spp = r.stats["samples_per_pixel"]["mean"]
        rows[method] = (rel_mse(r.image, ref, noise=noise), rel_mse(r.image, ref, region, noise))
        extra = ""
        if "photons" in r.stats:
            ph = r.stats["photons"]
            extra = (f"; photon passes {ph['photon_passes']}, traced {ph['photons_traced']}, stored {ph['photons_stored']}, "
                     f"radius {ph['radius_first']:.4g} -> {ph['radius_last']:.4g}, trace {ph['trace_seconds']:.1f} s, "
                     f"gather {ph['gather_seconds']:.1f} s (worker seconds)")
        print(f"  {method:8s} {r.stats['render_seconds']:5.1f} s, {spp:7.1f} spp: relMSE image {rows[method][0]:.3e}, "
              f"caustic {rows[method][1]:.3e}{extra}")
    whole, caustic = (rows["path"][i] / rows["photons"][i] for i in range(2))
    print(f"relMSE path / photons: caustic region {caustic:.1f}x (target >= 10), whole image {whole:.1f}x "
          f"(target >= 3)")


if __name__ == "__main__":
    main()
