"""The frame side of a render: tiles, work units, the ordered merge, the film and the result.

It runs where the render was asked for (the command line, Blender) and never needs the geometry:
the units are traced by a pool (engine/pools/protocol.py) whose workers each hold the tracer side,
a PreparedScene (engine/rendering/session.py); what the frame side reports of the preparation
(accelerator, effect plan, warnings) comes from the pool as TracerFacts.  Tiles and units depend
on the scene's resolution and the settings only, never on the workers, and the film adds each
tile's units in chunk order, so the image is the same bit for bit whatever renders it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import WorkersLost
from ..core.settings import stats_of
from ..core.version import ENGINE_NAME, ENGINE_VERSION
from ..film.accumulator import Film
from ..film.passes import FrameFeatures, pass_images, traced
from ..geometry.scene_geometry import Counters
from .units import PHOTON_UNIT_SAMPLES, Tile, await_units, make_tiles, make_units, tile_size_for

DEFAULT_TARGET = 0.01            # the error seconds_to_target aims at without a noise target


@dataclass
class RenderResult:
    image: np.ndarray
    variance: np.ndarray
    stats: dict
    warnings: list = field(default_factory=list)
    cancelled: bool = False
    passes: dict = field(default_factory=dict)    # engine/film/passes.py pass_images(): name -> (H, W, C)
    film: "FrameFilm | None" = None       # sums, half buffers, samples per pixel (engine/rendering/estimate.py)
    alpha: np.ndarray | None = None       # (H, W) float32 alpha of a transparent film (image is premultiplied)

    def combined(self) -> np.ndarray:
        """Blender's Combined as written to files: the image, with its alpha when the film is
        transparent ((H, W, 4) premultiplied RGBA), else (H, W, 3)."""
        if self.alpha is None:
            return self.image
        return np.concatenate([self.image, self.alpha[..., None].astype(self.image.dtype)], axis=-1)


class FrameFilm(Film):
    """The frame's film, merged from unit results: each tile's units in chunk order (results that
    arrive early wait), so floating-point sums never depend on arrival order.  Besides the sums it
    keeps half buffer A of the stopping rules' rounds (engine/film/error_estimate.py; B = total - A)
    and the traced passes' features."""

    def __init__(self, width: int, height: int, units, transparent: bool = False, exposure: float = 1.0):
        super().__init__(width, height, transparent)
        self.exposure = exposure
        self.sum_a = np.zeros((height, width, 3))
        self.count_a = np.zeros((height, width))
        self.next_chunk = {}                    # tile index -> next chunk to add
        self.pending = {}                       # (tile index, chunk, part) -> UnitResult
        self.parts_added = {}                   # (tile index, chunk) -> its parts merged so far
        self.units_total = len(units)
        self.units_added = 0
        self.features = None                    # FrameFeatures when a traced pass is on
        self._error = None                      # (units_added, estimated_rel_error) last computed

    def add(self, result) -> list[Tile]:
        """Merge a unit's result; returns the tiles (or bands of a split chunk) whose pixels changed.
        The parts of a split chunk (engine/rendering/units.py balance_units) cover apart rows of the
        tile: each merges once its chunk is next, and the chunk after waits for all of them."""
        unit = result.unit
        index = unit.tile.index
        self.pending[(index, unit.chunk, unit.part)] = result
        changed = {}
        while True:
            chunk = self.next_chunk.get(index, 0)
            ready = sorted(k for k in self.pending if k[0] == index and k[1] == chunk)
            for key in ready:
                t = self._merge(self.pending.pop(key))
                changed[(t.x0, t.y0, t.x1, t.y1)] = t
            if not ready or self.next_chunk.get(index, 0) == chunk:
                return list(changed.values())

    def flush(self) -> list[Tile]:
        """Merge the results still waiting for an earlier chunk of their tile that will not come
        (a cancelled render: the work finished is kept, in chunk order); the tiles changed."""
        changed = {}
        for key in sorted(self.pending):
            t = self._merge(self.pending.pop(key))
            changed[(t.x0, t.y0, t.x1, t.y1)] = t
        return list(changed.values())

    def _merge(self, r) -> Tile:
        t, unit = r.unit.tile, r.unit
        h, w = t.y1 - t.y0, t.x1 - t.x0
        self.add_sums(t.x0, t.y0, r.sum.reshape(h, w, 3), r.sum_sq.reshape(h, w, 3), r.count.reshape(h, w),
                      None if r.transparent is None else r.transparent.reshape(h, w))
        if r.sum_a is not None:
            self.sum_a[t.y0:t.y1, t.x0:t.x1] += r.sum_a.reshape(h, w, 3)
            self.count_a[t.y0:t.y1, t.x0:t.x1] += r.count_a.reshape(h, w)
        if self.features is not None and r.features is not None:
            self.features.add(t, r.features)
        self.units_added += 1
        parts = self.parts_added[(t.index, unit.chunk)] = self.parts_added.get((t.index, unit.chunk), 0) + 1
        if parts == unit.parts:
            self.next_chunk[t.index] = max(self.next_chunk.get(t.index, 0), unit.chunk + 1)
        return t

    @property
    def samples_per_pixel(self) -> np.ndarray:
        """(H, W) camera samples each pixel got (they differ under adaptive sampling)."""
        return self.count

    def half_buffer_variance(self) -> np.ndarray:
        """(H, W, 3) variance of each pixel mean from the half buffers (engine/film/error_estimate.py);
        where a pixel has no two halves (renders without stopping rules), the sample variance; NaN (no
        estimate) for a pixel without samples (a time limit that ran out first)."""
        from ..film.error_estimate import half_buffer_variance
        var = half_buffer_variance(self.sum, self.count, self.sum_a, self.count_a)
        missing = np.isnan(var)
        if missing.any():
            var[missing] = self.variance_of_mean()[missing]
        var[self.count == 0] = np.nan
        return var

    def estimated_rel_error(self) -> float:
        """The image's estimated relative error E (docs/user-guide.md: Stopping rules).  Computed
        once per state of the film (the sums change in _merge only, which counts units_added): the
        result's stats take the estimate of the last progress line instead of computing it again
        after the last unit (1-2 ms of every frame at 128², engine/rendering/frame.py Frame.result)."""
        if self._error is None or self._error[0] != self.units_added:
            from ..film.error_estimate import image_rel_error
            self._error = (self.units_added,
                           image_rel_error(self.mean().astype(np.float64), self.half_buffer_variance()))
        return self._error[1]


