"""What the path tracer asks of the caustic photons: the photon map of a pass, and the caustic
radiance at camera-path vertices.

Pass k holds the camera samples k S .. (k + 1) S - 1 of every pixel (S = SAMPLES_PER_PASS) and one
photon map of `photons_per_pass` photons (the setting's, or automatic from the render's pixels) with
radius r_k (engine/integrators/photons/photon_map.py).
A pass's map is a function of (seed, k) and the scene only: its photons are emitted from their own
stream, and traced together with those of the other passes of its batch of PASSES_PER_BATCH (passes
8 b .. 8 b + 7, with the batch's stream for the bounces), so every worker that renders samples of
pass k builds the same map, whatever unit, worker or order asks for it, and images stay
bit-identical on every pool.  A batch's maps (photon_map.py BatchMaps: its passes' grids) are
kept while the cache holds less than CACHE_BYTES; maps made after that are used and dropped
(rebuilt, identically, when asked for again).  Units run through their passes in order, tile after
tile, so keeping the first maps (rather than the latest, which such a sweep would always evict)
saves the most tracing.  The gather of every pass of a batch is one call of gather.py's kernels
(or of their numba twins, gather_jit.py, with the backend's choice: the same bits).

Batches as work (engine/rendering/photon_passes.py): a render session has one worker trace a batch
(`trace_batch`, a photon unit) and hands its stored photons to every worker (`share`): each worker
then builds its maps from them (a grid, milliseconds) instead of tracing the batch itself, and
drops them with `forget` once no unit needs them.  A batch that was not shared is traced where it is
needed, as above: the photons are the same either way, so the image is too.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from ...sampling.qmc import hash32
from .emission import emit
from . import gather
from .photon_map import BatchMaps, PhotonMap, radius_of_pass
from .targets import specular_targets
from .tracing import trace_photons

SAMPLES_PER_PASS = 1          # camera samples per pixel per photon pass (SPPM: one)
PASSES_PER_BATCH = 8          # passes traced together (one wavefront of photons: less overhead per photon)
PHOTON_STREAM = 0x70686F74    # 'phot': the photon passes' random stream, apart from the camera's
CACHE_BYTES = 512 << 20
SECONDARY_SCALE = 4.0         # the radius at vertices after a non-delta bounce: their caustics are seen
                              # blurred anyway, and a wider disk holds 16 x the photons (less noise)
AUTO_RADIUS_PIXELS = 1.0      # the automatic first radius: this many pixel footprints at the targets
SECONDARY_GATHER = 1.0        # the probability that a vertex after a non-delta bounce gathers (weight 1 / it):
                              # 1/4 saved 10 % of the CPU but quadrupled the caustic's variance, a vertex seen
                              # through the glass after a diffuse bounce carries much of it (docs/photons.md
                              # "Equal time against path tracing")
GATHER_SALT = 0x67617468      # 'gath': the secondary gathers' coin, apart from every other stream
AUTO_PHOTONS_PER_PIXEL = 0.25 # photons_per_pass 0: this many photons a pass per pixel of the render ...
AUTO_PHOTONS = (1000, 50000)  # ... within these bounds (docs/photons.md "Photons per pass")


def photons_per_pass(settings, scene) -> int:
    """The photons a pass emits: the setting, or (0: auto) AUTO_PHOTONS_PER_PIXEL x the scene's pixels
    within AUTO_PHOTONS.  A pass's variance from its photons grows with the pixels that share them
    (the radius is a pixel's footprint) and its camera paths' cost with the pixels too, so the best
    count per pixel is about the same at every resolution (measured on the Cornell box, the point
    light's caustic and the caustic room at 96 x 96 and 256 x 256)."""
    if settings.photons_per_pass > 0:
        return int(settings.photons_per_pass)
    width, height = scene.resolution
    return int(min(max(round(AUTO_PHOTONS_PER_PIXEL * width * height), AUTO_PHOTONS[0]), AUTO_PHOTONS[1]))


def gather_coins(seed: int, sample: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(M,) uniform numbers in [0, 1) for the vertices at `points` (3, M) of the camera samples `sample`
    (M,): a hash of the seed, the sample number and the point's coordinates' bits, so the same vertex
    draws the same coin on every worker (the image stays bit-identical on every pool) and no coin
    depends on the photons."""
    bits = np.ascontiguousarray(points, dtype=np.float64).view(np.uint64)
    folded = ((bits ^ (bits >> np.uint64(32))) & np.uint64(0xFFFFFFFF)).astype(np.uint32)
    with np.errstate(over="ignore"):
        h = hash32(folded[0] ^ np.uint32(GATHER_SALT ^ (seed & 0xFFFFFFFF)))
        h = hash32(h ^ folded[1])
        h = hash32(h ^ folded[2])
        h = hash32(h ^ np.asarray(sample, dtype=np.uint32))
    return h * (1.0 / 4294967296.0)


def batches_of(start: int, stop: int) -> range:
    """The photon batches that camera samples start .. stop - 1 of a pixel gather from."""
    if stop <= start:
        return range(0)
    return range(start // SAMPLES_PER_PASS // PASSES_PER_BATCH, (stop - 1) // SAMPLES_PER_PASS // PASSES_PER_BATCH + 1)


def passes_of(samples: int) -> int:
    """The number of photon passes a render of `samples` samples per pixel runs."""
    return -(-samples // SAMPLES_PER_PASS)


def auto_radius(scene, targets) -> float:
    """The first pass's radius: AUTO_RADIUS_PIXELS pixel footprints at the distance from the camera
    to the nearest target's centre (a pinhole's footprint: sensor width / lens / pixels), at least
    1e-5 of the scene's size."""
    cam = scene.camera
    eye = np.asarray(cam.matrix, dtype=np.float64)[:3, 3]
    width, height = scene.resolution
    if cam.sensor_fit == "VERTICAL":
        per_pixel = cam.sensor_height / cam.lens / height
    elif cam.sensor_fit == "HORIZONTAL":
        per_pixel = cam.sensor_width / cam.lens / width
    else:
        per_pixel = cam.sensor_width / cam.lens / max(width, height)
    distance = float(np.min(np.linalg.norm(targets.center - eye[:, None], axis=0)))
    size = float(np.max(targets.radius))
    return max(AUTO_RADIUS_PIXELS * per_pixel * distance, 1e-5 * size, 1e-9)


class CausticPhotons:
    """The caustic photon maps of a prepared scene (engine/rendering/session.py), pass by pass."""

    def __init__(self, tracer, scene, settings):
        """tracer: the PathTracer whose geometry, lights and materials the photons meet."""
        self.tracer, self.settings = tracer, settings
        self.targets = specular_targets(scene, tracer.mats)
        self.photons = photons_per_pass(settings, scene)    # fixed at preparation (the viewport: its first view)
        self.alpha = float(settings.photon_alpha)
        self.first_radius = (float(settings.photon_radius) if settings.photon_radius > 0 or self.targets is None
                             else auto_radius(scene, self.targets))
        self.maps = {}                   # batch -> BatchMaps
        self.cached_bytes = 0
        backend = getattr(getattr(tracer, "plan", None), "backends", {}).get("photon_caustics", "numpy")
        if backend == "numba":           # the gather compiled (engine/integrators/photons/gather_jit.py)
            from . import gather_jit
            self.kernels = gather_jit
        else:
            self.kernels = gather
        self.shared = {}                 # batch -> Stored handed over by the session (share)
        self.lock = threading.Lock()     # threads of one worker: a map is built (or its batch traced) once

    def radius(self, k: int) -> float:
        return radius_of_pass(self.first_radius, k, self.alpha)

    def view_changed(self, scene) -> None:
        """A new camera or resolution (the viewport): the automatic first radius follows it; the
        maps built with the old radius go, the shared photons (which do not depend on the view) stay."""
        if self.settings.photon_radius > 0 or self.targets is None:
            return
        radius = auto_radius(scene, self.targets)
        with self.lock:
            if radius != self.first_radius:
                self.first_radius, self.maps, self.cached_bytes = radius, {}, 0

    def trace_batch(self, b: int, counters, cancel=None):
        """The stored photons (engine/integrators/photons/tracing.py Stored) of batch b: passes
        PASSES_PER_BATCH b .. PASSES_PER_BATCH (b + 1) - 1, each pass's photons from its own stream,
        traced together; None when `cancel` (anything with is_set()) was set first (it is checked
        between passes' emissions and at every bounce)."""
        start = time.perf_counter()
        batch = range(b * PASSES_PER_BATCH, (b + 1) * PASSES_PER_BATCH)
        emitted = []
        for j in batch:                  # each pass's photons from its own stream
            if cancel is not None and cancel.is_set():
                return None
            emitted.append(emit(self.tracer.lights, self.photons,
                                np.random.default_rng([self.settings.seed, PHOTON_STREAM, j]), self.targets))
        label = np.concatenate([np.full(e.origin.shape[1], j) for j, e in zip(batch, emitted)])
        o, d, phi = (np.concatenate([getattr(e, name) for e in emitted], axis=1)
                     for name in ("origin", "direction", "flux"))
        rng = np.random.default_rng([self.settings.seed, PHOTON_STREAM, batch[0], 1])     # the batch's bounces
        stored = trace_photons(self.tracer, o, d, phi, counters, rng, self.settings.max_depth, label, cancel)
        if stored is None:
            return None
        ph = counters.photons
        for key, value in (("photon_passes_traced", PASSES_PER_BATCH), ("photons_emitted", self.photons * PASSES_PER_BATCH),
                           ("photons_traced", stored.traced), ("photons_stored", len(stored.label)),
                           ("photon_rays", stored.rays), ("trace_seconds", time.perf_counter() - start)):
            ph[key] = ph.get(key, 0) + value
        for j in batch:
            counters.photon_radii[j] = self.radius(j)
        return stored

    def share(self, b: int, stored) -> None:
        """Batch b's stored photons, traced elsewhere (engine/rendering/photon_passes.py)."""
        with self.lock:
            self.shared[b] = stored

    def forget(self, batches) -> None:
        """Drop the shared photons and the maps of `batches`: no unit of the render needs them now."""
        with self.lock:
            for b in batches:
                self.shared.pop(b, None)
                made = self.maps.pop(b, None)
                if made is not None:
                    self.cached_bytes -= made.nbytes

    def maps_of(self, b: int, counters, cancel=None) -> BatchMaps | None:
        """Batch b's photon maps (every pass's): from the cache, built from its shared photons, or
        traced now (None: cancelled while tracing)."""
        found = self.maps.get(b)
        if found is not None:
            return found
        with self.lock:
            found = self.maps.get(b)
            if found is not None:
                return found
            stored = self.shared.get(b)
            if stored is None:
                stored = self.trace_batch(b, counters, cancel)
                if stored is None:
                    return None
            passes = range(b * PASSES_PER_BATCH, (b + 1) * PASSES_PER_BATCH)
            found = BatchMaps(stored, passes, [self.radius(j) for j in passes], (1.0, SECONDARY_SCALE))
            if self.cached_bytes + found.nbytes <= CACHE_BYTES:
                self.maps[b] = found
                self.cached_bytes += found.nbytes
            return found

    def map_of(self, k: int, counters, cancel=None) -> PhotonMap | None:
        """Pass k's photon map (its batch's maps_of)."""
        maps = self.maps_of(k // PASSES_PER_BATCH, counters, cancel)
        return None if maps is None else PhotonMap(maps, k)

    def radiance(self, sample, bsdf, si, points, facing, counters, segments=None, secondary=None,
                 budget=None) -> np.ndarray:
        """(3, M) the caustic radiance at the M camera-path vertices (rows `points`, ShadingPoint si
        of `bsdf`, facing geometric normals) of the camera samples `sample` (M,), each from its
        pass's map; segments (M,): the most photon segments each may take (None: any); secondary
        (M,) bool: the vertices after a non-delta bounce, which gather with SECONDARY_SCALE x the
        radius, each with probability SECONDARY_GATHER and weight 1 / SECONDARY_GATHER (None: none);
        budget (3, M): the bounce limits per type left to the photons' chains
        (engine/integrators/photons/photon_map.py BatchMaps.radiance; None: none).  The points of
        every pass of a batch are gathered in one call."""
        m = points.shape[1]
        out = np.zeros((3, m))
        passes = sample // SAMPLES_PER_PASS
        wide = np.zeros(m, bool) if secondary is None else np.asarray(secondary, bool)
        gathering = np.ones(m, bool)
        if SECONDARY_GATHER < 1.0 and wide.any():
            gathering[wide] = gather_coins(self.settings.seed, sample[wide], points[:, wide]) < SECONDARY_GATHER
        batch = passes // PASSES_PER_BATCH
        everyone = gathering.all()
        albedo = None if bsdf is None else bsdf.lambert_albedo(si)     # f = rho / pi: one kernel call a batch
        for b in np.unique(batch if everyone else batch[gathering]):
            maps = self.maps_of(int(b), counters)
            start = time.perf_counter()
            rows = np.flatnonzero((batch == b) & gathering)
            if albedo is not None:
                self.kernels.lambert_radiance(maps, rows, points, facing, passes, wide, SECONDARY_SCALE, segments,
                                              budget, albedo, out)
            else:
                whole = len(rows) == m
                part = (lambda a: a) if whole else (lambda a: a.take(rows, axis=-1))
                local, radius = gather.slots_of(maps, part(passes), part(wide), SECONDARY_SCALE)
                out[:, rows] = maps.radiance(bsdf, si if whole else si.take(rows), part(points), part(facing), local,
                                             radius, None if segments is None else part(segments),
                                             None if budget is None else part(budget), self.kernels)
            if SECONDARY_GATHER < 1.0:
                out[:, rows[wide.take(rows)]] *= 1.0 / SECONDARY_GATHER
            counters.photons["gather_seconds"] = counters.photons.get("gather_seconds", 0.0) + \
                time.perf_counter() - start
        return out
