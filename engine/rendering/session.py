"""A render session: a scene prepared once, rendered as work units, merged into one film.

One object that every driver uses: the command line, the Blender add-on, the local worker pool
(engine/pools/local.py) and a Dask cluster (engine/pools/dask_cluster.py):

    session = RenderSession(scene, settings)      # validate, effect plan, BVH, lights: once
    for unit in session.units:                    # (tile, sample range): anywhere, any order
        result = session.render_unit(unit, cancel)
        session.film.add(result)                  # merged per tile in sample order
    session.result()                              # image, variance, stats

A work unit is a tile and a range of sample numbers.  Every random number is a function of
(seed, pixel, sample number, dimension) with the Sobol' sampler (engine/sampling/qmc.py), or of (seed,
unit) with independent random numbers, so a unit renders the same wherever and however often it
runs; the film adds each tile's units in sample order, so the image is the same bit for bit
whatever the number and kind of workers, the order units finish in, and retries after failures.
A unit that is cancelled returns None and is dropped whole: the film keeps the finished ones
(unbiased means over fewer samples), so Esc takes effect within a bounce.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry.accel import choose_accelerator
from ..scene.camera_rays import TileSamples
from ..integrators.effects import plan_effects
from ..film.tile_film import TileFilm
from ..geometry.scene_geometry import Counters, SceneGeometry
from ..integrators.path_tracer import PathTracer
from ..lights import LightSet
from .masked_samples import MaskedTileSamples, unpack_mask
from ..film.passes import FrameFeatures, TileFeatures, pass_images, traced
from ..sampling.qmc import RandomSampler, SobolSampler
from ..core.settings import RenderSettings
from ..materials.textures import load_textures
from ..core.version import ENGINE_NAME, ENGINE_VERSION
from .units import Tile, WorkUnit, await_units, make_tiles, make_units, tile_size_for

DEFAULT_TARGET = 0.01            # the error seconds_to_target aims at without a noise target


@dataclass
class UnitResult:
    unit: WorkUnit
    sum: np.ndarray              # (pixels, 3) radiance sums
    sum_sq: np.ndarray           # (pixels, 3) sums of squares
    count: np.ndarray            # (pixels,) samples
    counters: Counters
    seconds: float
    engine_version: str = ENGINE_VERSION
    sum_a: np.ndarray | None = None      # half buffer A (unit.halves): sums and counts of [start, mid)
    count_a: np.ndarray | None = None
    features: dict | None = None # engine/film/passes.py TileFeatures.sums(), when a traced pass is on


@dataclass
class RenderResult:
    image: np.ndarray
    variance: np.ndarray
    stats: dict
    warnings: list = field(default_factory=list)
    cancelled: bool = False
    passes: dict = field(default_factory=dict)    # engine/film/passes.py pass_images(): name -> (H, W, C)
    film: "SessionFilm | None" = None     # sums, half buffers, samples per pixel (engine/rendering/estimate.py)


class SessionFilm:
    """The frame's sums, merged from unit results: each tile's units in chunk order (results
    that arrive early wait), so floating-point sums never depend on arrival order."""

    def __init__(self, width: int, height: int, units):
        self.width, self.height = width, height
        self.sum = np.zeros((height, width, 3))
        self.sum_sq = np.zeros((height, width, 3))
        self.count = np.zeros((height, width))
        # Half buffer A of the stopping rules' passes (engine/film/error_estimate.py); B = total - A.
        self.sum_a = np.zeros((height, width, 3))
        self.count_a = np.zeros((height, width))
        self.next_chunk = {}                    # tile index -> next chunk to add
        self.pending = {}                       # (tile index, chunk) -> UnitResult
        self.units_total = len(units)
        self.units_added = 0
        self.features = None                    # FrameFeatures when a traced pass is on

    def add(self, result: UnitResult) -> list[Tile]:
        """Merge a unit's result; returns the tiles whose pixels changed."""
        unit = result.unit
        self.pending[(unit.tile.index, unit.chunk)] = result
        changed = []
        key = (unit.tile.index, self.next_chunk.get(unit.tile.index, 0))
        while key in self.pending:
            t = self._merge(self.pending.pop(key))
            key = (t.index, key[1] + 1)
            changed = [t]
        return changed

    def flush(self) -> list[Tile]:
        """Merge the results still waiting for an earlier chunk of their tile that will not come
        (a cancelled render: the work finished is kept, in chunk order); the tiles changed."""
        changed = {}
        for key in sorted(self.pending):
            t = self._merge(self.pending.pop(key))
            changed[t.index] = t
        return list(changed.values())

    def _merge(self, r: UnitResult) -> Tile:
        t = r.unit.tile
        h, w = t.y1 - t.y0, t.x1 - t.x0
        self.sum[t.y0:t.y1, t.x0:t.x1] += r.sum.reshape(h, w, 3)
        self.sum_sq[t.y0:t.y1, t.x0:t.x1] += r.sum_sq.reshape(h, w, 3)
        self.count[t.y0:t.y1, t.x0:t.x1] += r.count.reshape(h, w)
        if r.sum_a is not None:
            self.sum_a[t.y0:t.y1, t.x0:t.x1] += r.sum_a.reshape(h, w, 3)
            self.count_a[t.y0:t.y1, t.x0:t.x1] += r.count_a.reshape(h, w)
        if self.features is not None and r.features is not None:
            self.features.add(t, r.features)
        self.units_added += 1
        self.next_chunk[t.index] = max(self.next_chunk.get(t.index, 0), r.unit.chunk + 1)
        return t

    def mean(self, tile: Tile | None = None) -> np.ndarray:
        s = (slice(None), slice(None)) if tile is None else (slice(tile.y0, tile.y1), slice(tile.x0, tile.x1))
        with np.errstate(invalid="ignore", divide="ignore"):
            m = self.sum[s] / self.count[s][..., None]
        return np.nan_to_num(m).astype(np.float32)

    def variance_of_mean(self) -> np.ndarray:
        """Per-pixel variance of the pixel estimate (sample variance / n)."""
        n = np.maximum(self.count, 2)[..., None]
        mean = self.sum / n
        return (np.maximum(self.sum_sq / n - mean * mean, 0.0) / (n - 1)).astype(np.float32)

    @property
    def samples_per_pixel(self) -> np.ndarray:
        """(H, W) camera samples each pixel got (they differ under adaptive sampling)."""
        return self.count

    def half_buffer_variance(self) -> np.ndarray:
        """(H, W, 3) variance of each pixel mean from the half buffers (engine/film/error_estimate.py);
        where a pixel has no two halves (renders without stopping rules), the sample variance."""
        from ..film.error_estimate import half_buffer_variance
        var = half_buffer_variance(self.sum, self.count, self.sum_a, self.count_a)
        missing = np.isnan(var)
        if missing.any():
            var[missing] = self.variance_of_mean()[missing]
        return var

    def estimated_rel_error(self) -> float:
        """The image's estimated relative error E (README: Stopping rules)."""
        from ..film.error_estimate import image_rel_error
        return image_rel_error(self.mean().astype(np.float64), self.half_buffer_variance())


