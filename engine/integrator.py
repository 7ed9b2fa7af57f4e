"""Wavefront path tracer: the report's Monte Carlo estimator (§2.3-2.5).

The paths of a wavefront advance one bounce at a time as NumPy arrays; after each
bounce the arrays are compacted to the paths still alive and topped up with new
camera paths (path regeneration), so the wavefront stays full.  Per hit:

* emission is added when the path arrived from the camera or a specular bounce, or
  when no shadow rays sample the lights (then BSDF sampling must find them); so
  light is never counted twice;
* diffuse: N_s shadow rays to the area lights (eq. 2.11), then a cosine-weighted
  bounce whose weight f cos / pdf is the albedo (eq. 2.13-2.14);
* mirror: perfect reflection, weight = colour (eq. 2.15-2.16, 2.20);
* glass: Fresnel (eq. 2.17, Schlick or exact) picks reflection or refraction
  (eq. 2.21-2.24) stochastically, weight = tint; total internal reflection has R = 1.
  By default every glass surface separates its IOR from air, as the report (and
  Cycles) do; with `nested_dielectrics` each path keeps a stack of the media it is in,
  so glass inside glass or water in a glass refracts with the ratio of the two IORs
  (the report's §4 future work);
* Russian roulette (report 2.4) with survival probability min(1, max throughput),
  survivors divided by it; a zero throughput always terminates, without a division.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .bsdf import FRESNEL, reflect, refract, refract_cos
from .sampling import cosine_directions
from .scene import DIFFUSE, GLASS, MIRROR
from .vec import dot, max3, rows

KIND_CODE = {DIFFUSE: 0, MIRROR: 1, GLASS: 2}
BLACK = 3
N_GROUPS = 4
WAVEFRONT_SIZE = 1 << 15       # paths advanced together; 32768 measured fastest here
MEDIUM_STACK_DEPTH = 4          # nested dielectrics: media a path can be inside at once
SHADOW_TMAX_SCALE = 1.0 - 2.0 ** -20


class MaterialTable:
    """Materials as arrays indexed by material id; colours as rows (3, M)."""

    def __init__(self, materials):
        self.kind = np.array([KIND_CODE[m.kind] for m in materials], dtype=np.int8)
        color = np.array([m.color for m in materials], dtype=np.float64).reshape(-1, 3)
        emission = np.array([m.emission for m in materials], dtype=np.float64).reshape(-1, 3)
        self.color, self.emission = rows(color), rows(emission)
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.is_emissive = emission.max(axis=1) > 0
        # Scattering group: the kind, or BLACK for surfaces that absorb everything.
        self.group = np.where(color.max(axis=1) > 0.0, self.kind, BLACK).astype(np.int8)


VECTOR_FIELDS = ("o", "d", "beta", "radiance")


@dataclass
class Paths:
    """The state of the paths in the wavefront (struct of arrays; vectors as (3, N) rows)."""
    pixel: np.ndarray           # (N,) pixel of the tile the camera sample belongs to
    o: np.ndarray               # (3, N) ray origins
    d: np.ndarray               # (3, N) unit ray directions
    beta: np.ndarray            # (3, N) path throughput
    radiance: np.ndarray        # (3, N) radiance L gathered so far
    count_emission: np.ndarray  # (N,) emission at the next hit counts (camera/specular ray, no NEE)
    bounce: np.ndarray          # (N,) bounces made so far (0: camera ray)
    media: np.ndarray | None = None   # nested dielectrics: (N, MEDIUM_STACK_DEPTH) IOR stack
    depth: np.ndarray | None = None   # nested dielectrics: (N,) stack height

    @classmethod
    def start(cls, pixel, origins, directions, nested: bool) -> "Paths":
        n = len(pixel)
        return cls(pixel, origins, directions, np.ones((3, n)), np.zeros((3, n)), np.ones(n, dtype=bool),
                   np.zeros(n, dtype=np.int32),
                   np.ones((n, MEDIUM_STACK_DEPTH)) if nested else None,
                   np.zeros(n, dtype=np.int64) if nested else None)

    def _fields(self):
        return [(f.name, 1 if f.name in VECTOR_FIELDS else 0) for f in fields(self)
                if getattr(self, f.name) is not None]

    def take(self, index) -> "Paths":
        return Paths(**{name: getattr(self, name).take(index, axis=axis) for name, axis in self._fields()})

    def extend(self, other: "Paths") -> "Paths":
        return Paths(**{name: np.concatenate([getattr(self, name), getattr(other, name)], axis=axis)
                        for name, axis in self._fields()})


class PathTracer:
    def __init__(self, geometry, lights, materials, plan, settings, background):
        self.geometry = geometry
        self.lights = lights
        self.mats = MaterialTable(materials)
        self.plan = plan
        self.settings = settings
        self.background = np.asarray(background, dtype=np.float64)
        self.fresnel = FRESNEL[settings.fresnel]
        self.use_nee = (plan.diffuse and lights.count > 0 and settings.shadow_rays > 0)
        self.has_background = bool(self.background.max() > 0)

    # -- the wavefront -----------------------------------------------------------------
    def trace(self, samples, rng, counters, on_finished, cancel=None) -> None:
        """Trace every camera sample of `samples` (a camera.TileSamples) to completion.

        The wavefront holds up to WAVEFRONT_SIZE paths that advance one bounce per
        iteration; whenever paths end and there is room, new camera paths join it, so
        the arrays stay long and the per-call cost of NumPy is paid once per bounce of
        a full wavefront, not for the few paths left at depth 8.  Each path carries its
        pixel, throughput beta and radiance L; a finished path is handed to
        `on_finished(pixel, L)`.  Once `cancel` is set no new sample starts, but the paths
        in flight are traced to their end (a few bounces): dropping them would keep only
        the short paths of a partial tile and darken it.
        """
        paths = None
        while True:
            alive = 0 if paths is None else len(paths.pixel)
            room = WAVEFRONT_SIZE - alive
            fresh = 0
            stopping = cancel is not None and cancel.is_set()
            if samples.remaining and not stopping and (alive == 0 or room >= WAVEFRONT_SIZE // 4):
                pixel, o, d = samples.take(room)
                fresh = len(pixel)
                new = Paths.start(pixel, o, d, self.settings.nested_dielectrics)
                paths = new if paths is None else paths.extend(new)
            if paths is None or len(paths.pixel) == 0:
                break
            counters.rays["camera"] += fresh
            counters.rays["extension"] += len(paths.pixel) - fresh
            paths = self.bounce(paths, rng, counters, on_finished)

    def bounce(self, p: "Paths", rng, counters, on_finished) -> "Paths":
        """Advance every path one bounce; returns the survivors (report §2.3-2.5)."""
        s = self.settings
        finished_pixel, finished_l = [], []
        # Hits sorted by how their surface scatters, 0 diffuse, 1 mirror, 2 glass, 3 black
        # (absorbs), then by primitive kind: every group is one slice.
        hits = self.geometry.nearest_hits(p.o, p.d, counters, self.mats.group, N_GROUPS)
        if len(hits.miss):
            m = hits.miss
            radiance = p.radiance.take(m, axis=1)
            if self.has_background:
                radiance += p.beta.take(m, axis=1) * self.background[:, None]
            finished_pixel.append(p.pixel.take(m))
            finished_l.append(radiance)
        p = p.take(hits.index)
        surf = self.geometry.surface(p.o, p.d, hits)
        mat = surf.material
        if self.plan.emission:
            glow = np.flatnonzero(p.count_emission & self.mats.is_emissive.take(mat))
            if len(glow):
                p.radiance[:, glow] += p.beta.take(glow, axis=1) * self.mats.emission.take(mat.take(glow), axis=1)

        color = self.mats.color.take(mat, axis=1)
        bounds = [start for start, _ in hits.groups] + [hits.groups[-1][1]]
        point, normal, offset, d = surf.point, surf.normal, surf.offset, p.d
        cos_in = dot(d, normal)
        facing = normal * np.where(cos_in < 0.0, 1.0, -1.0)             # towards the incoming ray
        diffuse, mirror, glass = (slice(bounds[0], bounds[1]), slice(bounds[1], bounds[2]),
                                  slice(bounds[2], bounds[3]))
        n_diffuse = bounds[1] - bounds[0]

        if self.use_nee and n_diffuse:                                    # eq. 2.11
            p.radiance[:, diffuse] += p.beta[:, diffuse] * self.direct_light(
                point[:, diffuse], facing[:, diffuse], color[:, diffuse], offset[diffuse], rng, counters)

        alive = bounds[3]                     # groups 0-2 continue, black surfaces end here
        new_d = np.empty((3, alive))
        side = np.ones(alive)                 # +1: leave on the facing side, -1: go through
        next_emission = np.ones(alive, dtype=bool)
        if n_diffuse:
            new_d[:, diffuse] = cosine_directions(rng.random(n_diffuse), rng.random(n_diffuse),
                                                  facing[:, diffuse])      # eq. 2.13b
            next_emission[diffuse] = not self.use_nee
        if bounds[2] > bounds[1]:
            new_d[:, mirror] = reflect(d[:, mirror], facing[:, mirror])   # eq. 2.20
        if bounds[3] > bounds[2]:
            stack = None if p.media is None else (p.media[glass], p.depth[glass])   # views: updated in place
            new_d[:, glass], side[glass] = self.scatter_glass(
                d[:, glass], normal[:, glass], facing[:, glass], cos_in[glass], self.mats.ior.take(mat[glass]),
                rng, stack)
        beta = p.beta[:, :alive] * color[:, :alive]  # eq. 2.14 (f cos / pdf = colour), 2.16, glass tint
        bounce = p.bounce[:alive]

        keep = (max3(beta) > 0.0) & (bounce < s.max_depth)
        if s.russian_roulette:                                            # report 2.4
            survive_p = np.where(bounce + 1 >= s.rr_start_depth, np.minimum(max3(beta), 1.0), 1.0)
            keep &= rng.random(alive) < survive_p
            beta = beta / np.where(keep, survive_p, 1.0)
        ended = np.flatnonzero(~keep)
        finished_pixel += [p.pixel.take(ended), p.pixel[alive:]]
        finished_l += [p.radiance.take(ended, axis=1), p.radiance[:, alive:]]
        keep = np.flatnonzero(keep)
        pixel = np.concatenate(finished_pixel)
        if len(pixel):
            on_finished(pixel, np.concatenate(finished_l, axis=1))

        return Paths(
            pixel=p.pixel.take(keep),
            o=point.take(keep, axis=1) + (side.take(keep) * offset.take(keep)) * facing.take(keep, axis=1),
            d=new_d.take(keep, axis=1),
            beta=beta.take(keep, axis=1),
            radiance=p.radiance.take(keep, axis=1),
            count_emission=next_emission.take(keep),
            bounce=bounce.take(keep) + 1,
            media=None if p.media is None else p.media.take(keep, axis=0),
            depth=None if p.depth is None else p.depth.take(keep))

    # -- direct light, eq. 2.11 ---------------------------------------------------------
    def direct_light(self, point, normal, albedo, offset, rng, counters) -> np.ndarray:
        """<L_direct> with N_s shadow rays per point, divided by N_s: rows (3, M).

        point, normal (facing the viewer) and albedo are rows (3, M); offset (M,)."""
        ns = self.settings.shadow_rays
        m = point.shape[1]
        k = m * ns
        ls = self.lights.sample(rng.random(k), rng.random(k), rng.random(k))
        # Shadow ray j of point i is column i * ns + j.
        x = np.repeat(point, ns, axis=1) if ns > 1 else point
        nx = np.repeat(normal, ns, axis=1) if ns > 1 else normal
        off_x = np.repeat(offset, ns) if ns > 1 else offset
        w = ls.point - x
        dist2 = dot(w, w)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = w / np.sqrt(dist2)
        cos_x = dot(nx, w)
        cos_ly = dot(ls.normal, w)
        cos_y = np.abs(cos_ly)                          # two-sided emitters
        ok = (cos_x > 0.0) & (cos_y > 0.0) & (dist2 > 0.0) & np.isfinite(dist2)
        if self.lights.any_one_sided:                   # front side only: emits towards -w
            ok &= ~(ls.one_sided & (cos_ly >= 0.0))
        valid = np.flatnonzero(ok)
        everything = len(valid) == k

        def pick(a, axis=0):                          # the valid samples (no copy if all are)
            return a if everything else a.take(valid, axis=axis)
        weight = np.zeros(k)
        if len(valid):
            origin = pick(x, 1) + pick(off_x) * pick(nx, 1)
            # End point pulled off the light towards x, so the light never occludes itself.
            pull = np.copysign(1.0, pick(cos_ly)) * pick(ls.offset)
            target = pick(ls.point, 1) - pull * pick(ls.normal, 1)
            seg = target - origin
            seg_len = np.sqrt(dot(seg, seg))
            direction = seg / seg_len
            counters.rays["shadow"] += len(valid)
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            g = pick(cos_x) * pick(cos_y) / pick(dist2)                            # G(x, y)
            weight[valid] = np.where(blocked, 0.0, g * pick(ls.inv_pdf))           # V G / p(y)
        contrib = ls.radiance * weight
        mean = contrib.reshape(3, m, ns).sum(axis=2) / ns if ns > 1 else contrib
        return mean * albedo * (1.0 / np.pi)                            # f_r = colour / pi (eq. 2.13a)

    # -- glass, report 2.5.4 ----------------------------------------------------------
    def scatter_glass(self, d, normal, facing, cos_in, ior, rng, stack=None):
        """Reflect or refract at glass (direction rows); returns (directions, side).
        `stack` = (media, depth) views of the paths' medium stacks (nested dielectrics),
        updated in place."""
        cos_i = np.abs(cos_in)
        entering = cos_in < 0.0
        n = len(cos_in)
        if stack is None:
            eta = np.where(entering, 1.0 / ior, ior)       # n1 / n2, air on the other side
        else:
            media, depth = stack
            path = np.arange(n)
            current = np.where(depth > 0, media[path, np.maximum(depth - 1, 0)], 1.0)
            below = np.where(depth > 1, media[path, np.maximum(depth - 2, 0)], 1.0)
            # Entering: from the medium the path is in.  Leaving: into the one below it.
            eta = np.where(entering, current / ior, ior / below)
        cos_t, tir = refract_cos(cos_i, eta)
        fresnel = self.fresnel(cos_i, cos_t, eta, tir)
        reflected = rng.random(n) < fresnel
        out = np.empty_like(d)
        sel = np.flatnonzero(reflected)
        if len(sel):
            out[:, sel] = reflect(d.take(sel, axis=1), facing.take(sel, axis=1))
        through = np.flatnonzero(~reflected)
        if len(through):
            out[:, through] = refract(d.take(through, axis=1), facing.take(through, axis=1), cos_i.take(through),
                                      cos_t.take(through), eta.take(through))
        if stack is not None:
            push = through[entering[through] & (depth[through] < MEDIUM_STACK_DEPTH)]
            media[push, depth[push]] = ior[push]
            depth[push] += 1
            pop = through[~entering[through] & (depth[through] > 0)]
            depth[pop] -= 1
        return out, np.where(reflected, 1.0, -1.0)
