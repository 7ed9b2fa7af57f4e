"""Wavefront path tracer: the report's Monte Carlo estimator (§2.3-2.5), with the light
sampling and MIS of its §4 future work.

The paths of a wavefront advance one bounce at a time as NumPy arrays; after each
bounce the arrays are compacted to the paths still alive and topped up with new
camera paths (path regeneration), so the wavefront stays full.  One bounce runs in
named stages (`bounce`): intersect, misses, emission, pass-through (Blender Area
lights), direct light, scatter, roulette, compaction.

* Every surface scatters through its BSDF (engine/materials/protocol.py; which one: the
  material table, engine/materials/table.py): hits are sorted into scatter groups, one per BSDF,
  then the absorbing surfaces and the Area lights that rays pass through; each group is one
  slice of the wavefront.
* Direct light at hits whose BSDF has a non-delta lobe (today: diffuse): N_s shadow rays
  (eq. 2.11).  Under the `report` estimator a light is picked by power and a point on it by
  area (pdf 1/A); otherwise the light tree picks by importance at the shading point and the
  light is sampled by solid angle where stable (engine/lights).
* Emission reached by a ray counts with weight 1 after the camera or a delta (mirror/glass)
  bounce, and when no shadow rays run.  After a non-delta bounce: `report` and
  `solid-angle` drop it (the shadow rays account for it: light is never counted
  twice); `mis` weights it, and the shadow-ray samples, by the power heuristic
  (Veach & Guibas 1995, beta = 2) with the multi-sample counts N_s light samples and
  one BSDF sample (Veach's thesis ch. 9):
      w_light = (N_s p_l)^2 / ((N_s p_l)^2 + p_b^2),  w_bsdf = p_b^2 / (p_b^2 + (N_s p_l)^2)
  with p_l = P(k | x, n) p_w(x -> y) from the light sampler and p_b the BSDF's pdf (Lambert:
  cos/pi).  The path state keeps, for this, the previous bounce's BSDF pdf and whether its lobe
  was a delta.
* The BSDFs: diffuse, a cosine-weighted bounce whose weight f cos / pdf is the albedo
  (eq. 2.13-2.14, engine/materials/lambert.py); mirror, perfect reflection, weight = colour
  (eq. 2.15-2.16, 2.20, engine/materials/mirror.py); glass, Fresnel (eq. 2.17, Schlick or exact)
  picks reflection or refraction (eq. 2.21-2.24) stochastically, weight = tint
  (engine/materials/glass.py).  By default every glass surface separates its IOR from air, as
  the report (and Cycles) do; with `nested_dielectrics` each path keeps a stack of the media it
  is in (engine/materials/media.py), so glass inside glass or water in a glass refracts with the
  ratio of the two IORs (the report's §4 future work);
* image textures (engine/materials/textures.py): the colour and emission of textured materials at triangle
  hits, and the radiance of light samples on textured emitters, are read from the texture at the
  UV interpolated with the hit's barycentrics (pdfs and MIS weights depend on geometry only);
* an image world (engine/lights/environment.py): escaping rays see its radiance along their
  direction (camera rays their own background), MIS-weighted with its importance sampler's pdf;
* Russian roulette (report 2.4) with survival probability min(1, max throughput),
  survivors divided by it; a zero throughput always terminates, without a division.  With the
  effect plan's deferred_roulette (scenes of Cycles' material models) in Cycles' order instead: the
  ray is traced either way, the emission and background it reaches count with the throughput
  before the roulette, and only the rest of the path is ended or divided, with Cycles' survival
  probability min(1, sqrt(max throughput)) (`deferred_roulette`).
* Cycles' Light Paths options (bounce limits per type, clamping, Filter Glossy, caustics): what
  they do is engine/integrators/light_paths.py; the effect plan switches them on.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..core.vec import dot, max3
from ..geometry.scene_geometry import LIGHT, QUAD, SPHERE, TRIANGLE
from ..geometry.shading_normals import compiled_for, terminator_amount
from ..materials.media import MEDIUM_STACK_DEPTH, MediumStack
from ..materials.protocol import (DELTA_LOBE, DIFFUSE_LOBE, STRAIGHT_LOBE, TRANSMISSION_LOBE, ShadingPoint,
                                  transmits_non_delta)
from ..materials.table import ABSORB, N_SCATTER_GROUPS, PASS_THROUGH, MaterialTable
from ..sampling.qmc import RandomSampler
from .delta_blur import DeltaBlur
from .light_paths import LightPaths
from .light_paths import after_diffuse as lp_after_diffuse

WAVEFRONT_SIZE = 1 << 16       # paths advanced together: 65536 measured 0.89-0.91x the time of 32768 at 256²
                               # (docs/performance.md "Speed"); images do not depend on it
SHADOW_TMAX_SCALE = 1.0 - 2.0 ** -20


VECTOR_FIELDS = ("o", "d", "beta", "radiance", "prev_p", "prev_n", "f_thru", "counts")
CAMERA_RAY, DIFFUSE_RAY, GLOSSY_RAY, TRANSMISSION_RAY = 0, 1, 2, 3   # LightPolygons.RAY_KINDS
# Dimension pairs of the sampler (engine/sampling/qmc.py): 0 is the camera jitter (engine/scene/camera_rays.py);
# the hit after bounce b uses DIMS_PER_BOUNCE pairs from 1 + DIMS_PER_BOUNCE b on.
# BSDF_UV: the direction of a non-delta lobe; CHOICES: (light pick with one shadow ray, or the
# lobe choice of the BSDF: Fresnel at glass; roulette).
LIGHT_UV, BSDF_UV, CHOICES, LIGHT_PICK = 1, 2, 3, 4          # LIGHT_PICK: with several shadow rays
DIMS_PER_BOUNCE = 4
# Caustic photons (engine/integrators/photons/): whether a camera path has made a non-delta bounce.
# Every non-delta vertex gathers the photons (the L S+ D light that reaches it); emission reached
# after such a bounce through delta bounces only is L S+ D too, the photons' own: it counts 0.
CAMERA_CHAIN, AFTER_RECEIVER = 0, 1


@dataclass
class Paths:
    """The state of the paths in the wavefront (struct of arrays; vectors as (3, N) rows)."""
    pixel: np.ndarray           # (N,) pixel of the tile the camera sample belongs to
    sample: np.ndarray          # (N,) the camera sample's number within its pixel (QMC index)
    o: np.ndarray               # (3, N) ray origins
    d: np.ndarray               # (3, N) unit ray directions
    beta: np.ndarray            # (3, N) path throughput
    radiance: np.ndarray        # (3, N) radiance L gathered so far
    prev_delta: np.ndarray      # (N,) camera ray, or the last bounce took a delta lobe: emission weight 1
    ray_kind: np.ndarray        # (N,) int8 CAMERA_RAY .. TRANSMISSION_RAY (Area lights' visibility)
    bounce: np.ndarray          # (N,) bounces made so far (0: camera ray)
    prev_p: np.ndarray | None = None    # MIS: (3, N) the last non-delta vertex, which sampled the ray
    prev_n: np.ndarray | None = None    # MIS: (3, N) its shading normal facing the ray (the light tree's input)
    prev_bsdf_pdf: np.ndarray | None = None   # MIS: (N,) its BSDF's pdf of the ray's direction
    media: np.ndarray | None = None   # nested dielectrics: (N, MEDIUM_STACK_DEPTH) IOR stack
    depth: np.ndarray | None = None   # nested dielectrics: (N,) stack height
    f_thru: np.ndarray | None = None  # passes: (3, N) tints of the delta bounces before the feature hit
    f_open: np.ndarray | None = None  # passes: (N,) still looking for its first non-delta hit
    counts: np.ndarray | None = None  # bounce limits: (4, N) diffuse, glossy, transmission, transparent bounces made
    min_pdf: np.ndarray | None = None  # Filter Glossy: (N,) the least pdf of the non-delta bounces made
    after_diffuse: np.ndarray | None = None  # caustics: (N,) the last bounce was diffuse
    lobe: np.ndarray | None = None    # light passes: (N,) int8 pass class of the first bounce (-1: none yet)
    lobe_at: np.ndarray | None = None  # light passes: (N,) the bounce that set it
    caustic: np.ndarray | None = None   # caustic photons: (N,) int8 CAMERA_CHAIN or AFTER_RECEIVER
    rr_after: np.ndarray | None = None  # deferred roulette: (N,) factor of the throughput after this ray's
    #                                     emission: 1 / survival probability, 0 = ended (the ray only emits)

    @staticmethod
    def starting(nested: bool, mis: bool, features: bool = False, light_paths: LightPaths | None = None,
                 photons: bool = False, deferred_roulette: bool = False, light_split: bool = False) -> dict:
        """What every field of a camera path but its own (pixel, sample, o, d) starts at, {name: (value,
        dtype)}, for the render's options; the fields left out stay None."""
        f64 = np.float64
        values = {"beta": (1.0, f64), "radiance": (0.0, f64), "prev_delta": (True, np.bool_), "ray_kind": (0, np.int8),
                  "bounce": (0, np.int32)}
        if mis:
            values.update(prev_p=(0.0, f64), prev_n=(0.0, f64), prev_bsdf_pdf=(1.0, f64))
        if nested:
            values.update(media=(1.0, f64), depth=(0, np.int64))
        if features:
            values.update(f_thru=(1.0, f64), f_open=(True, np.bool_))
        if light_paths is not None and light_paths.bounce_limits:
            values["counts"] = (0, np.int32)
        if light_paths is not None and light_paths.caustics:
            values["after_diffuse"] = (False, np.bool_)
        if light_paths is not None and light_paths.filter_glossy > 0:
            values["min_pdf"] = (np.inf, f64)
        if photons:
            values["caustic"] = (CAMERA_CHAIN, np.int8)
        if deferred_roulette:
            values["rr_after"] = (1.0, f64)
        if light_split:                     # engine/film/passes.py LIGHT
            values.update(lobe=(-1, np.int8), lobe_at=(0, np.int32))
        return values

    @classmethod
    def start(cls, pixel, sample, origins, directions, starting: dict) -> "Paths":
        """New camera paths: their pixels, sample numbers and rays, the other fields as `starting` says."""
        n = len(pixel)
        shapes = {"counts": (4, n), "media": (n, MEDIUM_STACK_DEPTH)}
        return cls(pixel, sample, origins, directions,
                   **{name: np.full(shapes.get(name, (3, n) if name in VECTOR_FIELDS else n), value, dtype)
                      for name, (value, dtype) in starting.items()})

    def put_start(self, at: int, pixel, sample, origins, directions, starting: dict) -> None:
        """Paths.start's camera paths written into these paths' places at .. at + len(pixel) (the room
        of `take`), without arrays of their own."""
        span = slice(at, at + len(pixel))
        self.pixel[span], self.sample[span], self.o[:, span], self.d[:, span] = pixel, sample, origins, directions
        for name, (value, _) in starting.items():
            getattr(self, name)[(slice(None),) * _AXIS[name] + (span,)] = value

    def _fields(self):
        return [(name, axis) for name, axis in _FIELD_AXES if getattr(self, name) is not None]

    def take(self, index, replaced=(), jit=None, room=0) -> "Paths":
        """The paths `index`; the fields named in `replaced` are left None, for the caller to set.
        jit: engine/integrators/wavefront_jit.py, whose compiled gathers then take them (the same arrays).
        room: each array has that many uninitialised paths more at its end, for `put` and `put_start` to
        fill (the paths that join the wavefront: no concatenation of the wavefront's arrays)."""
        kept = [(name, axis) for name, axis in self._fields() if name not in replaced]
        taken = gather(jit, [(getattr(self, name), axis) for name, axis in kept], index, room)
        return Paths(**{name: None for name in replaced}, **{name: a for (name, _), a in zip(kept, taken)})

    def put(self, start: int, other: "Paths") -> None:
        """Write the paths `other` (the same fields) into these paths' places start .. start + len(other)."""
        stop = start + len(other.pixel)
        for name, axis in self._fields():
            getattr(self, name)[(slice(None),) * axis + (slice(start, stop),)] = getattr(other, name)


