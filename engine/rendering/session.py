"""The tracer side of a render: the scene prepared once, work units traced on demand.

Whoever traces builds a PreparedScene from the scene and the settings: this process for threads
and forked processes (engine/pools/local.py), each worker process (engine/pools/processes.py,
engine/pools/viewport.py) and each Dask worker (engine/pools/dask_cluster.py).  The frame side
(tiles, units, the ordered merge, the film, the result: engine/rendering/frame.py) runs where the
render was asked for and never needs the geometry:

    prepared = PreparedScene(scene, settings)     # validate, effect plan, BVH, lights: once
    frame = Frame(scene, settings, prepared.facts())
    for unit in frame.units:                      # (tile, sample range): anywhere, any order
        frame.add(prepared.render_unit(unit, cancel))   # merged per tile in sample order
    frame.result(seconds)                         # image, variance, stats

A work unit is a tile and a range of sample numbers.  Every random number is a function of
(seed, pixel, sample number, dimension) with the Sobol' sampler (engine/sampling/qmc.py), or of (seed,
unit) with independent random numbers, so a unit renders the same wherever and however often it
runs; the film adds each tile's units in sample order, so the image is the same bit for bit
whatever the number and kind of workers, the order units finish in, and retries after failures.
A unit that is cancelled returns None and is dropped whole: the film keeps the finished ones
(unbiased means over fewer samples), so Esc takes effect within a bounce.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry.accel import choose_accelerator
from ..scene.camera_rays import TileSamples
from ..scene.tracing_origin import moved, moved_camera, tracing_origin
from ..integrators.effects import EffectPlan, plan_effects
from ..film.accumulator import Film
from ..film.ordered_samples import OrderedSamples
from ..film.pixel_filter import pixel_filter_for
from ..geometry.scene_geometry import Counters, SceneGeometry
from ..integrators.path_tracer import PathTracer
from ..lights import LightSet
from .masked_samples import MaskedTileSamples, unpack_mask
from ..film.passes import CRYPTO, EXTRA, FirstHitTables, TileFeatures
from ..sampling.qmc import RandomSampler, SobolSampler
from ..core.settings import RenderSettings
from ..core.backend import resolve as resolve_backend
from ..core.collector import collector_paused
from ..materials.textures import load_textures
from ..core.version import ENGINE_VERSION
from .units import PhotonUnit, WorkUnit


@dataclass
class UnitResult:
    unit: WorkUnit
    sum: np.ndarray              # (h, w, 3) radiance sums of the unit's tile
    sum_sq: np.ndarray           # (h, w, 3) sums of squares
    count: np.ndarray            # (h, w) samples
    counters: Counters
    seconds: float
    engine_version: str = ENGINE_VERSION
    sum_a: np.ndarray | None = None      # half buffer A (unit.halves): sums and counts of [start, mid)
    count_a: np.ndarray | None = None
    features: dict | None = None # engine/film/passes.py TileFeatures.sums(), when a traced pass is on
    transparent: np.ndarray | None = None   # (h, w) samples that saw the background (a transparent film)


@dataclass
class PhotonResult:
    """A traced photon batch (engine/rendering/units.py PhotonUnit): its stored photons
    (engine/integrators/photons/tracing.py Stored), for every worker's units to gather from."""
    unit: PhotonUnit
    stored: object
    counters: Counters
    seconds: float
    engine_version: str = ENGINE_VERSION


@dataclass
class TracerFacts:
    """What the frame side learns from a prepared scene (it is small and pickles: a worker sends it)."""
    accelerator: str
    accelerator_reason: str
    plan: EffectPlan
    build_seconds: float
    setup_seconds: float
    warnings: list = field(default_factory=list)
    python: str = sys.version.split()[0]
    pid: int = 0
    setup_cpu_seconds: float = 0.0      # CPU seconds of the preparation (its process's, all threads)


