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
  (eq. 2.21-2.24) stochastically, weight = tint; total internal reflection has R = 1;
* Russian roulette (report 2.4) with survival probability min(1, max throughput),
  survivors divided by it; a zero throughput always terminates, without a division.
"""
from __future__ import annotations

import numpy as np

from .bsdf import FRESNEL, dot, reflect, refract, refract_cos
from .geometry import NONE
from .sampling import cosine_hemisphere, to_world
from .scene import DIFFUSE, GLASS, MIRROR

KIND_CODE = {DIFFUSE: 0, MIRROR: 1, GLASS: 2}
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
        """Radiance (N, 3) carried by each camera ray."""
        s = self.settings
        n = len(origins)
        radiance = np.zeros((n, 3))
        ids = np.arange(n)
        o, d = origins, directions
        beta = np.ones((n, 3))
        count_emission = np.ones(n, dtype=bool)
        has_background = self.background.max() > 0
        for bounce in range(s.max_depth + 1):
            if len(ids) == 0:
                break
            counters.rays["camera" if bounce == 0 else "extension"] += len(ids)
            t, kind, prim, u, v = self.geometry.intersect(o, d, counters)
            miss = kind == NONE
            if has_background and miss.any():
                radiance[ids[miss]] += beta[miss] * self.background
            hit = ~miss
            ids, o, d, beta, count_emission = ids[hit], o[hit], d[hit], beta[hit], count_emission[hit]
            if len(ids) == 0:
                break
            surf = self.geometry.surface(o, d, t[hit], kind[hit], prim[hit], u[hit], v[hit])
            mat = surf.material
            if self.plan.emission:
                glow = count_emission & self.mats.is_emissive[mat]
                if glow.any():
                    radiance[ids[glow]] += beta[glow] * self.mats.emission[mat[glow]]
            cos_in = dot(d, surf.normal)
            facing = np.where((cos_in < 0.0)[:, None], surf.normal, -surf.normal)
            kind_code = self.mats.kind[mat]
            color = self.mats.color[mat]
            last = bounce == s.max_depth

            diffuse = (kind_code == 0) & (color.max(axis=1) > 0.0) if self.plan.diffuse else None
            if self.use_nee and diffuse.any():
                radiance[ids[diffuse]] += beta[diffuse] * self.direct_light(
                    surf.point[diffuse], facing[diffuse], color[diffuse], surf.offset[diffuse], rng, counters)
            if last:
                break

            alive = np.zeros(len(ids), dtype=bool)
            side = np.ones(len(ids))             # +1: leave on the facing side, -1: go through
            new_d = np.empty_like(d)
            next_emission = np.zeros(len(ids), dtype=bool)
            if self.plan.diffuse and diffuse.any():
                local = cosine_hemisphere(rng.random(int(diffuse.sum())), rng.random(int(diffuse.sum())))
                new_d[diffuse] = to_world(local, facing[diffuse])
                beta[diffuse] *= color[diffuse]              # eq. 2.14: f cos / pdf = colour
                alive |= diffuse
                next_emission[diffuse] = not self.use_nee
            if self.plan.mirror:
                mirror = kind_code == 1
                if mirror.any():
                    new_d[mirror] = reflect(d[mirror], facing[mirror])
                    beta[mirror] *= color[mirror]            # eq. 2.16
                    alive |= mirror
                    next_emission[mirror] = True
            if self.plan.glass:
                glass = kind_code == 2
                if glass.any():
                    dirs, sides = self.scatter_glass(d[glass], surf.normal[glass], facing[glass],
                                                     cos_in[glass], self.mats.ior[mat[glass]], rng)
                    new_d[glass], side[glass] = dirs, sides
                    beta[glass] *= color[glass]
                    alive |= glass
                    next_emission[glass] = True

            if s.russian_roulette and bounce + 1 >= s.rr_start_depth:
                survive_p = np.minimum(beta.max(axis=1), 1.0)
                survive = rng.random(len(ids)) < survive_p
                beta[survive] /= survive_p[survive, None]
                alive &= survive
            alive &= beta.max(axis=1) > 0.0
            offset = (side * surf.offset)[:, None] * facing
            o = (surf.point + offset)[alive]
            d = new_d[alive]
            ids, beta, count_emission = ids[alive], beta[alive], next_emission[alive]
        return radiance

    # -- direct light, eq. 2.11 ---------------------------------------------------------
    def direct_light(self, point, normal, albedo, offset, rng, counters) -> np.ndarray:
        """<L_direct> with N_s shadow rays per point, divided by N_s: (M, 3)."""
        ns = self.settings.shadow_rays
        m = len(point)
        k = m * ns
        idx = np.repeat(np.arange(m), ns)
        ls = self.lights.sample(rng.random(k), rng.random(k), rng.random(k))
        x, nx = point[idx], normal[idx]
        w = ls.point - x
        dist2 = dot(w, w)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = w / np.sqrt(dist2)[:, None]
        cos_x = dot(nx, w)
        cos_ly = dot(ls.normal, w)
        cos_y = np.abs(cos_ly)                          # two-sided emitters
        valid = (cos_x > 0.0) & (cos_y > 0.0) & (dist2 > 0.0) & np.isfinite(dist2)
        contrib = np.zeros((k, 3))
        if valid.any():
            v = valid
            origin = x[v] + (offset[idx[v]])[:, None] * nx[v]
            target = ls.point[v] - (np.copysign(1.0, cos_ly[v]) * ls.offset[v])[:, None] * ls.normal[v]
            seg = target - origin
            seg_len = np.sqrt(dot(seg, seg))
            direction = seg / seg_len[:, None]
            counters.rays["shadow"] += int(v.sum())
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            g = cos_x[v] * cos_y[v] / dist2[v]                        # G(x, y)
            weight = np.where(blocked, 0.0, g * ls.inv_pdf[v])         # V G / p(y)
            contrib[v] = ls.radiance[v] * weight[:, None]
        mean = contrib.reshape(m, ns, 3).sum(axis=1) / ns
        return mean * albedo / np.pi                                    # f_r = colour / pi (eq. 2.13a)

    # -- glass, report 2.5.4 ----------------------------------------------------------
    def scatter_glass(self, d, normal, facing, cos_in, ior, rng):
        cos_i = np.abs(cos_in)
        entering = cos_in < 0.0
        eta = np.where(entering, 1.0 / ior, ior)           # n1 / n2
        cos_t, tir = refract_cos(cos_i, eta)
        fresnel = self.fresnel(cos_i, cos_t, eta, tir)
        reflected = rng.random(len(d)) < fresnel
        out = np.empty_like(d)
        if reflected.any():
            out[reflected] = reflect(d[reflected], facing[reflected])
        through = ~reflected
        if through.any():
            out[through] = refract(d[through], facing[through], cos_i[through], cos_t[through], eta[through])
        return out, np.where(reflected, 1.0, -1.0)
