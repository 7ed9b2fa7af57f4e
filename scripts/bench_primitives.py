"""Many analytic primitives against their triangle / point-light twins, timed in one run.

  python scripts/bench_primitives.py [--count N] [--resolution W H] [--samples S] [--repeats R] [--check]
  make bench-primitives

Each row renders two scenes that show the same thing, one after the other in the same process
(the machines here drift by +-20 % between runs: only ratios within one run mean anything), one
worker, best of `--repeats`:

* spheres:       N implicit spheres on a floor  /  the same balls as UV-sphere triangles;
* quads:         N analytic quads (tiles above a floor)  /  the same tiles as triangles;
* area lights:   N small Blender Area lights above a floor  /  N point lights at their centres;
* seen lamps:    N / 10 round point lights over a mirror ball  /  N / 100 of them (the seen-lamps
                 radiance that mirror rays ask for: engine/lights/seen.py).

Three times per scene: of the whole render() call (validation, preparation, BVH builds and
tracing) `cpu`, the process's CPU seconds (one worker: the tracing thread and this one; robust
to the load of other jobs on the machine), and `wall`; and `trace`, the wall time of the tracing
alone (stats["render_seconds"]).  The ratios are the first scene's over
the second's; the target is a CPU ratio <= 2 for every row (<= 1.5 for seen lamps;
docs/performance.md "Many primitives"); with --check the exit code is 1 when a row misses it.
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
from engine.scene.model import (DIFFUSE, MIRROR, AreaLight, Camera, Material, PointLight, Quad,  # noqa: E402
                                Scene, Sphere, TriangleMesh)

WHITE, MIRROR_MAT, LAMP = 0, 1, 2


def _materials():
    return [Material("White", DIFFUSE, (0.7, 0.7, 0.7)), Material("Mirror", MIRROR, (0.9, 0.9, 0.9)),
            Material("Lamp", DIFFUSE, (0.0, 0.0, 0.0), emission=(8.0, 8.0, 8.0))]


def _floor(size=1.2):
    v = np.array([(-size, -size, 0.0), (size, -size, 0.0), (size, size, 0.0), (-size, size, 0.0)])
    return TriangleMesh("Floor", v, np.array([[0, 1, 2], [0, 2, 3]]), np.array([WHITE, WHITE]))


def _scene(name, resolution, meshes=(), spheres=(), quads=(), lights=(), points=()):
    camera = Camera.look_at((0.0, -2.6, 1.9), (0.0, 0.0, 0.15), lens=35.0, name="Camera")
    return Scene(camera, _materials(), [_floor(), *meshes], list(spheres), list(quads),
                 resolution=tuple(resolution), name=name, lights=list(lights), points=list(points))


def _grid(count, extent=1.0):
    """count points on a square grid over [-extent, extent]^2 (z = 0) and the grid spacing."""
    side = int(np.ceil(np.sqrt(count)))
    step = 2.0 * extent / side
    axis = -extent + step * (np.arange(side) + 0.5)
    x, y = np.meshgrid(axis, axis, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.zeros(side * side)], axis=1)[:count], step


def uv_sphere(center, radius, rings=4, segments=5):
    """(vertices, triangles) of a UV sphere: 2 x segments x (rings - 1) triangles."""
    theta = np.pi * np.arange(1, rings) / rings
    phi = 2.0 * np.pi * np.arange(segments) / segments
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    v = np.concatenate([[(0, 0, 1)], ring, [(0, 0, -1)]]) * radius + np.asarray(center)
    idx = 1 + np.arange((rings - 1) * segments).reshape(rings - 1, segments)
    nxt = np.roll(idx, -1, axis=1)
    tris = [np.stack([np.zeros(segments, int), idx[0], nxt[0]], 1)]
    for r in range(rings - 2):
        tris += [np.stack([idx[r], idx[r + 1], nxt[r + 1]], 1), np.stack([idx[r], nxt[r + 1], nxt[r]], 1)]
    tris.append(np.stack([np.full(segments, len(v) - 1), nxt[-1], idx[-1]], 1))
    return v, np.concatenate(tris)


def _key_light():
    return [PointLight("Key", (0.5, -0.8, 2.5), (6.0, 6.0, 6.0), radius=0.1)]


def spheres_scenes(count, resolution):
    centers, step = _grid(count)
    r = 0.35 * step
    centers[:, 2] = r
    spheres = [Sphere(f"Ball {i}", tuple(c), r, WHITE) for i, c in enumerate(centers)]
    parts = [uv_sphere(c, r) for c in centers]
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    tris = np.concatenate([t + o for (_, t), o in zip(parts, offsets)])
    balls = TriangleMesh("Balls", np.concatenate([v for v, _ in parts]), tris, np.full(len(tris), WHITE))
    return (_scene("spheres", resolution, spheres=spheres, points=_key_light()),
            _scene("spheres as triangles", resolution, meshes=[balls], points=_key_light()))


def _tiles(count, z=0.3):
    centers, step = _grid(count)
    h = 0.35 * step
    corners = np.stack([centers + (-h, -h, z), centers + (h, -h, z), centers + (h, h, z), centers + (-h, h, z)],
                       axis=1)
    return corners


def quads_scenes(count, resolution):
    corners = _tiles(count)
    quads = [Quad(f"Tile {i}", c, WHITE) for i, c in enumerate(corners)]
    v = corners.reshape(-1, 3)
    q = np.arange(len(v)).reshape(-1, 4)
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    tiles = TriangleMesh("Tiles", v, tris, np.full(len(tris), WHITE))
    return (_scene("quads", resolution, quads=quads, points=_key_light()),
            _scene("quads as triangles", resolution, meshes=[tiles], points=_key_light()))


def area_light_scenes(count, resolution):
    corners = _tiles(count, z=1.2)
    corners = corners[:, ::-1]                               # facing down
    size = np.abs(corners[0, 0] - corners[0, 2]).max()
    radiance = 4.0 / (count * size * size)
    lights = [AreaLight(f"Area {i}", c, (radiance,) * 3) for i, c in enumerate(corners)]
    intensity = radiance * size * size / np.pi                # the same flux below, roughly
    points = [PointLight(f"Point {i}", tuple(c.mean(axis=0)), (intensity,) * 3) for i, c in enumerate(corners)]
    ball = [Sphere("Ball", (0.0, 0.0, 0.3), 0.3, WHITE)]
    return (_scene("area lights", resolution, spheres=ball, lights=lights),
            _scene("point lights", resolution, spheres=ball, points=points))


def seen_lamp_scenes(count, resolution):
    count = max(1, count // 10)
    def bulbs(n):
        centers, step = _grid(n, extent=1.0)
        centers[:, 2] = 1.4
        return [PointLight(f"Bulb {i}", tuple(c), (20.0 / n,) * 3, radius=0.2 * step) for i, c in enumerate(centers)]
    ball = [Sphere("Mirror ball", (0.0, 0.0, 0.5), 0.5, MIRROR_MAT)]
    few = max(1, count // 10)
    return (_scene(f"{count} round lamps", resolution, spheres=ball, points=bulbs(count)),
            _scene(f"{few} round lamps", resolution, spheres=ball, points=bulbs(few)))


TARGET = {"seen lamps": 1.5}          # CPU ratio; 2 for the other rows
ROWS = {"spheres": spheres_scenes, "quads": quads_scenes, "area lights": area_light_scenes,
        "seen lamps": seen_lamp_scenes}


def timed(scene, samples, repeats):
    """Best (CPU, wall, trace) seconds of `repeats` one-worker renders (trace: the tracing's wall
    time alone, stats["render_seconds"])."""
    cpu, wall, trace = np.inf, np.inf, np.inf
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        stats = render(scene, RenderSettings(samples=samples, threads=1), log=lambda *a: None).stats
        cpu, wall = min(cpu, time.process_time() - start_cpu), min(wall, time.perf_counter() - start)
        trace = min(trace, stats["render_seconds"])
    return cpu, wall, trace


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=10_000)
    parser.add_argument("--resolution", type=int, nargs=2, default=(128, 128))
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--only", action="append", choices=sorted(ROWS), help="rows to run (repeatable)")
    parser.add_argument("--check", action="store_true", help="exit code 1 when a row misses its target")
    args = parser.parse_args(argv)
    print(f"bench-primitives: {args.count} primitives, {args.resolution[0]}x{args.resolution[1]}, "
          f"{args.samples} spp, 1 worker, best of {args.repeats}; load {os.getloadavg()[0]:.1f}")
    timed(_scene("warm-up", (16, 16), spheres=[Sphere("b", (0, 0, 0.3), 0.3, WHITE)], points=_key_light()), 1, 1)
    print(f"{'row':12s} {'scene':>22s} {'cpu':>6s} {'wall':>6s} {'trace':>6s}   {'against':>22s} {'cpu':>6s} "
          f"{'wall':>6s} {'trace':>6s}   ratio cpu, wall, trace")
    missed = []
    for name in args.only or ROWS:
        first, second = ROWS[name](args.count, args.resolution)
        a = timed(first, args.samples, args.repeats)
        b = timed(second, args.samples, args.repeats)
        if a[0] / b[0] > TARGET.get(name, 2.0):    # on CPU seconds
            missed.append(name)
        print(f"{name:12s} {first.name:>22s} {a[0]:6.2f} {a[1]:6.2f} {a[2]:6.2f}   {second.name:>22s} {b[0]:6.2f} "
              f"{b[1]:6.2f} {b[2]:6.2f}   {a[0] / b[0]:5.2f}, {a[1] / b[1]:5.2f}, {a[2] / b[2]:5.2f}", flush=True)
    if missed:
        print("missed the target: " + ", ".join(missed))
    return 1 if missed and args.check else 0


if __name__ == "__main__":
    sys.exit(main())
