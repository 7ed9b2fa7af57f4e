"""Render a scene: tiles over worker threads or processes, progress, cancel, stats.

Each tile draws its random numbers from its own generator seeded by (seed, tile),
so the image for a given seed is identical whatever the number or kind of workers
(engine/workers.py).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .accel import choose_accelerator
from .allocator import tune_malloc
from .camera import TileSamples
from .effects import plan_effects
from .film import TileFilm
from .geometry import Counters, SceneGeometry
from .integrator import PathTracer
from .lights import LightSampler
from .qmc import RandomSampler, SobolSampler
from .settings import RenderSettings
from .workers import choose_parallelism, make_workers

ENGINE_NAME = "TNCG15 MC"


@dataclass
class Tile:
    index: int
    x0: int
    y0: int
    x1: int
    y1: int


@dataclass
class RenderResult:
    image: np.ndarray
    variance: np.ndarray
    stats: dict
    warnings: list = field(default_factory=list)
    cancelled: bool = False


MIN_TILES = 4          # so that both cores of a small frame have work (one 64-px tile would idle one)


def tile_size_for(width: int, height: int, size: int) -> int:
    """The tile edge used: `size`, halved (not below 16) until the frame has MIN_TILES tiles.
    It depends on the frame only, never on the thread count, so images stay identical
    whatever the number of workers."""
    while size > 16 and -(-width // size) * -(-height // size) < MIN_TILES:
        size = max(16, size // 2)
    return size


def make_tiles(width: int, height: int, size: int) -> list[Tile]:
    tiles = []
    for y0 in range(0, height, size):
        for x0 in range(0, width, size):
            tiles.append(Tile(len(tiles), x0, y0, min(x0 + size, width), min(y0 + size, height)))
    return tiles


class Renderer:
    """Scene preparation (BVH, lights, effect plan) separated from tracing."""

    def __init__(self, scene, settings: RenderSettings, log=print):
        settings.validate()
        self.warnings = scene.validate()
        self.scene = scene
        self.settings = settings
        n_tri = sum(len(m.triangles) for m in scene.meshes)
        self.accelerator, self.accelerator_reason = choose_accelerator(settings.accelerator, n_tri)
        self.plan = plan_effects(scene, settings, self.accelerator)
        if scene.lights and not self.plan.area_lights and settings.shadow_rays == 0:
            self.warnings.append(f"{len(scene.lights)} area light(s) are reached by shadow rays only here: "
                                 "with 0 shadow rays they light nothing")
        for w in self.warnings:
            log(f"warning: {w}")
        self.geometry = SceneGeometry(scene, self.accelerator, self.plan)
        self.lights = LightSampler(scene, solid_angle=self.plan.solid_angle, spatial=self.plan.light_tree,
                                   lamps_hittable=self.plan.area_lights)
        self.plan.describe_light_kinds(self.lights)
        self.tracer = PathTracer(self.geometry, self.lights, scene.materials, self.plan,
                                 settings, scene.background)

    def render_tile(self, tile: Tile, cancel, counters: Counters) -> TileFilm:
        """Render one tile; `cancel` is any event with is_set() (thread or process)."""
        s = self.settings
        width, height = self.scene.resolution
        film = TileFilm(tile.x1 - tile.x0, tile.y1 - tile.y0)
        rng = np.random.default_rng([s.seed, tile.index])
        sampler = (SobolSampler(s.seed, tile.x0, tile.y0, tile.x1, tile.y1, s.samples, s.shadow_rays)
                   if s.sampler == "sobol"
                   else RandomSampler(rng))
        samples = TileSamples(self.scene.camera, width, height, tile.x0, tile.y0, tile.x1, tile.y1,
                              s.samples, sampler)

        def finished(pixel, radiance):
            bad = ~np.isfinite(radiance).all(axis=0)
            if bad.any():
                # Counted before the guard, never hidden silently.
                counters.nonfinite_samples += int(bad.sum())
                radiance[:, bad] = 0.0
            film.add(pixel, radiance)

        self.tracer.trace(samples, rng, counters, finished, cancel, sampler)
        return film


def render(scene, settings: RenderSettings | None = None, on_tile=None, should_cancel=None,
           on_progress=None, log=print) -> RenderResult:
    """Render `scene`; see module docstring.  Callbacks run on the calling thread.

    on_tile(x0, y0, x1, y1, pixels) with pixels (y1-y0, x1-x0, 3) float32, rows from the top.
    should_cancel() -> bool is polled about every 0.1 s.  on_progress(fraction, message).
    """
    settings = settings or RenderSettings()
    tune_malloc()                      # keep the bounce temporaries off mmap (engine/allocator.py)
    setup_start = time.perf_counter()
    renderer = Renderer(scene, settings, log=log)
    setup_seconds = time.perf_counter() - setup_start
    width, height = scene.resolution
    tile_size = tile_size_for(width, height, settings.tile_size)
    tiles = make_tiles(width, height, tile_size)
    threads = settings.resolved_threads()
    log(f"{ENGINE_NAME}: {width}x{height}, {settings.samples} spp, {settings.shadow_rays} shadow ray(s), "
        f"estimator {settings.estimator}, "
        f"max depth {settings.max_depth}, {threads} thread(s), accelerator {renderer.accelerator} "
        f"({renderer.accelerator_reason})")
    log("effect plan:\n" + renderer.plan.describe())

    image = np.zeros((height, width, 3), dtype=np.float32)
    variance = np.zeros((height, width, 3), dtype=np.float32)
    totals = Counters()
    parallelism = choose_parallelism(settings.parallelism, threads) if threads > 1 else "threads"
    cancelled = False
    start = time.perf_counter()
    workers = make_workers(parallelism, renderer, threads)
    done_tiles = 0
    error = None
    try:
        workers.start(tiles)
        while done_tiles < len(tiles):
            result = workers.next_result(timeout=0.1)
            if should_cancel is not None and not cancelled and should_cancel():
                cancelled = True
                workers.cancel()
            if result is None:
                continue
            tile, film, counters, exc = result
            done_tiles += 1
            totals.merge(counters)
            if exc is not None:
                error = error or exc
                workers.cancel()
                continue
            pixels = film.mean().astype(np.float32)
            image[tile.y0:tile.y1, tile.x0:tile.x1] = pixels
            variance[tile.y0:tile.y1, tile.x0:tile.x1] = film.variance_of_mean()
            if on_tile is not None and film.count.any():
                on_tile(tile.x0, tile.y0, tile.x1, tile.y1, pixels)
            if on_progress is not None:
                elapsed = max(time.perf_counter() - start, 1e-9)
                rate = sum(totals.rays.values()) / elapsed / 1e6
                on_progress(done_tiles / len(tiles), f"tile {done_tiles}/{len(tiles)} · {rate:.2f} M rays/s · "
                                                     f"effects: {renderer.plan.summary()}")
    finally:
        workers.close()
    if error is not None:
        raise error
    seconds = time.perf_counter() - start
    rays = dict(totals.rays)
    total_rays = sum(rays.values())
    stats = {
        "engine": ENGINE_NAME,
        "render_seconds": seconds,
        "setup_seconds": setup_seconds,
        "build_seconds": renderer.geometry.build_seconds,
        "samples": settings.samples,
        "shadow_rays": settings.shadow_rays,
        "max_depth": settings.max_depth,
        "russian_roulette": settings.russian_roulette,
        "fresnel": settings.fresnel,
        "estimator": settings.estimator,
        "sampler": settings.sampler,
        "seed": settings.seed,
        "resolution": [width, height],
        "threads": threads,
        "tile_size": tile_size,
        "accelerator": renderer.accelerator,
        "accelerator_reason": renderer.accelerator_reason,
        "rays": rays,
        "rays_per_second": total_rays / seconds if seconds > 0 else 0.0,
        "effects": dict(renderer.plan.enabled),
        "effects_reason": dict(renderer.plan.reason),
        "nonfinite_samples": totals.nonfinite_samples,
        "seconds_in_intersection": totals.seconds_in_intersection,
        "seconds_in_accelerator": totals.seconds_in_accelerator,
        "cancelled": cancelled,
        "parallelism": parallelism,
        "warnings": list(renderer.warnings),
    }
    return RenderResult(image, variance, stats, list(renderer.warnings), cancelled)