class PreparedScene:
    """Scene preparation (validation, effect plan, BVH, lights, textures, the path tracer) once;
    units rendered on demand with render_unit."""

    def __init__(self, scene, settings: RenderSettings | None = None, log=print, checked: bool = False):
        """checked: `scene` was validated where it was made (its warnings reported there) and has
        not changed since; Scene.validate is idempotent, so it is not run again (the kept workers of
        Persistent Data, engine/pools/kept.py)."""
        with collector_paused():            # long-lived objects only (engine/core/collector.py)
            self._prepare(scene, settings, log, checked)

    def _prepare(self, scene, settings, log, checked) -> None:
        settings = settings or RenderSettings()
        settings.validate()
        start, start_cpu = time.perf_counter(), time.process_time()
        self.warnings = [] if checked else scene.validate()
        # Positions relative to the camera when the scene stands far from the world origin
        # (engine/scene/tracing_origin.py); None: world coordinates, the scene as it is.
        self.origin = tracing_origin(scene)
        if self.origin is not None:
            scene = moved(scene, self.origin)
        self.scene, self.settings = scene, settings
        n_tri = sum(len(m.triangles) for m in scene.meshes)
        self.accelerator, self.accelerator_reason = choose_accelerator(settings.accelerator, n_tri)
        self.plan = plan_effects(scene, settings, self.accelerator)
        kernels = ([k for k, on in self.plan.enabled.items() if on] + ["wavefront"]
                   + (["sobol"] if settings.sampler == "sobol" else []))
        self.plan.use_backend(*resolve_backend(settings.backend, log, kernels), kernels)
        self.sobol_kernel = None                     # qmc.sample_2d; its numba twin where the backend says
        self.sobol_seeded_kernel = None              # with it, the sampler's kernel that reads the seeds itself
        if self.plan.backends.get("sobol") == "numba":
            from ..sampling.sobol_jit import sample_2d as compiled_sample_2d, sample_2d_seeded
            self.sobol_kernel = compiled_sample_2d
            self.sobol_seeded_kernel = sample_2d_seeded
        self.camera_rays_jit = None                  # the primary rays compiled (engine/scene/camera_rays_jit.py)
        if self.plan.backends.get("wavefront") == "numba":
            from ..scene import camera_rays_jit
            self.camera_rays_jit = camera_rays_jit
        if scene.lights and not self.plan.area_lights and settings.shadow_rays == 0:
            self.warnings.append(f"{len(scene.lights)} area light(s) are reached by shadow rays only here: "
                                 "with 0 shadow rays they light nothing")
        for w in self.warnings:
            log(f"warning: {w}")
        self.geometry = SceneGeometry(scene, self.accelerator, self.plan)
        textures, lit = load_textures(scene, self.plan, log, self.warnings)    # engine/materials/textures.py
        self.lights = LightSet(lit, solid_angle=self.plan.solid_angle, spatial=self.plan.light_tree,
                               lamps_hittable=self.plan.area_lights, world=self.plan.world_light,
                               backend=self.plan.backends.get("light_tree", "numpy"),
                               shapes_backend=self.plan.backends.get("emission", "numpy"),
                               wavefront_backend=self.plan.backends.get("wavefront", "numpy"))
        self.plan.describe_light_kinds(self.lights)
        self.tracer = PathTracer(self.geometry, self.lights, lit.materials, self.plan, settings,
                                 scene.background, textures=textures and textures.bind(self.geometry, self.lights))
        self.pixel_filter = pixel_filter_for(settings)        # None: the box of width 1
        self.first_hit = (FirstHitTables(scene, self.geometry, settings.passes, self.origin)
                          if self.plan.passes and set(EXTRA + CRYPTO) & set(settings.passes) else None)
        self.prepass()
        self.setup_seconds = time.perf_counter() - start
        self.setup_cpu_seconds = time.process_time() - start_cpu

    def prepass(self) -> None:
        """The hook for work done once per prepared scene before any unit, wherever the scene is
        prepared.  It may depend on the scene and the settings only, never on the worker, so that
        every worker holds the same result and images stay identical.  The caustic photons
        (engine/integrators/photons/caustics.py) are set up here; each pass's map is traced when a
        unit first needs it, as a function of (seed, pass) alone."""
        if self.plan.enabled.get("photon_caustics"):
            from ..integrators.photons import CausticPhotons
            self.tracer.photons = CausticPhotons(self.tracer, self.scene, self.settings)

    def set_view(self, camera, resolution) -> None:
        """A new camera (world coordinates) and resolution for the same prepared scene (the viewport)."""
        self.scene.camera = camera if self.origin is None else moved_camera(camera, self.origin)
        self.scene.resolution = tuple(resolution)
        if self.tracer.photons is not None:
            self.tracer.photons.view_changed(self.scene)

    # -- photon batches (engine/rendering/photon_passes.py) -----------------------------------------
    def trace_photon_unit(self, unit: PhotonUnit, cancel=None) -> PhotonResult | None:
        """Trace the unit's photon batch; None when `cancel` was set first (checked at every bounce)."""
        start = time.perf_counter()
        counters = Counters()
        stored = self.tracer.photons.trace_batch(unit.batch, counters, cancel)
        return None if stored is None else PhotonResult(unit, stored, counters, time.perf_counter() - start)

    def share_photons(self, batch: int, stored) -> None:
        """A photon batch traced by some worker: this scene's units gather from it."""
        if self.tracer.photons is not None:
            self.tracer.photons.share(batch, stored)

    def forget_photons(self, batches) -> None:
        if self.tracer.photons is not None:
            self.tracer.photons.forget(batches)

    def facts(self) -> TracerFacts:
        return TracerFacts(self.accelerator, self.accelerator_reason, self.plan, self.geometry.build_seconds,
                           self.setup_seconds, list(self.warnings), pid=os.getpid(),
                           setup_cpu_seconds=self.setup_cpu_seconds)

    # -- one unit -------------------------------------------------------------------------
    def render_unit(self, unit: WorkUnit, cancel=None) -> UnitResult | None:
        """Trace the unit's samples; None when `cancel` (anything with is_set()) was set first.  A
        PhotonUnit is traced by trace_photon_unit (every pool runs both kinds the same way)."""
        if isinstance(unit, PhotonUnit):
            return self.trace_photon_unit(unit, cancel)
        s, tile = self.settings, unit.tile
        start = time.perf_counter()
        width, height = self.scene.resolution
        counters = Counters()
        # A band of a split unit (engine/rendering/units.py balance_units) draws its own numbers.
        rng = np.random.default_rng([s.seed, tile.index, unit.start] + ([unit.part] if unit.parts > 1 else []))
        sampler = (SobolSampler(s.seed, tile.x0, tile.y0, tile.x1, tile.y1, s.sample_net or s.samples,
                                s.shadow_rays)
                   if s.sampler == "sobol" else RandomSampler(rng))
        if self.sobol_kernel is not None:
            sampler.kernel, sampler.seeded_kernel = self.sobol_kernel, self.sobol_seeded_kernel
        features = (TileFeatures(tile.pixels, self.scene.camera, surface=bool({"albedo", "normal"} & set(s.passes)),
                                 first_hit=self.first_hit)
                    if self.plan.passes else None)
        films = []
        transparent = s.film_transparent
        mid = unit.start + (unit.stop - unit.start) // 2 if unit.halves else unit.start
        for first, stop in ((unit.start, mid), (mid, unit.stop)):     # half A, then B (or all)
            if stop <= first:
                films.append(Film(tile.x1 - tile.x0, tile.y1 - tile.y0, transparent))
                continue
            if unit.mask is None:
                samples = TileSamples(self.scene.camera, width, height, tile.x0, tile.y0, tile.x1, tile.y1,
                                      stop, sampler, first=first, pixel_filter=self.pixel_filter)
            else:
                samples = MaskedTileSamples(self.scene.camera, width, height, tile.x0, tile.y0, tile.x1,
                                            tile.y1, stop, sampler, unpack_mask(unit.mask, tile.pixels), first,
                                            pixel_filter=self.pixel_filter)
            samples.compiled = self.camera_rays_jit
            film = Film(tile.x1 - tile.x0, tile.y1 - tile.y0, transparent)
            films.append(film)
            # The film's sums in sample order, whatever the wavefront (engine/film/ordered_samples.py).
            ordered = OrderedSamples(film, tile.pixels, first, stop)

            def finished(pixel, radiance, sample, ordered=ordered):
                bad = ~np.isfinite(radiance).all(axis=0)
                if bad.any():
                    # Counted before the guard, never hidden silently.
                    counters.nonfinite_samples += int(bad.sum())
                    radiance[:, bad] = 0.0
                ordered.add(pixel, radiance, sample)

            if not self.tracer.trace(samples, rng, counters, finished, cancel, sampler, features,
                                     film.add_transparent if transparent else None):
                return None
            ordered.flush()
        a, b = films
        seconds = time.perf_counter() - start
        sums = None if features is None else features.sums()
        if not unit.halves:
            return UnitResult(unit, b.sum, b.sum_sq, b.count, counters, seconds, features=sums,
                              transparent=b.transparent)
        return UnitResult(unit, a.sum + b.sum, a.sum_sq + b.sum_sq, a.count + b.count, counters, seconds,
                          sum_a=a.sum, count_a=a.count, features=sums,
                          transparent=None if not transparent else a.transparent + b.transparent)