_FIELD_AXES = tuple((f.name, 1 if f.name in VECTOR_FIELDS else 0) for f in fields(Paths))   # the paths' axis
_AXIS = dict(_FIELD_AXES)


def gather(jit, arrays, index, room=0):
    """[a.take(index, axis=axis) for a, axis in arrays], each with `room` uninitialised entries more at
    the end of its axis: by engine/integrators/wavefront_jit.py's compiled gathers (jit) where they
    apply (the same arrays), else NumPy's take."""
    taken = jit.take(arrays, index, room) if jit is not None else [None] * len(arrays)
    return [taken_with_room(a, index, axis, room) if t is None else t for (a, axis), t in zip(arrays, taken)]


def taken_with_room(a, index, axis, room):
    """a.take(index, axis=axis) with `room` uninitialised entries more at the end of the axis."""
    if not room:
        return a.take(index, axis=axis)
    shape = list(a.shape)
    shape[axis] = len(index) + room
    out = np.empty(shape, a.dtype)
    a.take(index, axis=axis, out=out[(slice(None),) * axis + (slice(0, len(index)),)])
    return out


def with_room(rows, room):
    """rows (3, M) with `room` uninitialised columns more (rows themselves when room is 0)."""
    if not room:
        return rows
    out = np.empty((rows.shape[0], rows.shape[1] + room), rows.dtype)
    out[:, :rows.shape[1]] = rows
    return out


def next_rays(keep, point, side, offset, facing, new_d, beta):
    """(o, d, beta) rows of the surviving paths `keep`: their hit point moved off the surface by
    `offset` along `facing` to the side they leave on (side +1 or -1), their new direction and
    throughput.  (The same in one loop: engine/integrators/wavefront_jit.py.)"""
    return (point.take(keep, axis=1) + (side.take(keep) * offset.take(keep)) * facing.take(keep, axis=1),
            new_d.take(keep, axis=1), beta.take(keep, axis=1))


def filled(buffer: np.ndarray, a) -> np.ndarray:
    """`buffer` filled with a, or a itself where it already is such an array (C-contiguous, of the
    buffer's shape and dtype): PathTracer.scatter's rows when one BSDF samples every hit (read only
    after, so the BSDF's own arrays can stand for the copies)."""
    if isinstance(a, np.ndarray) and a.dtype == buffer.dtype and a.shape == buffer.shape and a.flags.c_contiguous:
        return a
    buffer[...] = a
    return buffer


def facing_normals(d, normal, shading):
    """(facing, shade) of hits under smooth shading: the geometric normals (3, N) turned towards the rays
    d, and the shading normals on the geometric normal's side of the ray (shading only; offsets and side
    tests keep `facing`).  (The same in one loop: engine/integrators/wavefront_jit.py facing.)"""
    towards = np.where(dot(d, normal) < 0.0, 1.0, -1.0)
    return normal * towards, shading * towards


def group_of(spans, n) -> np.ndarray:
    """(n,) the scatter group of each of the first n paths, from the groups' slices."""
    return np.repeat(np.arange(len(spans)), [span.stop - span.start for span in spans])[:n]