class RenderSession:
    """Scene preparation (validation, effect plan, BVH, lights) once; units rendered on demand."""

    def __init__(self, scene, settings: RenderSettings | None = None, log=print, progressive: str = "tiles"):
        settings = settings or RenderSettings()
        settings.validate()
        start = time.perf_counter()
        self.warnings = scene.validate()
        self.scene, self.settings = scene, settings
        n_tri = sum(len(m.triangles) for m in scene.meshes)
        self.accelerator, self.accelerator_reason = choose_accelerator(settings.accelerator, n_tri)
        self.plan = plan_effects(scene, settings, self.accelerator)
        if scene.lights and not self.plan.area_lights and settings.shadow_rays == 0:
            self.warnings.append(f"{len(scene.lights)} area light(s) are reached by shadow rays only here: "
                                 "with 0 shadow rays they light nothing")
        for w in self.warnings:
            log(f"warning: {w}")
        self.geometry = SceneGeometry(scene, self.accelerator, self.plan)
        textures, lit = load_textures(scene, self.plan, log, self.warnings)    # engine/materials/textures.py
        self.lights = LightSet(lit, solid_angle=self.plan.solid_angle, spatial=self.plan.light_tree,
                               lamps_hittable=self.plan.area_lights, world=self.plan.world_light)
        self.plan.describe_light_kinds(self.lights)
        self.tracer = PathTracer(self.geometry, self.lights, lit.materials, self.plan, settings,
                                 scene.background, textures=textures and textures.bind(self.geometry, self.lights))
        self.cut_frame(progressive)
        self.setup_seconds = time.perf_counter() - start

    def cut_frame(self, progressive: str) -> None:
        """Tiles, work units, an empty film and counters: the same on every machine for the same
        scene and settings (a unit is found by its index anywhere)."""
        width, height = self.scene.resolution
        self.tile_size = tile_size_for(width, height, self.settings.tile_size)
        self.tiles = make_tiles(width, height, self.tile_size)
        self.units = make_units(self.tiles, self.settings.samples, progressive)
        self.progressive = progressive
        self.film = SessionFilm(width, height, self.units)
        if traced(self.settings.passes):
            self.film.features = FrameFeatures(width, height)
        self.totals = Counters()

    # -- one unit -------------------------------------------------------------------------
    def render_unit(self, unit: WorkUnit, cancel=None) -> UnitResult | None:
        """Trace the unit's samples; None when `cancel` (anything with is_set()) was set first."""
        s, tile = self.settings, unit.tile
        start = time.perf_counter()
        width, height = self.scene.resolution
        counters = Counters()
        rng = np.random.default_rng([s.seed, tile.index, unit.start])
        sampler = (SobolSampler(s.seed, tile.x0, tile.y0, tile.x1, tile.y1, s.sample_net or s.samples,
                                s.shadow_rays)
                   if s.sampler == "sobol" else RandomSampler(rng))
        features = (TileFeatures(tile.pixels, self.scene.camera, surface=bool({"albedo", "normal"} & set(s.passes)))
                    if self.plan.passes else None)
        films = []
        mid = unit.start + (unit.stop - unit.start) // 2 if unit.halves else unit.start
        for first, stop in ((unit.start, mid), (mid, unit.stop)):     # half A, then B (or all)
            if stop <= first:
                films.append(TileFilm(tile.x1 - tile.x0, tile.y1 - tile.y0))
                continue
            if unit.mask is None:
                samples = TileSamples(self.scene.camera, width, height, tile.x0, tile.y0, tile.x1, tile.y1,
                                      stop, sampler, first=first)
            else:
                samples = MaskedTileSamples(self.scene.camera, width, height, tile.x0, tile.y0, tile.x1,
                                            tile.y1, stop, sampler, unpack_mask(unit.mask, tile.pixels), first)
            film = TileFilm(tile.x1 - tile.x0, tile.y1 - tile.y0)
            films.append(film)

            def finished(pixel, radiance, film=film):
                bad = ~np.isfinite(radiance).all(axis=0)
                if bad.any():
                    # Counted before the guard, never hidden silently.
                    counters.nonfinite_samples += int(bad.sum())
                    radiance[:, bad] = 0.0
                film.add(pixel, radiance)

            if not self.tracer.trace(samples, rng, counters, finished, cancel, sampler, features):
                return None
        a, b = films
        seconds = time.perf_counter() - start
        sums = None if features is None else features.sums()
        if not unit.halves:
            return UnitResult(unit, b.sum, b.sum_sq, b.count, counters, seconds, features=sums)
        return UnitResult(unit, a.sum + b.sum, a.sum_sq + b.sum_sq, a.count + b.count, counters, seconds,
                          sum_a=a.sum, count_a=a.count, features=sums)

    # -- the whole frame --------------------------------------------------------------------
    def add(self, result: UnitResult) -> list[Tile]:
        self.totals.merge(result.counters)
        return self.film.add(result)

    def add_and_show(self, result: UnitResult, on_tile=None) -> None:
        """Merge a unit's result and hand every tile it changed to on_tile(x0, y0, x1, y1, pixels)."""
        for tile in self.add(result):
            if on_tile is not None:
                on_tile(tile.x0, tile.y0, tile.x1, tile.y1, self.film.mean(tile))

    def run(self, workers, on_tile=None, should_cancel=None, on_progress=None) -> RenderResult:
        """Render every unit on `workers` (start(units), next_result(timeout), cancel(), close():
        engine/pools/local.py, engine/pools/dask_cluster.py).  Callbacks run on the calling thread: on_tile(x0, y0,
        x1, y1, pixels) after each merge, should_cancel() polled about every 0.1 s,
        on_progress(fraction, message)."""
        if self.settings.stopping_rules():
            from .stopping import run_passes
            return run_passes(self, workers, on_tile, should_cancel, on_progress)
        start = time.perf_counter()

        def merge(result):
            self.add_and_show(result, on_tile)
            if on_progress is not None:
                elapsed = max(time.perf_counter() - start, 1e-9)
                rate = sum(self.totals.rays.values()) / elapsed / 1e6
                on_progress(self.film.units_added / len(self.units),
                            f"unit {self.film.units_added}/{len(self.units)} · {rate:.2f} M rays/s · "
                            f"effects: {self.plan.summary()}")
        try:
            workers.start(self.units)
            interrupt = None if should_cancel is None else (lambda: "cancelled" if should_cancel() else None)
            reason, error = await_units(workers, len(self.units), merge, interrupt)
            cancelled = reason is not None
        finally:
            workers.close()
        if error is not None:
            raise error
        if cancelled:                                      # keep every unit that finished
            for tile in self.film.flush():
                if on_tile is not None:
                    on_tile(tile.x0, tile.y0, tile.x1, tile.y1, self.film.mean(tile))
        return self.result(time.perf_counter() - start, cancelled, getattr(workers, "describe", "local"))

    def error_stats(self, seconds: float) -> dict:
        """estimated_rel_error and seconds_to_target (README: Stopping rules)."""
        from ..film.error_estimate import seconds_to_target
        s = self.settings
        error = self.film.estimated_rel_error()
        target = s.noise_target or DEFAULT_TARGET
        spp = self.film.samples_per_pixel
        finite = (lambda x: float(x) if np.isfinite(x) else None)        # JSON has no NaN
        return {"estimated_rel_error": finite(error), "target_rel_error": target,
                "seconds_to_target": finite(seconds_to_target(seconds, error, target)),
                "error_estimate": "half buffers" if self.film.count_a.any() else "sample variance",
                "time_limit": s.time_limit, "noise_target": s.noise_target, "min_samples": s.min_samples,
                "adaptive": s.adaptive and s.noise_target > 0,
                "samples_per_pixel": {"min": float(spp.min()), "mean": float(spp.mean()), "max": float(spp.max())}}

    def result(self, seconds: float, cancelled: bool = False, workers: str = "local") -> RenderResult:
        s, geo = self.settings, self.geometry
        width, height = self.scene.resolution
        rays = dict(self.totals.rays)
        stats = {
            "engine": ENGINE_NAME, "engine_version": ENGINE_VERSION,
            "render_seconds": seconds, "setup_seconds": self.setup_seconds, "build_seconds": geo.build_seconds,
            "samples": s.samples, "shadow_rays": s.shadow_rays, "max_depth": s.max_depth,
            "russian_roulette": s.russian_roulette, "fresnel": s.fresnel, "estimator": s.estimator,
            "sampler": s.sampler, "seed": s.seed, "resolution": [width, height], "threads": s.resolved_threads(),
            "tile_size": self.tile_size, "units": len(self.units), "units_done": self.film.units_added,
            "progressive": self.progressive, "parallelism": workers,
            "accelerator": self.accelerator, "accelerator_reason": self.accelerator_reason,
            "rays": rays, "rays_per_second": sum(rays.values()) / seconds if seconds > 0 else 0.0,
            "effects": dict(self.plan.enabled), "effects_reason": dict(self.plan.reason),
            "nonfinite_samples": self.totals.nonfinite_samples,
            "seconds_in_intersection": self.totals.seconds_in_intersection,
            "seconds_in_accelerator": self.totals.seconds_in_accelerator,
            "cancelled": cancelled, "warnings": list(self.warnings), "passes": list(s.passes),
        }
        stats.update(self.error_stats(seconds))
        return RenderResult(self.film.mean(), self.film.variance_of_mean(), stats, list(self.warnings), cancelled,
                            pass_images(self.film, s.passes), film=self.film)
