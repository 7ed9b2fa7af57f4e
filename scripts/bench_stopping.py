"""Benchmarks of the stopping rules (figures, not timed tests; README: Stopping rules).

  .venv/bin/python scripts/bench_stopping.py [--time-limits 2 5 10] [--estimate-scenes cornell near_lamp caustic]

* Time limit: the built-in Cornell box at 256x256 with a sample cap it never reaches and
  --time-limit T: render seconds and the overshoot past T (target: T + 0.5 s).
* Estimate: `estimate` (64-spp pilot) against the real render to the same noise target on the
  built-in scenes: predicted and real render seconds and mean samples (target: within +-30 %).
The load average is printed with the figures: on a shared machine they are noisy.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine.default_scene import BUILTIN_SCENES  # noqa: E402
from engine.estimate import estimate  # noqa: E402
from engine.render import render  # noqa: E402
from engine.settings import RenderSettings  # noqa: E402

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


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--time-limits", type=float, nargs="*", default=[2.0, 5.0, 10.0])
    p.add_argument("--estimate-scenes", nargs="*", default=list(TARGETS))
    p.add_argument("--size", type=int, default=96)
    args = p.parse_args()
    if args.time_limits:
        bench_time_limit(args.time_limits)
    if args.estimate_scenes:
        bench_estimate(args.estimate_scenes, args.size)


if __name__ == "__main__":
    main()