def power_heuristic(n_f, p_f, n_g, p_g):
    """Veach's power heuristic (beta = 2) weight of technique f: (n_f p_f)^2 / sum (n p)^2.
    Overflow-safe: computed from the ratio, 1 where p_g = 0 and 0 where p_f = 0."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        r = (n_g * p_g) / (n_f * p_f)
        w = 1.0 / (1.0 + r * r)
    return np.where(p_f > 0.0, np.nan_to_num(w, nan=0.0), 0.0)


class PathTracer:
    def __init__(self, geometry, lights, materials, plan, settings, background, textures=None):
        self.geometry = geometry
        self.textures = textures          # engine/materials/textures.py HitTextures, or None (no textures)
        self.lights = lights
        self.mats = MaterialTable(materials, settings, None if textures is None else textures.has_color,
                                  plan.cycles_version)
        self.mats.use_backend(getattr(plan, "backends", {}))     # compiled material kernels (engine/core/backend.py)
        self.bsdfs = self.mats.bsdfs             # bsdfs[g] scatters scatter group g (engine/materials/table.py)
        self.plan = plan
        self.settings = settings
        self.background = np.asarray(background, dtype=np.float64)
        self.use_nee = bool(plan.direct_light and lights.count > 0)
        self.mis = bool(plan.mis and self.use_nee)
        # Under `mis` a non-delta vertex at the depth limit still traces its BSDF ray for the
        # emission it reaches (weighted by MIS, or 1 without shadow rays), so every estimator
        # counts the same paths: light reached by up to max_depth + 1 segments.
        self.final_rays = settings.estimator == "mis" and (self.mis or not self.use_nee)
        # The image world (engine/lights/environment.py EnvironmentMap) or None: the constant background.
        self.environment = getattr(lights, "environment", None)
        if self.environment is not None:    # its image lookups on the wavefront's backend
            self.environment.use_backend(getattr(plan, "backends", {}).get("wavefront", "numpy"))
        self.has_background = bool(self.background.max() > 0) or self.environment is not None
        self.world_nee = self.use_nee and lights.world is not None       # shadow rays sample the world
        self.scatter_group = self.mats.scatter_group      # of each material id
        # Where the denoising features stop looking (surface_features): non-delta BSDFs and absorbers.
        self.feature_stops = np.array(self.mats.non_delta + [True])
        self.seen_lamps = lights.seen if plan.enabled.get("seen_lamps") else None
        self.light_of_kind = {TRIANGLE: lights.triangle_light, SPHERE: lights.sphere_light,
                              QUAD: lights.quad_light, LIGHT: lights.area_light_light}
        # The same as one table for the compiled emission: light_of_kind[k][prim] = light_table[kind_base[k] + prim]
        tables = [np.asarray(self.light_of_kind.get(k, np.zeros(0)), np.int64) for k in range(max(self.light_of_kind) + 1)]
        self.light_table = np.concatenate(tables)
        self.light_kind_base = np.array([-1 if k not in self.light_of_kind else sum(len(t) for t in tables[:k])
                                         for k in range(len(tables))], np.int64)
        light_paths = LightPaths(settings, plan, self.bsdfs)
        self.light_paths = light_paths if light_paths.on else None       # Cycles' Light Paths options
        # (Clamp Direct, Clamp Indirect) for the compiled sums of the light the paths gather; None: no clamping
        self.clamp_limits = ((light_paths.limit_direct, light_paths.limit_indirect) if light_paths.on and
                             light_paths.clamping else None)
        # Filter Glossy on mirrors and smooth glass: their hits after blurry bounces scatter as GGX
        # lobes (engine/integrators/delta_blur.py), whose glossy rays leave round lamps to the shadow rays.
        self.delta_blur = DeltaBlur.of(self.mats, self.light_paths, N_SCATTER_GROUPS)
        if self.delta_blur is not None:
            self.mats.glossy = True
        self.photons = None     # engine/integrators/photons/caustics.py CausticPhotons (set by the session's prepass)
        self.deferred_rr = bool(plan.enabled.get("deferred_roulette"))
        self.wavefront_jit = None       # the compaction compiled (engine/integrators/wavefront_jit.py)
        self.normals_jit = None         # bump shadowing compiled (engine/nodes/normals_jit.py)
        if getattr(plan, "backends", {}).get("wavefront", "numpy") == "numba":
            from . import wavefront_jit
            from ..nodes import normals_jit
            self.wavefront_jit, self.normals_jit = wavefront_jit, normals_jit

    # -- the wavefront -----------------------------------------------------------------
    def trace(self, *args, **kwargs) -> bool:
        """_trace with the shading-normal fix-ups that the BSDFs and nodes call on this render's
        backend (engine/geometry/shading_normals.py compiled_for)."""
        with compiled_for(self.normals_jit is not None):
            return self._trace(*args, **kwargs)

    def _trace(self, samples, rng, counters, on_finished, cancel=None, sampler=None, features=None,
               on_transparent=None) -> bool:
        """Trace every camera sample of `samples` (engine/scene/camera_rays.py TileSamples) to
        completion: True when all are traced, False when cancelled.

        The wavefront holds up to WAVEFRONT_SIZE paths that advance one bounce per
        iteration; whenever paths end and there is room, new camera paths join it, so
        the arrays stay long and the per-call cost of NumPy is paid once per bounce of
        a full wavefront, not for the few paths left at depth 8.  Each path carries its
        pixel, throughput beta and radiance L; a finished path is handed to
        `on_finished(pixel, L, sample)` (sample: its number within its pixel).  Returns False as soon as `cancel` is set (checked every
        bounce; the paths in flight are dropped): the caller drops the whole unit
        (engine/rendering/session.py), since a partial one would keep only its short paths and
        darken its tile.  Uniform numbers come from
        `sampler` (engine/sampling/qmc.py; default: independent ones from `rng`).  `features`: an
        engine/film/passes.py TileFeatures that gets each sample's first-hit albedo, normal and depth
        (None: no feature work at all).  `on_transparent(pixel)`: a transparent film
        (engine/film/accumulator.py Film.add_transparent) that counts the camera rays that leave the
        scene, weighted by their throughput; they then get no background (None: an opaque film).
        """
        sampler = sampler or RandomSampler(rng)

        def joining(alive):
            """How many camera paths join a wavefront of `alive` paths: all there is room for, once
            there is room for a quarter of it at least, while the samples last."""
            room = WAVEFRONT_SIZE - alive
            return min(room, samples.remaining) if alive == 0 or room >= WAVEFRONT_SIZE // 4 else 0

        starting = Paths.starting(self.settings.nested_dielectrics, self.mis, features is not None and features.surface,
                                  self.light_paths, self.photons is not None, self.deferred_rr,
                                  features is not None and features.light_split)
        paths, fresh = None, joining(0)
        while True:
            if cancel is not None and cancel.is_set():
                return False
            if fresh:                       # the camera paths, into the last `fresh` places of the arrays
                rays = samples.take(fresh)
                assert len(rays[0]) == fresh, "fewer camera samples than the room they were taken for"
                if paths is None:
                    paths = Paths.start(*rays, starting)
                else:
                    paths.put_start(len(paths.pixel) - fresh, *rays, starting)
            if paths is None or len(paths.pixel) == 0:
                return True
            counters.rays["camera"] += fresh
            counters.rays["extension"] += len(paths.pixel) - fresh
            paths, fresh = self.bounce(paths, sampler, counters, on_finished, features, on_transparent, joining)

    def bounce(self, p: "Paths", sampler, counters, on_finished, features=None, on_transparent=None,
               joining=None) -> tuple:
        """Advance every path one bounce (report §2.3-2.5); returns (the survivors, fresh): the survivors'
        arrays end in `fresh` = joining(number of survivors) places for the camera paths that join the
        wavefront, which the caller fills (Paths.put_start); joining None: none."""
        finished = []                                   # (pixel, radiance, sample) of paths that end
        # 1. Intersect.  Hits sorted by scatter group (engine/materials/table.py: one per BSDF,
        # 0 diffuse, 1 mirror, 2 glass, then ABSORB and PASS_THROUGH, the Area lights), then by
        # primitive kind: every group is one slice.
        # Under MIS a non-delta vertex at the depth limit still traces its BSDF ray: that ray only
        # collects the MIS-weighted emission it reaches (the other half of that vertex's direct
        # light), then ends: its surface absorbs (as Cycles' terminate-on-next-surface).
        start_radiance = p.radiance.copy() if p.lobe is not None else None       # light passes
        hits = self.geometry.nearest_hits(p.o, p.d, counters, self.scatter_group, N_SCATTER_GROUPS,
                                          light_group=PASS_THROUGH, ray_kind=p.ray_kind,
                                          forced_group=self.final_groups(p))
        if self.delta_blur is not None:     # blurred mirror and glass hits: to their non-delta rows
            hits = self.delta_blur.regroup(hits, p.min_pdf)
        # 2. Round lamps and suns met by mirror and glass rays (engine/lights/seen.py).
        if self.seen_lamps is not None:
            self.lamps_seen(p, hits)
        # Misses: the background.
        if len(hits.miss):
            finished.append((*self.misses(p, hits.miss, on_transparent), p.sample.take(hits.miss)))
            if features is not None and features.surface:
                self.miss_features(p, hits.miss, features)
            if features is not None and features.camera_light:
                self.camera_light(p, hits.miss, finished[-1][1] - p.radiance.take(hits.miss, axis=1), "environment",
                                  features)
            if start_radiance is not None:
                self.ray_light(p, hits.miss, finished[-1][1] - start_radiance.take(hits.miss, axis=1), features)
        # The hits' paths in hits.index order; the origins only for the surface, which reads them in the
        # rays' order (compiled: through hits.index, no gather of them here).
        origins, p = p.o, p.take(hits.index, replaced=("o",), jit=self.wavefront_jit)
        surf = self.geometry.surface(origins, p.d, hits, rays_order=True)
        bounds = [start for start, _ in hits.groups] + [hits.groups[-1][1]]
        alive = bounds[ABSORB]                # the paths at a BSDF scatter on
        surfaces = bounds[PASS_THROUGH]       # absorbing surfaces end the path here
        through = slice(bounds[PASS_THROUGH], bounds[PASS_THROUGH + 1])
        spans = [slice(bounds[g], bounds[g + 1]) for g in range(ABSORB)]      # the hits of bsdfs[g]
        # Texture and node-program lookups at the hits (engine/materials/textures.py HitLookup).
        lookup = None if self.textures is None else self.textures.at(hits, self.hit_points(p, surf, hits))
        # 3. Emission found by the ray (surfaces and Area lights), MIS-weighted after non-delta bounces.
        if self.plan.emission:
            seen = (np.flatnonzero(p.ray_kind == CAMERA_RAY) if features is not None and features.camera_light
                    else None)
            before = None if seen is None else p.radiance.take(seen, axis=1)
            self.emission(p, surf, hits, surfaces, lookup)
            if seen is not None:
                self.camera_light(p, seen, p.radiance.take(seen, axis=1) - before, "emission", features)
        if start_radiance is not None:
            self.ray_light(p, np.arange(len(p.pixel)), p.radiance - start_radiance.take(hits.index, axis=1), features)
        if p.rr_after is not None:          # the deferred roulette's division, after the emission
            p.beta[:, :alive] *= p.rr_after[:alive]
            p.rr_after[:alive] = 1.0
        # 4. Area lights: the ray goes on through them, as it was.
        passing = (self.pass_through(p.take(np.arange(through.start, through.stop), replaced=("o",)), surf, through)
                   if through.stop > through.start else None)
        # 5. Direct light at hits with a non-delta BSDF (eq. 2.11).
        smooth = surf.shading is not surf.normal
        if surf.facing is not None and not smooth:      # computed with the points (the same numbers)
            facing = shade = surf.facing
        elif smooth:
            facing, shade = (facing_normals if self.wavefront_jit is None else self.wavefront_jit.facing)(
                p.d, surf.normal, surf.shading)
        else:                               # flat-only scenes: the same array
            facing = shade = surf.normal * np.where(dot(p.d, surf.normal) < 0.0, 1.0, -1.0)
        if lookup is not None and lookup.has_normals:       # a BSDF's Normal input (Normal Map, Bump)
            shade = lookup.normal(shade, surf.material, facing, -p.d, self.mats.raised_normal)
            smooth = True
        (color,) = gather(self.wavefront_jit, [(self.mats.color, 1)], surf.material)
        if lookup is not None:
            color = lookup.color(color, surf.material)
        # this hit's dimensions (int64, as the compiled sampler reads them: no copy per call)
        dim = np.multiply(p.bounce[:alive], DIMS_PER_BOUNCE, dtype=np.int64) + 1
        u_choice, u_rr = sampler.pair(p.pixel[:alive], p.sample[:alive], dim + (CHOICES - 1))
        if features is not None:
            self.surface_features(p, surf, shade, color, bounds, features, hits, lookup)   # Cycles: the shading normal
        si = ShadingPoint(-p.d[:, :alive], shade[:, :alive], facing[:, :alive], surf.normal[:, :alive],
                          color[:, :alive], surf.material[:alive], smooth,
                          None if p.media is None else MediumStack(p.media, p.depth)[:alive],
                          None if lookup is None else lookup[:alive])
        no_light = self.shade_light_paths(p, si, spans) if self.light_paths is not None else None
        before_light = p.radiance[:, :alive].copy() if p.lobe is not None else None
        caustic_light = None
        if p.caustic is not None:           # caustic photons gathered at every non-delta hit
            before = None if before_light is None else p.radiance[:, :alive].copy()
            self.gather_caustics(p, si, spans, surf, facing, counters)
            if before is not None:          # light passes: light through a specular chain is indirect
                caustic_light = p.radiance[:, :alive] - before
        for bsdf, span, non_delta in zip(self.bsdfs, spans, self.mats.non_delta):
            if self.use_nee and non_delta and span.stop > span.start:
                # (compiled Lambertian hits, unless the caustics toggles leave light samples out
                # (no_light): the sum below done in place, None returned)
                light = self.direct_light(
                    bsdf, si[span], surf.point[:, span], surf.offset[span], None, counters,
                    u=self.light_uniforms(sampler, p.pixel[span], p.sample[span], dim[span], u_choice[span]),
                    lift=self.geometry.terminator_lift(hits, span, facing) if smooth else None,
                    into=None if no_light is not None else (p.radiance, p.beta, span.start, p.bounce,
                                                            self.clamp_limits))
                if light is None:
                    continue
                light = p.beta[:, span] * light
                if self.light_paths is not None:
                    light = self.light_paths.clamp(light, p.bounce[span] == 0)
                    if no_light is not None:
                        light = np.where(no_light[span], 0.0, light)
                p.radiance[:, span] += light
        # 6. Scatter: the next direction and throughput of every scattering path (non-delta lobes
        # draw their direction from the BSDF_UV pair, delta lobes need none).
        u_bsdf = [sampler.pair(p.pixel[span], p.sample[span], dim[span] + (BSDF_UV - 1))
                  if non_delta and span.stop > span.start else None       # (scatter skips empty spans)
                  for span, non_delta in zip(spans, self.mats.non_delta)]
        new_d, side, beta = self.scatter(p, surf.point, si, spans, u_choice, u_bsdf)
        if before_light is not None:        # the shadow rays' light, by the lobe the vertex sampled
            vertex = p.radiance[:, :alive] - before_light
            if caustic_light is not None:
                self.vertex_light(p, caustic_light, features, indirect=True)
                vertex = vertex - caustic_light
            self.vertex_light(p, vertex, features)
        # 7. Russian roulette and the depth limit.
        rays = None                         # the survivors' next (o, d, beta), when 7 makes them
        if self.wavefront_jit is not None:  # 6's tail, 7 and 8's rays in one pass (side None: scatter left
            # its tail to it); either roulette
            s = self.settings
            keep, ended, *rays = self.wavefront_jit.survivors(
                p.beta if side is None else beta, p.bounce[:alive], p.prev_delta[:alive], u_rr, s.max_depth,
                self.final_rays, s.russian_roulette, s.rr_start_depth, surf.point, side, surf.offset, facing, new_d,
                beta if side is None else None, None if p.rr_after is None else p.rr_after[:alive])
        else:                               # NumPy's lines
            if p.rr_after is None:
                keep, beta = self.roulette(beta, p.bounce[:alive], p.prev_delta[:alive], u_rr)
            else:
                keep, p.rr_after[:alive] = self.deferred_roulette(beta, p.bounce[:alive], p.prev_delta[:alive],
                                                                  u_rr)
            keep, ended = np.flatnonzero(keep), np.flatnonzero(~keep)
        # 8. Compaction: hand finished paths to the film, keep the rest.
        finished += [tuple(gather(self.wavefront_jit, [(p.pixel, 0), (p.radiance, 1), (p.sample, 0)], ended)),
                     (p.pixel[alive:surfaces], p.radiance[:, alive:surfaces], p.sample[alive:surfaces])]
        pixel = np.concatenate([f[0] for f in finished])
        if len(pixel):
            on_finished(pixel, np.concatenate([f[1] for f in finished], axis=1),
                        np.concatenate([f[2] for f in finished]))
        kept, passed = len(keep), 0 if passing is None else len(passing.pixel)
        fresh = 0 if joining is None else joining(kept + passed)
        room = passed + fresh
        survivors = p.take(keep, replaced=("o", "d", "beta"), jit=self.wavefront_jit, room=room)
        survivors.o, survivors.d, survivors.beta = (with_room(a, room) for a in (
            rays if rays is not None else next_rays(keep, surf.point, side, surf.offset, facing, new_d, beta)))
        survivors.bounce[:kept] += 1
        if passing is not None:
            survivors.put(kept, passing)
        return survivors, fresh

    # -- stages ------------------------------------------------------------------------
    def final_groups(self, p):
        """The scatter group ABSORB for the rays whose hit only emits (beyond the depth limit under `mis`,
        a bounce type past its limit, ended by the deferred roulette), -1 for the others; None when none
        does (nearest_hits' forced_group).  Compiled: wavefront_jit.final_groups, the same groups."""
        limits = None if p.counts is None else self.light_paths.limits
        if self.wavefront_jit is not None:
            return self.wavefront_jit.final_groups(p.bounce, self.settings.max_depth, self.final_rays, p.counts,
                                                   limits, p.rr_after, ABSORB)
        final = p.bounce > self.settings.max_depth if self.final_rays else None
        if p.counts is not None:            # a bounce type past its limit: this hit only emits
            past = self.light_paths.past_limit(p.counts)
            final = past if final is None else final | past
        if p.rr_after is not None:          # ended by the deferred roulette: this hit only emits
            ended = p.rr_after == 0.0
            final = ended if final is None else final | ended
        return None if final is None or not final.any() else np.where(final, ABSORB, -1)

    def misses(self, p, miss, on_transparent=None):
        """Rays that leave the scene reach the background, with weight 1 (the report), unless
        the world is a light (shadow rays sample it): then a ray sampled at a non-delta vertex
        (the final MIS rays beyond the depth limit included) counts with its MIS weight, or 0
        without MIS.  A transparent film takes the camera rays (Area lights pass them on) instead:
        weight 0, counted by on_transparent with their mean throughput (Cycles' average(throughput):
        1 for a camera ray).  Compiled (an opaque film, no caustic photons): the weights, the clamp and the
        sum in engine/integrators/wavefront_jit.py (background_light), the same numbers."""
        if self.wavefront_jit is not None and on_transparent is None and p.caustic is None and self.has_background:
            return p.pixel.take(miss), self.background_light(self.wavefront_jit, p, miss)
        radiance = p.radiance.take(miss, axis=1)
        camera = None
        if on_transparent is not None:
            camera = p.ray_kind.take(miss) == CAMERA_RAY
            seen = miss[camera]
            on_transparent(p.pixel.take(seen), p.beta.take(seen, axis=1).mean(axis=0))
        if self.has_background:
            weight = np.ones(len(miss))
            if camera is not None:
                weight[camera] = 0.0
            if self.world_nee:
                delta = p.prev_delta.take(miss)
                weight[~delta] = 0.0
                if self.mis:
                    sampled = np.flatnonzero(~delta)
                    m = miss.take(sampled)
                    p_world = self.lights.world_pdf(p.prev_n.take(m, axis=1), p.d.take(m, axis=1))
                    weight[sampled] = power_heuristic(1.0, p.prev_bsdf_pdf.take(m), float(self.settings.shadow_rays),
                                                      p_world)
            if p.caustic is not None and self.lights.world is not None:      # the world emits photons too
                weight[self.photons_own(p, miss)] = 0.0
            radiance += self.clamped(p.beta.take(miss, axis=1) * self.background_seen(p, miss) * weight,
                                     p.bounce.take(miss))
        return p.pixel.take(miss), radiance

    def background_light(self, jit, p, miss):
        """misses' radiance (3, len(miss)) of the paths `miss` in wavefront_jit's loops: the world's pdfs
        are the one call between them."""
        mode, places, p_world = 0, np.zeros(0, np.int64), np.zeros(0)
        if self.world_nee and not self.mis:
            mode = 1
        elif self.world_nee:
            mode = 2
            places = jit.sampled(miss, p.prev_delta)
            if len(places):
                m = miss.take(places)
                p_world = self.lights.world_pdf(p.prev_n.take(m, axis=1), p.d.take(m, axis=1))
        return jit.background_light(p.radiance, p.beta, miss, self.background_seen(p, miss), p.prev_delta,
                                    p.prev_bsdf_pdf, places, p_world, mode, self.settings.shadow_rays, p.bounce,
                                    self.clamp_limits)

    def background_seen(self, p, miss):
        """What the rays `miss` see where they leave the scene: the constant background (3, 1), or
        the image world's radiance along each ray (3, M), camera rays their own."""
        if self.environment is None:
            return self.background[:, None]
        return self.environment.seen(p.d.take(miss, axis=1), p.ray_kind.take(miss) == CAMERA_RAY, self.background)

    def lamps_seen(self, p, hits):
        """Emission of point, spot and sun lights reached by glossy and transmission rays before
        their hit, after a delta bounce (weight 1: shadow rays could not have found them there).
        After a glossy (non-delta) bounce the shadow rays account for these lamps, which a BSDF
        sample cannot reach in their MIS (LightSet.bsdf_reachable): the ray's lamp counts 0
        then, unless there are no shadow rays."""
        seen = (p.ray_kind == GLOSSY_RAY) | (p.ray_kind == TRANSMISSION_RAY)
        if self.use_nee and self.mats.glossy:
            seen &= p.prev_delta
        rays = np.flatnonzero(seen)
        if not len(rays):
            return
        tmax = np.full(len(p.pixel), np.inf)
        tmax[hits.index] = hits.t
        le = self.seen_lamps.radiance(p.o.take(rays, axis=1), p.d.take(rays, axis=1), tmax.take(rays),
                                      p.ray_kind.take(rays) == TRANSMISSION_RAY)
        if p.caustic is not None:
            le = np.where(self.photons_own(p, rays), 0.0, le)
        p.radiance[:, rays] += self.clamped(p.beta.take(rays, axis=1) * le, p.bounce.take(rays))

    def hit_points(self, p, surf, hits):
        """What node programs read of the hits besides their primitives (engine/nodes/context.py
        HitPoints); None when no material has a program."""
        if self.textures is None or self.textures.attributes is None:
            return None
        from ..nodes.context import HitPoints
        return HitPoints(point=surf.point, direction=p.d, normal=surf.normal, shading=surf.shading,
                         depth=p.bounce, ray_kind=p.ray_kind, distance=hits.t)

    def bump_shadowing(self, si, wi, diffuse, is_eval, repeat=1):
        """engine/nodes/normals.py bump_shadowing of directions wi (3, len(si) x repeat) at hits whose
        normal a Normal input replaced: against their smooth normal (from the lookup's HitPoints)."""
        from ..nodes.normals import bump_shadowing
        points = si.lookup.points
        if points is None:
            return np.ones(wi.shape[1])
        version = self.textures.textures.cycles_version
        if self.normals_jit is not None and tuple(version) >= (4, 0):       # the lines below in one loop
            return self.normals_jit.bump_shadowing(points.direction, points.normal, points.shading, si.n, wi,
                                                   diffuse, is_eval, repeat)
        towards = np.where(dot(points.direction, points.normal) < 0.0, 1.0, -1.0)
        smooth = (points.shading if points.shading is not None else points.normal) * towards
        n = si.n
        if repeat > 1:
            smooth, n = np.repeat(smooth, repeat, axis=1), np.repeat(n, repeat, axis=1)
        return bump_shadowing(smooth, n, wi, diffuse, is_eval, version)

    def emission(self, p, surf, hits, surfaces, lookup=None):
        """Add emission at emissive surfaces and front faces of Area lights, weighted: 1 after
        the camera or a delta bounce or without shadow rays; after a non-delta bounce 0 under
        `report`/`solid-angle`, the power-heuristic weight under `mis`.  Compiled (without caustic
        photons): the weights, the clamp and the sum in engine/integrators/wavefront_jit.py
        (emitter_lights, add_emission), the same numbers."""
        mat = surf.material
        lit = np.flatnonzero(self.mats.is_emissive.take(mat[:surfaces]))
        parts = [(lit, self.mats.emission.take(mat.take(lit), axis=1))] if len(lit) else []
        if parts and self.textures is not None:
            parts[0] = (lit, self.textures.emission(parts[0][1], mat.take(lit), hits.kind.take(lit),
                                                    hits.prim.take(lit), hits.u.take(lit), hits.v.take(lit),
                                                    None if lookup is None or lookup.points is None
                                                    else lookup.points.take(lit)))
        for (group, kind), (a, b) in hits.runs.items():
            if group == PASS_THROUGH:
                lamps, prim = self.geometry.lights, hits.prim[a:b]
                front = lamps.two_sided.take(prim) | (dot(p.d[:, a:b], surf.normal[:, a:b]) < 0.0)
                idx = np.arange(a, b)[front]
                if len(idx):
                    parts.append((idx, lamps.radiance.take(prim[front], axis=1)))
        jit = self.wavefront_jit
        if jit is not None and p.caustic is None:
            for idx, le in parts:
                self.add_emission(jit, p, surf, hits, idx, le)
            return
        for idx, le in parts:
            weight = self.emission_weight(p, surf, hits, idx)
            if p.caustic is not None:
                weight = np.where(self.photons_own(p, idx), 0.0, weight)
            p.radiance[:, idx] += self.clamped(p.beta.take(idx, axis=1) * le * weight, p.bounce.take(idx))

    def add_emission(self, jit, p, surf, hits, idx, le):
        """emission's sum of le (3, len(idx)) into the paths idx weighted by emission_weight, in
        wavefront_jit's loops: the lights' pdfs are the one call between them."""
        mode, places, p_light = 0, np.zeros(0, np.int64), np.zeros(0)
        if self.use_nee and not self.mis:
            mode = 1
        elif self.use_nee:
            mode = 2
            places, light = jit.emitter_lights(idx, p.prev_delta, hits.kind, hits.prim, self.light_table,
                                               self.light_kind_base)
            if len(places):
                h = idx.take(places)
                p_light = self.lights.pdf(p.prev_p.take(h, axis=1), p.prev_n.take(h, axis=1), light,
                                          surf.point.take(h, axis=1))
        jit.add_emission(p.radiance, p.beta, idx, le, p.prev_delta, p.prev_bsdf_pdf, places, p_light, mode,
                         self.settings.shadow_rays, p.bounce, self.clamp_limits)

    def emission_weight(self, p, surf, hits, idx):
        delta = p.prev_delta.take(idx)
        if not self.use_nee or delta.all():
            return 1.0
        if not self.mis:
            return delta.astype(np.float64)
        weight = np.ones(len(idx))
        sel = np.flatnonzero(~delta)
        hit = idx.take(sel)
        kind, prim = hits.kind.take(hit), hits.prim.take(hit)
        light = np.full(len(hit), -1, dtype=np.int64)
        for k, table in self.light_of_kind.items():
            mine = np.flatnonzero(kind == k)
            if len(mine):
                light[mine] = table.take(prim.take(mine))
        known = light >= 0                  # an emitter the light sampler has (always, here)
        p_light = np.zeros(len(hit))
        if known.any():
            j = np.flatnonzero(known)
            h = hit.take(j)
            p_light[j] = self.lights.pdf(p.prev_p.take(h, axis=1), p.prev_n.take(h, axis=1), light.take(j),
                                         surf.point.take(h, axis=1))
        weight[sel] = power_heuristic(1.0, p.prev_bsdf_pdf.take(hit), float(self.settings.shadow_rays), p_light)
        return weight

    # -- render passes (engine/film/passes.py) ------------------------------------------------
    def miss_features(self, p, miss, features):
        """A path still without a feature hit that leaves the scene: the background's radiance
        times its delta-bounce tints is its albedo (Cycles: film_write_emission_or_background_pass);
        its normal stays 0."""
        idx = miss[p.f_open.take(miss)]
        if len(idx) and self.has_background:
            features.add_albedo(p.pixel.take(idx), p.f_thru.take(idx, axis=1) * self.background_seen(p, idx))

    def camera_light(self, p, idx, radiance, name, features):
        """The Emission or Environment pass: what the paths `idx` gathered at this stage, for those
        still camera rays (Cycles' "directly visible", before PATH_RAY_ANY_PASS; Area lights and
        straight pass-throughs keep a camera ray one)."""
        camera = np.flatnonzero(p.ray_kind.take(idx) == CAMERA_RAY)
        if len(camera):
            features.add_camera_light(name, p.pixel.take(idx.take(camera)), radiance.take(camera, axis=1))

    def first_lobe(self, p, flags):
        """Light passes: the pass class of each path's first non-straight bounce (Cycles' pass_diffuse_weight
        and pass_glossy_weight, set at bounce 0): diffuse lobes (translucent too) -> diffuse, other
        reflections -> glossy, other transmissions -> transmission (engine/film/passes.py LIGHT)."""
        alive = len(flags)
        new = (p.lobe[:alive] < 0) & ((flags & STRAIGHT_LOBE) == 0)
        if new.any():
            cls = np.where((flags & DIFFUSE_LOBE) != 0, 0, np.where((flags & TRANSMISSION_LOBE) != 0, 2, 1))
            p.lobe[:alive] = np.where(new, cls, p.lobe[:alive])
            p.lobe_at[:alive] = np.where(new, p.bounce[:alive], p.lobe_at[:alive])

    def ray_light(self, p, idx, radiance, features):
        """Light passes: emission and background a ray found (radiance rows of the paths `idx`):
        Direct after the first bounce, Indirect after more; camera rays' is Emission / Environment."""
        lobe = p.lobe.take(idx)
        on = np.flatnonzero(lobe >= 0)
        if len(on):
            direct = p.bounce.take(idx.take(on)) == p.lobe_at.take(idx.take(on)) + 1
            features.add_light(lobe.take(on), direct, p.pixel.take(idx.take(on)), radiance.take(on, axis=1))

    def vertex_light(self, p, radiance, features, indirect=False):
        """Light passes: the shadow rays' light at the first len(radiance) paths' vertices: Direct at
        the vertex that set the path's class, Indirect after it (and always with `indirect`: gathered
        caustic photons, light that came through a specular chain)."""
        alive = radiance.shape[1]
        lobe = p.lobe[:alive]
        on = np.flatnonzero((lobe >= 0) & (radiance != 0.0).any(axis=0))
        if len(on):
            direct = (p.bounce.take(on) == p.lobe_at.take(on)) & (not indirect)
            features.add_light(lobe.take(on), direct, p.pixel.take(on), radiance.take(on, axis=1))

    def surface_features(self, p, surf, facing, color, bounds, features, hits=None, lookup=None):
        """Cycles' denoising features (film_write_denoising_features_surface): at the first hit with
        a non-delta BSDF (diffuse) or an absorbing one write albedo = the delta-bounce tints x
        colour and the facing normal, then stop; at delta BSDFs (mirrors, glass) multiply the tints
        by the colour and look further.  Emission seen on the way adds its radiance (unclipped, as
        Cycles).  Depth: every camera ray's first surface."""
        surfaces = bounds[PASS_THROUGH]
        first = np.flatnonzero(p.bounce[:surfaces] == 0)
        if len(first):
            features.add_depth(p.pixel.take(first), surf.point.take(first, axis=1))
        if features.first_hit is not None and len(first):      # Cycles' data passes (film_write_data_passes)
            n_first = facing.take(first, axis=1)
            features.add_first_hit(p.pixel.take(first), p.sample.take(first), surf.point.take(first, axis=1),
                                   n_first, surf.material.take(first), hits.kind.take(first),
                                   hits.prim.take(first), hits.u.take(first), hits.v.take(first),
                                   color.take(first, axis=1), -dot(p.d.take(first, axis=1), n_first))
        if not features.surface:                 # depth only
            return
        idx = np.flatnonzero(p.f_open[:surfaces])
        if not len(idx):
            return
        group = np.searchsorted(np.asarray(bounds), idx, side="right") - 1
        mat, pix, thru = surf.material.take(idx), p.pixel.take(idx), p.f_thru.take(idx, axis=1)
        emissive = self.mats.is_emissive.take(mat)
        if emissive.any():
            e = np.flatnonzero(emissive)
            le = self.mats.emission.take(mat.take(e), axis=1)
            if self.textures is not None and hits is not None:         # textured emitters: per hit
                h = idx.take(e)
                le = self.textures.emission(le, mat.take(e), hits.kind.take(h), hits.prim.take(h), hits.u.take(h),
                                            hits.v.take(h), None if lookup is None or lookup.points is None
                                            else lookup.points.take(h))
            features.add_albedo(pix.take(e), thru.take(e, axis=1) * le)
        stop = self.feature_stops.take(group)
        absorbs = group == ABSORB
        scatters = np.flatnonzero(stop & ~absorbs)
        if len(scatters):
            features.add_albedo(pix.take(scatters),
                                thru.take(scatters, axis=1) * color.take(idx.take(scatters), axis=1))
        normal = np.flatnonzero(stop & ~(emissive & absorbs))     # emitters only: normal 0, as Cycles
        if len(normal):
            features.add_normal(pix.take(normal), facing.take(idx.take(normal), axis=1))
        p.f_open[idx[stop]] = False
        delta = np.flatnonzero(~stop)
        if len(delta):
            p.f_thru[:, idx[delta]] = thru.take(delta, axis=1) * color.take(idx.take(delta), axis=1)

    def pass_through(self, through: "Paths", surf, span):
        """Paths that reached an Area light continue behind it, direction and state unchanged."""
        if span.stop == span.start:
            return None
        point, offset = surf.point[:, span], surf.offset[span]
        through.o = point + offset * through.d
        return through

    def light_uniforms(self, sampler, pixel, sample, dim, u_choice):
        """(pick, u1, u2) for the N_s shadow rays of each diffuse hit: ray j of sample s is
        point s N_s + j of the light dimensions, so a pixel's light samples stay one net.
        With one shadow ray the pick is the hit's choice number (u_choice)."""
        ns = self.settings.shadow_rays
        if ns == 1:
            u1, u2 = sampler.pair(pixel, sample, dim + (LIGHT_UV - 1))
            return u_choice, u1, u2
        pixel, dim = np.repeat(pixel, ns), np.repeat(dim, ns)
        sample = np.repeat(sample * ns, ns) + np.tile(np.arange(ns), len(sample))
        u1, u2 = sampler.pair(pixel, sample, dim + (LIGHT_UV - 1), light=True)
        pick, _ = sampler.pair(pixel, sample, dim + (LIGHT_PICK - 1), light=True)
        return pick, u1, u2

    def scatter(self, p, point, si, spans, u_lobe, u_dir):
        """New directions, the side to leave on (+1 facing, -1 through) and throughputs of the
        paths at a BSDF (the first len(si) of `p`): bsdfs[g].sample on the hits spans[g], with the
        lobe uniforms u_lobe and the direction pairs u_dir[g] (None for delta-only BSDFs); updates
        the paths' ray kinds and their delta / MIS state (point: the hit points).

        Under smooth shading a direction on the wrong side of the geometric surface for its lobe
        (a reflection below it, a transmission not through it) ends the path
        (engine/geometry/shading_normals.py).  Returns (new_d, side, beta); where the compiled bounce
        runs the tail below in its compaction's pass (wavefront_jit.survivors), (new_d, None, that
        tail's other inputs) instead."""
        alive = len(si)
        new_d = np.empty((3, alive))
        value = np.empty((3, alive))
        flags = np.empty(alive, dtype=np.int8)
        pdf = np.empty(alive) if p.min_pdf is not None else None
        normals = si.lookup is not None and si.lookup.has_normals
        split = None            # a Normal input on diffuse and glossy closures in one BSDF: its diffuse part / pdf
        for g, span in enumerate(spans):
            if span.stop == span.start:
                continue
            s = self.bsdfs[g].sample(si[span], u_lobe[span], u_dir[g])
            if span.stop - span.start == alive:      # one BSDF for all: its arrays, not copies
                new_d, value, flags = filled(new_d, s.wi), filled(value, s.value), filled(flags, s.flags)
            else:
                new_d[:, span], value[:, span], flags[span] = s.wi, s.value, s.flags
            part = self.bsdfs[g].diffuse_part(si[span], s.wi) if normals else None
            if part is not None:
                if split is None:
                    split, diffuse_part = np.zeros(alive, dtype=bool), np.zeros((3, alive))
                split[span] = True
                with np.errstate(divide="ignore", invalid="ignore"):
                    diffuse_part[:, span] = np.where(s.pdf > 0.0, part / s.pdf, 0.0)
            if pdf is not None:
                pdf[span] = s.pdf
            if self.mis and self.mats.non_delta[g]:          # MIS: the vertex and pdf of non-delta samples
                delta = (s.flags & DELTA_LOBE) != 0
                if delta.any():                 # a BSDF with delta lobes too: its non-delta samples
                    local = np.flatnonzero(~delta)
                    sampled = span.start + local
                else:                           # slices, no copies
                    local, sampled = slice(None), span
                p.prev_p[:, sampled] = point[:, sampled]
                p.prev_n[:, sampled] = si.n[:, sampled]
                p.prev_bsdf_pdf[sampled] = s.pdf[local]
        if self.light_paths is not None:
            value = self.scatter_light_paths(p, spans, flags, pdf, value)
        if self.wavefront_jit is not None and p.lobe is None and p.caustic is None and not normals:
            # the lines below in the compaction's pass (bounce: wavefront_jit.survivors)
            return new_d, None, (flags, p.ray_kind[:alive], value, si.ng if si.smooth else None)
        transmitted = (flags & TRANSMISSION_LOBE) != 0
        if p.lobe is not None:
            self.first_lobe(p, flags)
        p.prev_delta[:alive] = (flags & DELTA_LOBE) != 0
        if p.caustic is not None:
            p.caustic[:alive] = np.where(p.prev_delta[:alive], p.caustic[:alive], AFTER_RECEIVER)
        kind = np.where(transmitted, TRANSMISSION_RAY, np.where((flags & DIFFUSE_LOBE) != 0, DIFFUSE_RAY, GLOSSY_RAY))
        # A straight pass-through (alpha) keeps a camera ray a camera ray (Area lights' visibility, as Cycles).
        p.ray_kind[:alive] = np.where(((flags & STRAIGHT_LOBE) != 0) & (p.ray_kind[:alive] == CAMERA_RAY),
                                      CAMERA_RAY, kind)
        side = np.where(transmitted, -1.0, 1.0)
        beta = p.beta[:, :alive] * value             # eq. 2.14 (f cos / pdf = colour), 2.16, glass tint
        if si.lookup is not None and si.lookup.has_normals:     # a Normal input: Cycles' bump shadowing
            shadowing = self.bump_shadowing(si, new_d, (flags & DIFFUSE_LOBE) != 0, False)
            if split is None:
                beta = beta * shadowing
            else:                               # per closure, as Cycles: the glossy part and the diffuse part
                glossy = self.bump_shadowing(si, new_d, np.zeros(alive, dtype=bool), False)
                soft = self.bump_shadowing(si, new_d, np.ones(alive, dtype=bool), False)
                split_value = glossy * (value - diffuse_part) + soft * diffuse_part
                beta = p.beta[:, :alive] * np.where(split, split_value, shadowing * value)
        if si.smooth:                       # below the geometric surface (or not through it): ends
            wrong = dot(new_d, si.ng) * side <= 0.0
            if wrong.any():
                beta = np.where(wrong, 0.0, beta)
        return new_d, side, beta

    # -- caustic photons (engine/integrators/photons/) ---------------------------------------------
    @staticmethod
    def photons_own(p, idx):
        """(len(idx),) whether the emission the paths idx reach belongs to the photon map: a ray after
        a delta bounce, with a non-delta bounce before it on the path (L S+ D, gathered at D)."""
        return (p.caustic.take(idx) == AFTER_RECEIVER) & p.prev_delta.take(idx)

    def gather_caustics(self, p, si, spans, surf, facing, counters):
        """Add beta x the caustic photons' radiance at every hit with a non-delta BSDF, from photons
        whose paths keep the whole path within the depth limit."""
        for g, span in enumerate(spans):
            if not self.mats.non_delta[g] or span.stop == span.start:
                continue
            # The path tracer's paths have up to max_depth + 1 segments; this vertex ends bounce + 1.
            caustic = self.photons.radiance(p.sample[span], self.bsdfs[g], si[span], surf.point[:, span],
                                            facing[:, span], counters, self.settings.max_depth - p.bounce[span],
                                            p.caustic[span] == AFTER_RECEIVER,
                                            None if p.counts is None else self.light_paths.chain_budget(
                                                p.counts[:, span], self.bsdfs[g].flags))
            p.radiance[:, span] += p.beta[:, span] * caustic

    # -- Cycles' Light Paths options (engine/integrators/light_paths.py) ---------------------------
    def clamped(self, contribution, bounce):
        """Emission and background reached after `bounce` bounces (N,): clamped as direct light up
        to one bounce, as indirect after more (Cycles' bounce - 1 <= 0)."""
        if self.light_paths is None:
            return contribution
        return self.light_paths.clamp(contribution, bounce <= 1)

    def shade_light_paths(self, p, si, spans):
        """Before direct light: the alpha floor of Filter Glossy and the lobes the caustics
        toggles leave out, onto `si`; returns the hits that take no light samples (or None)."""
        lp, alive = self.light_paths, len(si)
        if p.min_pdf is not None:
            si.alpha_floor = lp.alpha_floor(p.min_pdf[:alive])
        if not lp.caustics:
            return None
        after_diffuse = p.after_diffuse[:alive]
        si.glossy_off = lp.glossy_off(after_diffuse)
        return lp.no_light_samples(group_of(spans, alive), after_diffuse)

    def scatter_light_paths(self, p, spans, flags, pdf, value):
        """After sampling: count the bounce types, keep the least non-delta pdf, and drop the
        samples of the lobes the caustics toggles leave out (their throughput 0 ends the path)."""
        lp, alive = self.light_paths, len(flags)
        if p.counts is not None and self.wavefront_jit is not None and p.counts.flags.c_contiguous:
            self.wavefront_jit.count_bounces(p.counts, flags)           # the line below in one loop
        elif p.counts is not None:
            lp.count(p.counts[:, :alive], flags)
        if pdf is not None:
            non_delta = (flags & DELTA_LOBE) == 0
            p.min_pdf[:alive] = np.where(non_delta, np.minimum(p.min_pdf[:alive], pdf), p.min_pdf[:alive])
        if lp.caustics:
            after_diffuse = p.after_diffuse[:alive]
            group = group_of(spans, alive)
            drop = lp.dropped_samples(group, after_diffuse, flags) | lp.no_closure(group, after_diffuse)
            if drop.any():
                value = np.where(drop, 0.0, value)
            p.after_diffuse[:alive] = lp_after_diffuse(flags, after_diffuse)
        return value

    def roulette(self, beta, bounce, delta, u):
        """Which paths go on (report 2.4) and their throughput after the survival division.
        Under `mis` a non-delta bounce at the depth limit goes on for its emission (see `bounce`).
        (Compiled with the compaction: engine/integrators/wavefront_jit.py survivors.)"""
        s = self.settings
        within = bounce < s.max_depth
        if self.final_rays:
            within |= (bounce == s.max_depth) & ~delta
        keep = (max3(beta) > 0.0) & within
        if s.russian_roulette:
            survive_p = np.where(bounce + 1 >= s.rr_start_depth, np.minimum(max3(beta), 1.0), 1.0)
            keep &= u < survive_p
            beta = beta / np.where(keep, survive_p, 1.0)
        return keep, beta

    def deferred_roulette(self, beta, bounce, delta, u):
        """Russian roulette in Cycles' order (kernel/integrator/intersect_closest.h, shade_surface.h
        integrate_surface_terminate): (which paths trace their next ray, the factor (N,) their
        throughput takes after the emission that ray reaches: 1 / survival probability, or 0 for
        the paths the roulette ends, whose next hit then only emits).  The survival probability is
        Cycles' (path_state_continuation_probability), min(1, sqrt(max throughput)), from the bounce
        `rr_start_depth` on as `roulette`; the throughput is left as it is until that emission is counted.
        (Compiled with the compaction: engine/integrators/wavefront_jit.py survivors(rr_after).)"""
        s = self.settings
        within = bounce < s.max_depth
        if self.final_rays:
            within |= (bounce == s.max_depth) & ~delta
        keep = (max3(beta) > 0.0) & within
        survive_p = np.where(bounce + 1 >= s.rr_start_depth, np.minimum(np.sqrt(max3(beta)), 1.0), 1.0)
        with np.errstate(divide="ignore"):
            after = np.where(u < survive_p, 1.0 / survive_p, 0.0)
        return keep, after

    # -- direct light, eq. 2.11 ---------------------------------------------------------
    def direct_light(self, bsdf, si, point, offset, rng, counters, u=None, lift=None, into=None):
        """<L_direct> with N_s shadow rays per point, divided by N_s: rows (3, M).

        bsdf: the BSDF of the M hits `si` (an engine/materials/protocol.py ShadingPoint), whose
        shading normals si.n face the viewer; point rows (3, M), offset (M,).  Each sample adds
        Le f cos(theta_x) V / p_l (eq. 2.11 written per unit solid angle: with
        p_l = P(k) d^2 / (A cos(theta_y)) it is the report's Le f G V A / P(k)), times the
        MIS weight under `mis` (p_b = bsdf.pdf).  A Lambertian BSDF (f = rho / pi everywhere,
        bsdf.lambert_albedo) has its f multiplied in after the mean over the shadow rays, as the
        report writes it; any other has f cos = bsdf.eval per shadow ray.  Light comes from the
        viewer's side, and from the far side for a BSDF with a non-delta transmission lobe (its shadow
        rays then start on that side).  u: (pick, u1, u2) per shadow ray, else
        drawn from rng.  Smooth shading (si.smooth): shadow rays start off the geometric surface
        si.ng and directions below it count 0 (no light leaks, engine/geometry/shading_normals.py).
        lift: (lift rows, cutoff) per point, the shadow-terminator geometry offset of smooth
        triangles (Cycles' shadow_ray_offset).  into: (radiance, beta, start, bounce, clamp), the path
        state's rows, the first path of these hits and PathTracer.clamp_limits (None: no clamping):
        where the compiled Lambertian case runs (lambert_direct_light) it adds beta x its light into
        radiance in place (the caller's product and sum) and returns None."""
        ns = self.settings.shadow_rays
        m = point.shape[1]
        k = m * ns
        albedo = bsdf.lambert_albedo(si)
        # Shadow ray j of point i is column i * ns + j.
        x = np.repeat(point, ns, axis=1) if ns > 1 else point
        nx = np.repeat(si.n, ns, axis=1) if ns > 1 else si.n
        off_x = np.repeat(offset, ns) if ns > 1 else offset
        ng = nx if not si.smooth else (np.repeat(si.ng, ns, axis=1) if ns > 1 else si.ng)
        u_pick, u1, u2 = u if u is not None else (rng.random(k), rng.random(k), rng.random(k))
        compiled = (self.wavefront_jit is not None and albedo is not None and ns == 1 and not si.smooth
                    and not transmits_non_delta(bsdf.flags) and (si.lookup is None or not si.lookup.has_normals))
        if compiled:        # the compiled kernels read contiguous rows: one copy of a span's, not one per kernel
            x, nx = np.ascontiguousarray(x), np.ascontiguousarray(nx)
        ls = self.lights.sample(x, nx, u_pick, u1, u2)
        if self.textures is not None:                   # textured emitters: Le at the sampled point
            ls.radiance = self.textures.light_radiance(ls.radiance, ls.light, ls.point)
        if compiled:
            return self.lambert_direct_light(bsdf, si, x, nx, offset, ls, counters, albedo, into)
        w = ls.direction
        cos_x = dot(nx, w)
        # A non-delta transmission lobe takes light from the far side too: side -1 there, and the
        # viewer-side tests below hold for the side the sample is on.
        side = np.where(cos_x < 0.0, -1.0, 1.0) if transmits_non_delta(bsdf.flags) else None
        cos_side = cos_x if side is None else cos_x * side
        cos_ly = dot(ls.normal, w)
        ok = (cos_side > 0.0) & (cos_ly != 0.0) & (ls.pdf > 0.0) & (ls.distance > 0.0)
        if self.lights.any_one_sided:                   # front side only: emits towards -w
            ok &= ~(ls.one_sided & (cos_ly >= 0.0))
        amount = None
        if si.smooth:
            # Below the geometric surface: no light, unless the shadow-terminator lift moves the
            # shadow ray's origin up onto the smooth surface (Cycles: it is then traced from there).
            ng_w = dot(ng, w) if side is None else dot(ng, w) * side
            if lift is not None:
                s_vec, cutoff = (np.repeat(lift[0], ns, axis=1), np.repeat(lift[1], ns)) if ns > 1 else lift
                amount = terminator_amount(cos_side, ng_w, cutoff)
                if side is not None:                # no lift for light from the far side
                    amount = np.where(side > 0.0, amount, 0.0)
                ok &= (ng_w > 0.0) | (amount > 0.0)
            else:
                ok &= ng_w > 0.0
        valid = np.flatnonzero(ok)
        everything = len(valid) == k

        def pick(a, axis=0):                          # the valid samples (no copy if all are)
            return a if everything else a.take(valid, axis=axis)
        weight = np.zeros(k)
        f_cos = None if albedo is not None else np.zeros((3, k))
        if len(valid):
            # From the point lifted off its surface (grazing light on a smooth triangle: lifted by the
            # terminator offset too) to the light's point pulled off the light towards x, so the light
            # never occludes itself; the world is at infinity: its shadow rays run to t = inf.
            origin, direction, seg_len = self.lights.shadow_rays(
                ls, None if everything else valid, x, off_x if side is None else off_x * side, ng, cos_ly,
                None if amount is None else (amount, s_vec))
            counters.rays["shadow"] += len(valid)
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            cos, pdf = pick(cos_x), pick(ls.pdf)

            def at_valid():                         # the hit of each valid ray
                return si if everything and ns == 1 else si.take(valid // ns)
            if albedo is not None:                  # Lambertian: f = rho / pi comes in after the mean
                sample = cos / pdf                                              # cos V / p_l
                p_b = None
                if self.mis and ns == 1:            # its pdf is per ray: at every sample, then picked
                    with np.errstate(invalid="ignore", over="ignore"):     # (no copy of the hits)
                        p_b = pick(bsdf.pdf(si, w))
                elif self.mis:
                    p_b = bsdf.pdf(at_valid(), pick(w, 1))
            else:
                f_cos[:, valid], p_b = bsdf.eval(at_valid(), pick(w, 1))
                sample = 1.0 / pdf                                              # V / p_l
            if self.mis:                            # lights a BSDF sample cannot reach: weight 1
                p_bsdf = np.where(self.lights.bsdf_reachable.take(pick(ls.light)), p_b, 0.0)
                sample *= power_heuristic(float(ns), pdf, 1.0, p_bsdf)
            weight[valid] = np.where(blocked, 0.0, sample)
        if si.lookup is not None and si.lookup.has_normals:     # a Normal input: Cycles' bump shadowing
            diffuse = ~self.mats.specular_normal.take(si.material)
            shadowing = self.bump_shadowing(si, w, np.repeat(diffuse, ns) if ns > 1 else diffuse, True, ns)
            weight *= shadowing
            part = bsdf.diffuse_part(at_valid(), pick(w, 1)) if f_cos is not None and len(valid) else None
            if part is not None:
                # Diffuse and glossy closures in one BSDF (the Principled): the diffuse ones take the
                # diffuse term, per closure as Cycles' bsdf_eval
                soft = self.bump_shadowing(si, w, np.ones(k, dtype=bool), True, ns)
                with np.errstate(divide="ignore", invalid="ignore"):
                    scale = np.where(shadowing > 0.0, soft / shadowing - 1.0, 0.0)
                f_cos[:, valid] += pick(scale) * part
        contrib = ls.radiance * weight if albedo is not None else ls.radiance * weight * f_cos
        mean = contrib.reshape(3, m, ns).sum(axis=2) / ns if ns > 1 else contrib
        if albedo is None:
            return mean
        return mean * albedo * (1.0 / np.pi)                            # f_r = colour / pi (eq. 2.13a)

    def lambert_direct_light(self, bsdf, si, point, n, offset, ls, counters, albedo, into=None):
        """direct_light's Lambertian case with one shadow ray per hit, flat shading and no Normal
        input, for the light samples ls: the same tests, shadow rays and weights in two compiled
        loops around the shadow rays (engine/integrators/wavefront_jit.py light_tests and
        lambert_light), the same numbers.  point, n: the hits' points and si.n as contiguous rows; into:
        direct_light's (None unless the path state's rows are C-contiguous)."""
        jit = self.wavefront_jit
        cos_x, cos_ly, valid = jit.light_tests(n, ls, self.lights.any_one_sided)
        k = len(cos_x)
        blocked, p_b = np.zeros(0, dtype=bool), 0.0
        if len(valid):
            origin, direction, seg_len = self.lights.shadow_rays(ls, None if len(valid) == k else valid, point,
                                                                 offset, n, cos_ly)
            counters.rays["shadow"] += len(valid)
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            if self.mis and bsdf.cosine_pdf:        # the kernel takes it from cos_x (the same numbers)
                p_b = None
            elif self.mis:
                with np.errstate(invalid="ignore", over="ignore"):
                    p_b = bsdf.pdf(si, ls.direction)
        if into is not None and not (into[0].flags.c_contiguous and into[1].flags.c_contiguous):
            into = None
        return jit.lambert_light(valid, blocked, cos_x, ls, p_b, self.lights.bsdf_reachable, self.mis, albedo, into)
