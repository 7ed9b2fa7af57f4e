"""Benchmarks of the stopping rules (figures, not timed tests; docs/performance.md, docs/accuracy.md).

  .venv/bin/python scripts/bench_stopping.py [--time-limits 2 5 10] [--estimate-scenes cornell near_lamp caustic]
                                             [--blends cornell caustic ...] [--blend-target 0.05]

* Time limit: the built-in Cornell box at 256x256 with a sample cap it never reaches and
  --time-limit T: render seconds and the overshoot past T (target: T + 0.5 s).
* Estimate: `estimate` (the pilot) against the real render to the same noise target on the
  built-in scenes: predicted and real render seconds and mean samples (target: within +-30 %).
* The same on the sample .blend files through the add-on's command line (`--blends cornell
  caustic ...`): `python -m mcrt_addon estimate --json` against `python -m mcrt_addon render`.
The load average is printed with the figures: on a shared machine they are noisy.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine.scene.builtin import BUILTIN_SCENES  # noqa: E402
from engine.rendering.estimate import estimate  # noqa: E402
from engine.api import render  # noqa: E402
from engine.core.settings import RenderSettings  # noqa: E402

QUIET = dict(log=lambda *a: None)
TARGETS = {"cornell": 0.05, "near_lamp": 0.03, "caustic": 0.12}


def load():
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def scene(name, size):
    s = BUILTIN_SCENES[name]()
    s.resolution = (size, size)
    return s


def bench_time_limit(limits):
    print(f"time limit, cornell 256x256, cap 65536 spp (load {load()})")
    print("| limit | render s | overshoot s | wall s | mean spp |")
    print("|---:|---:|---:|---:|---:|")
    for t in limits:
        w0 = time.perf_counter()
        r = render(scene("cornell", 256), RenderSettings(samples=1 << 16, time_limit=t), **QUIET)
        wall = time.perf_counter() - w0
        st = r.stats
        print(f"| {t:g} | {st['render_seconds']:.2f} | {st['render_seconds'] - t:+.2f} | {wall:.2f} | "
              f"{st['samples_per_pixel']['mean']:.1f} |", flush=True)


def bench_estimate(names, size):
    print(f"\nestimate vs real render, {size}x{size}, cap 8192 spp, adaptive (load {load()})")
    print("| scene | target | predicted s | real s | ratio | predicted spp | real spp | real error | load |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for name in names:
        target = TARGETS[name]
        settings = RenderSettings(samples=8192, noise_target=target)
        e = estimate(scene(name, size), settings, target, render, **QUIET)
        r = render(scene(name, size), settings, **QUIET)
        st = r.stats
        print(f"| {name} | {target} | {e['seconds']:.2f} | {st['render_seconds']:.2f} | "
              f"{e['seconds'] / st['render_seconds']:.2f} | {e['mean_samples']:.0f} | "
              f"{st['samples_per_pixel']['mean']:.0f} | {st['estimated_rel_error'] * 100:.2f} % | {load()} |", flush=True)


def bench_blends(names, size, target):
    """Estimate against the real render on sample_blends/NAME.blend, both through the add-on's CLI."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    print(f"\nestimate vs real render on the sample .blend files, {size}x{size}, target {target}, cap 8192 spp, "
          f"adaptive (load {load()})")
    print("| file | predicted s | real s | ratio | predicted spp | real spp | real error | load |")
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    common = ["--noise-target", str(target), "--samples", "8192", "--resolution", str(size), str(size)]
    for name in names:
        blend = os.path.join(root, "sample_blends", f"{name}.blend")
        e = subprocess.run([sys.executable, "-m", "mcrt_addon", "estimate", blend, *common, "--json"], cwd=root,
                           capture_output=True, text=True)
        if e.returncode != 0:
            print(f"| {name} | estimate failed: {e.stderr.strip().splitlines()[-1:]} |")
            continue
        pred = json.loads(e.stdout.strip().splitlines()[-1])
        with tempfile.TemporaryDirectory() as tmp:
            r = subprocess.run([sys.executable, "-m", "mcrt_addon", "render", blend, *common, "-o",
                                os.path.join(tmp, "o.exr"), "--stats-json", os.path.join(tmp, "s.json")],
                               cwd=root, capture_output=True, text=True)
            if r.returncode != 0:
                print(f"| {name} | render failed: {r.stderr.strip().splitlines()[-1:]} |")
                continue
            with open(os.path.join(tmp, "s.json")) as fh:
                st = json.load(fh)
        print(f"| {name} | {pred['seconds']:.2f} | {st['render_seconds']:.2f} | "
              f"{pred['seconds'] / st['render_seconds']:.2f} | {pred['mean_samples']:.0f} | "
              f"{st['samples_per_pixel']['mean']:.0f} | {st['estimated_rel_error'] * 100:.2f} % | {load()} |", flush=True)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--time-limits", type=float, nargs="*", default=[2.0, 5.0, 10.0])
    p.add_argument("--estimate-scenes", nargs="*", default=list(TARGETS))
    p.add_argument("--size", type=int, default=96)
    p.add_argument("--blends", nargs="*", default=[], help="sample_blends/NAME.blend files to check the estimate on")
    p.add_argument("--blend-target", type=float, default=0.05)
    args = p.parse_args()
    if args.time_limits:
        bench_time_limit(args.time_limits)
    if args.estimate_scenes:
        bench_estimate(args.estimate_scenes, args.size)
    if args.blends:
        bench_blends(args.blends, args.size, args.blend_target)


if __name__ == "__main__":
    main()
