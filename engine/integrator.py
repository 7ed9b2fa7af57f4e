"""Wavefront path tracer: the report's Monte Carlo estimator (§2.3-2.5).

All paths of a batch advance one bounce at a time as NumPy arrays; after each bounce
the arrays are compacted to the paths still alive.  Per hit:

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

import numpy as np

from .bsdf import FRESNEL, reflect, refract, refract_cos
from .sampling import cosine_directions
from .scene import DIFFUSE, GLASS, MIRROR
from .vec import dot, max3

KIND_CODE = {DIFFUSE: 0, MIRROR: 1, GLASS: 2}
MEDIUM_STACK_DEPTH = 4          # nested dielectrics: media a path can be inside at once
SHADOW_TMAX_SCALE = 1.0 - 2.0 ** -20


class MaterialTable:
    """Materials as arrays indexed by material id."""

    def __init__(self, materials):
        self.kind = np.array([KIND_CODE[m.kind] for m in materials], dtype=np.int8)
        self.color = np.array([m.color for m in materials], dtype=np.float64).reshape(-1, 3)
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.emission = np.array([m.emission for m in materials], dtype=np.float64).reshape(-1, 3)
        self.is_emissive = self.emission.max(axis=1) > 0


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

    # -- one batch of camera paths ---------------------------------------------------
    def trace(self, origins, directions, rng, counters) -> np.ndarray:
        """Radiance (N, 3) carried by each camera ray.

        Paths are reordered freely between bounces (hits grouped by primitive kind, then
        by scattering kind) so every group is a contiguous slice; contributions are
        recorded as (path id, value) pairs and summed once at the end.
        """
        s = self.settings
        n = len(origins)
        record_ids, record_values = [], []
        ids = np.arange(n)
        o, d = origins, directions
        beta = np.ones((n, 3))
        count_emission = np.ones(n, dtype=bool)
        # Medium stack (nested dielectrics): IORs of the objects the path is inside, air below.
        media = np.ones((n, MEDIUM_STACK_DEPTH)) if s.nested_dielectrics else None
        depth = np.zeros(n, dtype=np.int64) if s.nested_dielectrics else None
        has_background = self.background.max() > 0
        for bounce in range(s.max_depth + 1):
            if len(ids) == 0:
                break
            counters.rays["camera" if bounce == 0 else "extension"] += len(ids)
            hits = self.geometry.nearest_hits(o, d, counters)
            if has_background and len(hits.miss):
                record_ids.append(ids.take(hits.miss))
                record_values.append(beta.take(hits.miss, axis=0) * self.background)
            h = hits.index
            if len(h) == 0:
                break
            ids, beta, count_emission = ids.take(h), beta.take(h, axis=0), count_emission.take(h)
            o, d = o.take(h, axis=0), d.take(h, axis=0)
            if media is not None:
                media, depth = media.take(h, axis=0), depth.take(h)
            surf = self.geometry.surface(o, d, hits)
            mat = surf.material
            if self.plan.emission:
                glow = np.flatnonzero(count_emission & self.mats.is_emissive.take(mat))
                if len(glow):
                    record_ids.append(ids.take(glow))
                    record_values.append(beta.take(glow, axis=0) * self.mats.emission.take(mat.take(glow), axis=0))

            # Group by how the surface scatters: 0 diffuse, 1 mirror, 2 glass, 3 black (absorbs).
            color = self.mats.color.take(mat, axis=0)
            group = self.mats.kind.take(mat)
            group = np.where(max3(color) > 0.0, group, 3)
            order = np.argsort(group, kind="stable")
            bounds = np.searchsorted(group.take(order), [0, 1, 2, 3])
            ids, beta, d, mat, color = (ids.take(order), beta.take(order, axis=0), d.take(order, axis=0),
                                        mat.take(order), color.take(order, axis=0))
            point, normal, offset = surf.point.take(order, axis=0), surf.normal.take(order, axis=0), surf.offset.take(order)
            if media is not None:
                media, depth = media.take(order, axis=0), depth.take(order)
            cos_in = dot(d, normal)
            facing = normal * np.where(cos_in < 0.0, 1.0, -1.0)[:, None]   # towards the incoming ray
            diffuse, mirror, glass = (slice(bounds[0], bounds[1]), slice(bounds[1], bounds[2]),
                                      slice(bounds[2], bounds[3]))
            n_diffuse = bounds[1] - bounds[0]

            if self.use_nee and n_diffuse:
                record_ids.append(ids[diffuse])
                record_values.append(beta[diffuse] * self.direct_light(
                    point[diffuse], facing[diffuse], color[diffuse], offset[diffuse], rng, counters))
            if bounce == s.max_depth:
                break

            alive = bounds[3]                     # groups 0-2 continue, black surfaces end here
            new_d = np.empty((alive, 3))
            side = np.ones(alive)                 # +1: leave on the facing side, -1: go through
            next_emission = np.ones(alive, dtype=bool)
            if n_diffuse:
                new_d[diffuse] = cosine_directions(rng.random(n_diffuse), rng.random(n_diffuse),
                                                   facing[diffuse])         # eq. 2.13b
                next_emission[diffuse] = not self.use_nee
            if bounds[2] > bounds[1]:
                new_d[mirror] = reflect(d[mirror], facing[mirror])           # eq. 2.20
            if bounds[3] > bounds[2]:
                stack = None if media is None else (media[glass], depth[glass])   # views: updated in place
                new_d[glass], side[glass] = self.scatter_glass(
                    d[glass], normal[glass], facing[glass], cos_in[glass], self.mats.ior.take(mat[glass]), rng,
                    stack)
            beta = beta[:alive] * color[:alive]  # eq. 2.14 (f cos / pdf = colour), 2.16, glass tint

            keep = max3(beta) > 0.0
            if s.russian_roulette and bounce + 1 >= s.rr_start_depth:
                survive_p = np.minimum(max3(beta), 1.0)
                keep &= rng.random(alive) < survive_p
                beta = beta / np.where(keep, survive_p, 1.0)[:, None]
            keep = np.flatnonzero(keep)
            o = point.take(keep, axis=0) + (side.take(keep) * offset.take(keep))[:, None] * facing.take(keep, axis=0)
            d = new_d.take(keep, axis=0)
            ids, beta, count_emission = ids.take(keep), beta.take(keep, axis=0), next_emission.take(keep)
            if media is not None:
                media, depth = media.take(keep, axis=0), depth.take(keep)
        radiance = np.zeros((n, 3))
        if record_ids:
            all_ids = np.concatenate(record_ids)
            values = np.concatenate(record_values)
            for c in range(3):
                radiance[:, c] = np.bincount(all_ids, weights=values[:, c], minlength=n)
        return radiance

    # -- direct light, eq. 2.11 ---------------------------------------------------------
    def direct_light(self, point, normal, albedo, offset, rng, counters) -> np.ndarray:
        """<L_direct> with N_s shadow rays per point, divided by N_s: (M, 3)."""
        ns = self.settings.shadow_rays
        m = len(point)
        k = m * ns
        ls = self.lights.sample(rng.random(k), rng.random(k), rng.random(k))
        x = np.repeat(point, ns, axis=0) if ns > 1 else point
        nx = np.repeat(normal, ns, axis=0) if ns > 1 else normal
        off_x = np.repeat(offset, ns) if ns > 1 else offset
        w = ls.point - x
        dist2 = dot(w, w)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = w / np.sqrt(dist2)[:, None]
        cos_x = dot(nx, w)
        cos_ly = dot(ls.normal, w)
        cos_y = np.abs(cos_ly)                          # two-sided emitters
        ok = (cos_x > 0.0) & (cos_y > 0.0) & (dist2 > 0.0) & np.isfinite(dist2)
        if self.lights.any_one_sided:                   # front side only: emits towards -w
            ok &= ~(ls.one_sided & (cos_ly >= 0.0))
        valid = np.flatnonzero(ok)
        weight = np.zeros(k)
        if len(valid):
            origin = x.take(valid, axis=0) + off_x.take(valid)[:, None] * nx.take(valid, axis=0)
            # End point pulled off the light towards x, so the light never occludes itself.
            pull = (np.copysign(1.0, cos_ly.take(valid)) * ls.offset.take(valid))[:, None]
            target = ls.point.take(valid, axis=0) - pull * ls.normal.take(valid, axis=0)
            seg = target - origin
            seg_len = np.sqrt(dot(seg, seg))
            direction = seg / seg_len[:, None]
            counters.rays["shadow"] += len(valid)
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            g = cos_x.take(valid) * cos_y.take(valid) / dist2.take(valid)          # G(x, y)
            weight[valid] = np.where(blocked, 0.0, g * ls.inv_pdf.take(valid))     # V G / p(y)
        contrib = ls.radiance * weight[:, None]
        mean = contrib.reshape(m, ns, 3).sum(axis=1) / ns if ns > 1 else contrib
        return mean * albedo / np.pi                                    # f_r = colour / pi (eq. 2.13a)

    # -- glass, report 2.5.4 ----------------------------------------------------------
    def scatter_glass(self, d, normal, facing, cos_in, ior, rng, stack=None):
        """Reflect or refract at glass; returns (directions, side).  `stack` = (media, depth)
        views of the paths' medium stacks (nested dielectrics), updated in place."""
        cos_i = np.abs(cos_in)
        entering = cos_in < 0.0
        if stack is None:
            eta = np.where(entering, 1.0 / ior, ior)       # n1 / n2, air on the other side
        else:
            media, depth = stack
            rows = np.arange(len(d))
            current = np.where(depth > 0, media[rows, np.maximum(depth - 1, 0)], 1.0)
            below = np.where(depth > 1, media[rows, np.maximum(depth - 2, 0)], 1.0)
            # Entering: from the medium the path is in.  Leaving: into the one below it.
            eta = np.where(entering, current / ior, ior / below)
        cos_t, tir = refract_cos(cos_i, eta)
        fresnel = self.fresnel(cos_i, cos_t, eta, tir)
        reflected = rng.random(len(d)) < fresnel
        out = np.empty_like(d)
        if reflected.any():
            out[reflected] = reflect(d[reflected], facing[reflected])
        through = ~reflected
        if through.any():
            out[through] = refract(d[through], facing[through], cos_i[through], cos_t[through], eta[through])
        if stack is not None:
            rows = np.flatnonzero(through)
            push = rows[entering[rows] & (depth[rows] < MEDIUM_STACK_DEPTH)]
            media[push, depth[push]] = ior[push]
            depth[push] += 1
            pop = rows[~entering[rows] & (depth[rows] > 0)]
            depth[pop] -= 1
        return out, np.where(reflected, 1.0, -1.0)