class Frame:
    """Tiles, work units, the film and the counters of one render of `scene` under `settings`;
    `facts` (engine/rendering/session.py TracerFacts) tell what the tracer side prepared.
    progressive: the order of the units, "tiles" (tile by tile) or "frame" (the whole frame
    refines: engine/rendering/units.py make_units)."""

    def __init__(self, scene, settings, facts, progressive: str = "tiles"):
        settings.validate()
        self.settings, self.facts, self.progressive = settings, facts, progressive
        self.resolution = width, height = tuple(scene.resolution)
        self.warnings = list(facts.warnings)
        self.tile_size = tile_size_for(width, height, settings.tile_size)
        self.tiles = make_tiles(width, height, self.tile_size)
        photons = facts.plan.enabled.get("photon_caustics", False)        # each sample a photon pass: shorter units
        # Sobol' numbers depend on the pixel and sample only: the units may be balanced for the
        # render's worker count (one per thread on every pool but Dask's), the image stays the same.
        workers = settings.resolved_threads() if settings.sampler == "sobol" else None
        self.units = make_units(self.tiles, settings.samples, progressive,
                                max_samples=PHOTON_UNIT_SAMPLES if photons else None, workers=workers)
        self.film = FrameFilm(width, height, self.units, settings.film_transparent, settings.film_exposure)
        if traced(settings.passes):
            self.film.features = FrameFeatures(width, height)
        self.totals = Counters()
        self.photon_schedule = None             # engine/rendering/photon_passes.py PhotonScheduler of run()

    def scheduled(self, pool):
        """`pool` with this frame's caustic photon batches as work units (engine/rendering/photon_passes.py)."""
        from .photon_passes import PhotonScheduler, photon_scheduled
        pool = photon_scheduled(pool, self)
        if isinstance(pool, PhotonScheduler):
            self.photon_schedule = pool
        return pool

    @property
    def plan(self):
        return self.facts.plan

    def add(self, result) -> list[Tile]:
        self.totals.merge(result.counters)
        return self.film.add(result)

    def add_and_show(self, result, on_tile=None) -> None:
        """Merge a unit's result and hand every tile it changed to on_tile(x0, y0, x1, y1, pixels)."""
        for tile in self.add(result):
            if on_tile is not None:
                on_tile(tile.x0, tile.y0, tile.x1, tile.y1, self.film.display(tile))

    def run(self, pool, on_tile=None, should_cancel=None, on_progress=None):
        """Render every unit on `pool` (engine/pools/protocol.py; prepared for this scene) and close
        it.  Callbacks run on the calling thread: on_tile(x0, y0, x1, y1, pixels) after each merge,
        should_cancel() polled about every 0.1 s, on_progress(fraction, message)."""
        pool = self.scheduled(pool)
        if self.settings.stopping_rules():
            from .stopping import run_rounds
            return run_rounds(self, pool, on_tile, should_cancel, on_progress)
        start = time.perf_counter()

        def merge(result):
            self.add_and_show(result, on_tile)
            if on_progress is not None:
                on_progress(*self.progress(time.perf_counter() - start))
        try:
            pool.start(self.units)
            interrupt = None if should_cancel is None else (lambda: "cancelled" if should_cancel() else None)
            reason, error = await_units(pool, len(self.units), merge, interrupt)
            cancelled = reason is not None
        finally:
            pool.close()
        if error is not None and not isinstance(error, WorkersLost):
            raise error
        if cancelled or error is not None:                 # keep every unit that finished
            for tile in self.film.flush():
                if on_tile is not None:
                    on_tile(tile.x0, tile.y0, tile.x1, tile.y1, self.film.display(tile))
        result = self.result(time.perf_counter() - start, cancelled or error is not None, pool.describe)
        if error is not None:                              # no worker left: the finished units go with it
            error.result = result
            raise error
        return result

    def progress(self, seconds: float) -> tuple[float, str]:
        """(fraction done, the stats line) after `seconds` of a render without stopping rules: the
        samples every pixel has on average, the time left at the sample rate so far, and the
        estimated error once every pixel has a sample (engine/rendering/stopping.py progress_message)."""
        from .stopping import progress_message
        count, cap = self.film.count, self.settings.samples
        fraction = min(float(count.sum()) / (count.size * cap), 1.0)
        samples = max(1, int(fraction * cap)) if fraction > 0 else 0
        error = self.film.estimated_rel_error() if count.min() > 0 else float("nan")
        remaining = seconds * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
        return fraction, progress_message(samples, cap, error, remaining)

    def error_stats(self, seconds: float) -> dict:
        """estimated_rel_error and seconds_to_target (docs/user-guide.md: Stopping rules)."""
        from ..film.error_estimate import seconds_to_target
        s = self.settings
        error = self.film.estimated_rel_error()
        target = s.noise_target or DEFAULT_TARGET
        spp = self.film.samples_per_pixel
        finite = (lambda x: float(x) if np.isfinite(x) else None)        # JSON has no NaN
        return {"estimated_rel_error": finite(error), "target_rel_error": target,
                "seconds_to_target": finite(seconds_to_target(seconds, error, target)),
                "error_estimate": "half buffers" if self.film.count_a.any() else "sample variance",
                "adaptive": s.adaptive and s.noise_target > 0,
                "samples_per_pixel": {"min": float(spp.min()), "mean": float(spp.mean()), "max": float(spp.max())}}

    def result(self, seconds: float, cancelled: bool = False, pool: str = "local") -> RenderResult:
        """The image, its variance, the passes and the stats; `pool`: the pool's describe."""
        s, facts = self.settings, self.facts
        width, height = self.resolution
        rays = dict(self.totals.rays)
        saturated = self.film.saturated_variance() if "variance" in s.passes else 0
        if saturated and not any(w.startswith("the variance of") for w in self.warnings):
            self.warnings.append(f"the variance of {saturated} pixel(s) is beyond float32: the Variance pass "
                                 "holds float32's largest value (3.4e38) there")
        stats = {
            "engine": ENGINE_NAME, "engine_version": ENGINE_VERSION,
            "render_seconds": seconds, "setup_seconds": facts.setup_seconds, "build_seconds": facts.build_seconds,
            "setup_cpu_seconds": getattr(facts, "setup_cpu_seconds", None),
            **stats_of(s), "resolution": [width, height], "threads": s.resolved_threads(),
            "tile_size": self.tile_size, "units": len(self.units), "units_done": self.film.units_added,
            "progressive": self.progressive, "parallelism": pool,
            "accelerator": facts.accelerator, "accelerator_reason": facts.accelerator_reason,
            "backend": self.plan.backend, "backend_reason": self.plan.backend_reason,
            "kernel_backends": dict(self.plan.backends),
            "rays": rays, "rays_per_second": sum(rays.values()) / seconds if seconds > 0 else 0.0,
            "effects": dict(self.plan.enabled), "effects_reason": dict(self.plan.reason),
            "nonfinite_samples": self.totals.nonfinite_samples,
            "seconds_in_intersection": self.totals.seconds_in_intersection,
            "seconds_in_accelerator": self.totals.seconds_in_accelerator,
            "cancelled": cancelled, "warnings": list(self.warnings),
        }
        stats.update(self.error_stats(seconds))
        if self.totals.photons:             # the caustic photon passes (engine/integrators/photons/)
            radii = self.totals.photon_radii
            stats["photons"] = {**self.totals.photons, "photon_passes": len(radii),
                                "radius_first": radii[min(radii)] if radii else None,
                                "radius_last": radii[max(radii)] if radii else None,
                                "radius_per_pass": [radii[k] for k in sorted(radii)],
                                **(self.photon_schedule.photon_stats() if self.photon_schedule else
                                   {"distribution": "each worker traces its own passes"})}
        shown = self.film.display()
        variance, passes = self.film.variance_of_mean(), pass_images(self.film, s.passes)
        if s.film_exposure != 1.0:                  # the variance of the image shown
            scale = np.float32(s.film_exposure) ** 2
            variance = variance * scale
            if "variance" in passes:
                passes["variance"] = passes["variance"] * scale
        return RenderResult(shown[..., :3], variance, stats, list(self.warnings), cancelled, passes,
                            film=self.film, alpha=shown[..., 3] if self.film.transparent is not None else None)
