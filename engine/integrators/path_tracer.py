"""Wavefront path tracer: the report's Monte Carlo estimator (§2.3-2.5), with the light
sampling and MIS of its §4 future work.

The paths of a wavefront advance one bounce at a time as NumPy arrays; after each
bounce the arrays are compacted to the paths still alive and topped up with new
camera paths (path regeneration), so the wavefront stays full.  One bounce runs in
named stages (`bounce`): intersect, misses, emission, pass-through (Blender Area
lights), direct light, scatter, roulette, compaction.

* Direct light at diffuse hits: N_s shadow rays (eq. 2.11).  Under the `report`
  estimator a light is picked by power and a point on it by area (pdf 1/A); otherwise
  the light tree picks by importance at the shading point and the light is sampled by
  solid angle where stable (engine/lights).
* Emission reached by a ray counts with weight 1 after the camera or a mirror/glass
  bounce, and when no shadow rays run.  After a diffuse bounce: `report` and
  `solid-angle` drop it (the shadow rays account for it: light is never counted
  twice); `mis` weights it, and the shadow-ray samples, by the power heuristic
  (Veach & Guibas 1995, beta = 2) with the multi-sample counts N_s light samples and
  one BSDF sample (Veach's thesis ch. 9):
      w_light = (N_s p_l)^2 / ((N_s p_l)^2 + p_b^2),  w_bsdf = p_b^2 / (p_b^2 + (N_s p_l)^2)
  with p_l = P(k | x, n) p_w(x -> y) from the light sampler and p_b = cos/pi.
* diffuse: a cosine-weighted bounce whose weight f cos / pdf is the albedo (eq. 2.13-2.14);
* mirror: perfect reflection, weight = colour (eq. 2.15-2.16, 2.20);
* glass: Fresnel (eq. 2.17, Schlick or exact) picks reflection or refraction
  (eq. 2.21-2.24) stochastically, weight = tint; total internal reflection has R = 1.
  By default every glass surface separates its IOR from air, as the report (and
  Cycles) do; with `nested_dielectrics` each path keeps a stack of the media it is in,
  so glass inside glass or water in a glass refracts with the ratio of the two IORs
  (the report's §4 future work);
* image textures (engine/materials/textures.py): the colour and emission of textured materials at triangle
  hits, and the radiance of light samples on textured emitters, are read from the texture at the
  UV interpolated with the hit's barycentrics (pdfs and MIS weights depend on geometry only);
* Russian roulette (report 2.4) with survival probability min(1, max throughput),
  survivors divided by it; a zero throughput always terminates, without a division.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..materials.bsdf import FRESNEL, reflect, refract, refract_cos
from ..geometry.scene_geometry import LIGHT, QUAD, SPHERE, TRIANGLE
from ..sampling.qmc import RandomSampler
from ..sampling.warps import cosine_directions
from ..scene.model import DIFFUSE, GLASS, MIRROR
from ..geometry.shading_normals import ensure_valid_reflection, terminator_amount
from ..core.vec import dot, max3, rows

KIND_CODE = {DIFFUSE: 0, MIRROR: 1, GLASS: 2}
BLACK = 3                       # surfaces that absorb everything
PASS = 4                        # Area lights: emission, then the ray goes on
N_GROUPS = 5
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


VECTOR_FIELDS = ("o", "d", "beta", "radiance", "prev_p", "prev_n", "f_thru")
CAMERA_RAY, DIFFUSE_RAY, GLOSSY_RAY, TRANSMISSION_RAY = 0, 1, 2, 3   # LightPolygons.RAY_KINDS
# Dimension pairs of the sampler (engine/sampling/qmc.py): 0 is the camera jitter (engine/scene/camera_rays.py);
# the hit after bounce b uses DIMS_PER_BOUNCE pairs from 1 + DIMS_PER_BOUNCE b on.
# CHOICES: (light pick with one shadow ray, or the Fresnel choice at glass; roulette).
LIGHT_UV, BSDF_UV, CHOICES, LIGHT_PICK = 1, 2, 3, 4          # LIGHT_PICK: with several shadow rays
DIMS_PER_BOUNCE = 4


@dataclass
class Paths:
    """The state of the paths in the wavefront (struct of arrays; vectors as (3, N) rows)."""
    pixel: np.ndarray           # (N,) pixel of the tile the camera sample belongs to
    sample: np.ndarray          # (N,) the camera sample's number within its pixel (QMC index)
    o: np.ndarray               # (3, N) ray origins
    d: np.ndarray               # (3, N) unit ray directions
    beta: np.ndarray            # (3, N) path throughput
    radiance: np.ndarray        # (3, N) radiance L gathered so far
    specular: np.ndarray        # (N,) camera ray or after a mirror/glass bounce: emission weight 1
    ray_kind: np.ndarray        # (N,) int8 CAMERA_RAY .. TRANSMISSION_RAY (Area lights' visibility)
    bounce: np.ndarray          # (N,) bounces made so far (0: camera ray)
    prev_p: np.ndarray | None = None    # MIS: (3, N) the diffuse vertex that sampled the ray
    prev_n: np.ndarray | None = None    # MIS: (3, N) its facing normal (the light tree's input)
    prev_pdf: np.ndarray | None = None  # MIS: (N,) cosine pdf of the ray's direction there
    media: np.ndarray | None = None   # nested dielectrics: (N, MEDIUM_STACK_DEPTH) IOR stack
    depth: np.ndarray | None = None   # nested dielectrics: (N,) stack height
    f_thru: np.ndarray | None = None  # passes: (3, N) tints of the specular bounces before the feature hit
    f_open: np.ndarray | None = None  # passes: (N,) still looking for its first non-specular hit

    @classmethod
    def start(cls, pixel, sample, origins, directions, nested: bool, mis: bool, features: bool = False) -> "Paths":
        n = len(pixel)
        return cls(pixel, sample, origins, directions, np.ones((3, n)), np.zeros((3, n)), np.ones(n, dtype=bool),
                   np.zeros(n, dtype=np.int8), np.zeros(n, dtype=np.int32),
                   np.zeros((3, n)) if mis else None, np.zeros((3, n)) if mis else None,
                   np.ones(n) if mis else None,
                   np.ones((n, MEDIUM_STACK_DEPTH)) if nested else None,
                   np.zeros(n, dtype=np.int64) if nested else None,
                   np.ones((3, n)) if features else None, np.ones(n, dtype=bool) if features else None)

    def _fields(self):
        return [(f.name, 1 if f.name in VECTOR_FIELDS else 0) for f in fields(self)
                if getattr(self, f.name) is not None]

    def take(self, index) -> "Paths":
        return Paths(**{name: getattr(self, name).take(index, axis=axis) for name, axis in self._fields()})

    def extend(self, other: "Paths") -> "Paths":
        return Paths(**{name: np.concatenate([getattr(self, name), getattr(other, name)], axis=axis)
                        for name, axis in self._fields()})


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
        self.mats = MaterialTable(materials)
        self.plan = plan
        self.settings = settings
        self.background = np.asarray(background, dtype=np.float64)
        self.fresnel = FRESNEL[settings.fresnel]
        self.use_nee = bool(plan.direct_light and lights.count > 0)
        self.mis = bool(plan.mis and self.use_nee)
        # Under `mis` a diffuse vertex at the depth limit still traces its BSDF ray for the
        # emission it reaches (weighted by MIS, or 1 without shadow rays), so every estimator
        # counts the same paths: light reached by up to max_depth + 1 segments.
        self.final_rays = settings.estimator == "mis" and (self.mis or not self.use_nee)
        self.has_background = bool(self.background.max() > 0)
        self.world_nee = self.use_nee and lights.world is not None       # shadow rays sample the world
        if textures is not None:         # a textured colour scatters whatever its unlinked value
            self.mats.group = np.where(textures.has_color, self.mats.kind, self.mats.group).astype(np.int8)
        self.material_group = self.mats.group
        self.seen_lamps = lights.seen if plan.enabled.get("seen_lamps") else None
        self.light_of_kind = {TRIANGLE: lights.triangle_light, SPHERE: lights.sphere_light,
                              QUAD: lights.quad_light, LIGHT: lights.area_light_light}

    # -- the wavefront -----------------------------------------------------------------
    def trace(self, samples, rng, counters, on_finished, cancel=None, sampler=None, features=None) -> None:
        """Trace every camera sample of `samples` (a camera.TileSamples) to completion.

        The wavefront holds up to WAVEFRONT_SIZE paths that advance one bounce per
        iteration; whenever paths end and there is room, new camera paths join it, so
        the arrays stay long and the per-call cost of NumPy is paid once per bounce of
        a full wavefront, not for the few paths left at depth 8.  Each path carries its
        pixel, throughput beta and radiance L; a finished path is handed to
        `on_finished(pixel, L)`.  Returns False as soon as `cancel` is set (checked every
        bounce): the caller drops the whole unit (engine/rendering/session.py), since a partial one
        would keep only its short paths and darken its tile.  Uniform numbers come from
        `sampler` (engine/sampling/qmc.py; default: independent ones from `rng`).  `features`: an
        engine/film/passes.py TileFeatures that gets each sample's first-hit albedo, normal and depth
        (None: no feature work at all).
        """
        sampler = sampler or RandomSampler(rng)
        paths = None
        while True:
            alive = 0 if paths is None else len(paths.pixel)
            room = WAVEFRONT_SIZE - alive
            fresh = 0
            if cancel is not None and cancel.is_set():
                return False
            if samples.remaining and (alive == 0 or room >= WAVEFRONT_SIZE // 4):
                pixel, sample, o, d = samples.take(room)
                fresh = len(pixel)
                new = Paths.start(pixel, sample, o, d, self.settings.nested_dielectrics, self.mis,
                                  features is not None and features.surface)
                paths = new if paths is None else paths.extend(new)
            if paths is None or len(paths.pixel) == 0:
                return True
            counters.rays["camera"] += fresh
            counters.rays["extension"] += len(paths.pixel) - fresh
            paths = self.bounce(paths, sampler, counters, on_finished, features)

    def bounce(self, p: "Paths", sampler, counters, on_finished, features=None) -> "Paths":
        """Advance every path one bounce; returns the survivors (report §2.3-2.5)."""
        finished = []                                   # (pixel, radiance) of paths that end
        # 1. Intersect.  Hits sorted by how their surface scatters, 0 diffuse, 1 mirror,
        # 2 glass, 3 black (absorbs), 4 Area light (passed through), then by primitive kind:
        # every group is one slice.
        # Under MIS a diffuse vertex at the depth limit still traces its BSDF ray: that ray only
        # collects the MIS-weighted emission it reaches (the other half of that vertex's direct
        # light), then ends: its surface counts as black (as Cycles' terminate-on-next-surface).
        final = p.bounce > self.settings.max_depth if self.final_rays else None
        hits = self.geometry.nearest_hits(p.o, p.d, counters, self.material_group, N_GROUPS,
                                          light_group=PASS, ray_kind=p.ray_kind,
                                          forced_group=None if final is None or not final.any()
                                          else np.where(final, BLACK, -1))
        # 2. Round lamps and suns met by mirror and glass rays (engine/lights/seen.py).
        if self.seen_lamps is not None:
            self.lamps_seen(p, hits)
        # Misses: the background.
        if len(hits.miss):
            finished.append(self.misses(p, hits.miss))
            if features is not None and features.surface:
                self.miss_features(p, hits.miss, features)
        p = p.take(hits.index)
        surf = self.geometry.surface(p.o, p.d, hits)
        bounds = [start for start, _ in hits.groups] + [hits.groups[-1][1]]
        alive = bounds[BLACK]                 # diffuse, mirror and glass paths scatter on
        surfaces = bounds[PASS]               # black surfaces end the path here
        through = slice(bounds[PASS], bounds[PASS + 1])
        # 3. Emission found by the ray (surfaces and Area lights), MIS-weighted after diffuse.
        if self.plan.emission:
            self.emission(p, surf, hits, surfaces)
        # 4. Area lights: the ray goes on through them, as it was.
        passing = self.pass_through(p.take(np.arange(through.start, through.stop)), surf, through)
        # 5. Direct light at diffuse hits (eq. 2.11).
        diffuse = slice(bounds[0], bounds[1])
        towards = np.where(dot(p.d, surf.normal) < 0.0, 1.0, -1.0)
        facing = surf.normal * towards                                      # towards the ray
        # Smooth shading: the shading normal on the geometric normal's side of the ray (shading
        # only; offsets and side tests keep `facing`).  Flat-only scenes: the same array.
        smooth = surf.shading is not surf.normal
        shade = surf.shading * towards if smooth else facing
        color = self.mats.color.take(surf.material, axis=1)
        if self.textures is not None:
            color = self.textures.color(color, surf.material, hits.kind, hits.prim, hits.u, hits.v)
        dim = 1 + DIMS_PER_BOUNCE * p.bounce[:alive]                        # this hit's dimensions
        u_choice, u_rr = sampler.pair(p.pixel[:alive], p.sample[:alive], dim + (CHOICES - 1))
        if features is not None:
            self.surface_features(p, surf, shade, color, bounds, features, hits)   # Cycles: the shading normal
        if self.use_nee and bounds[1] > bounds[0]:
            p.radiance[:, diffuse] += p.beta[:, diffuse] * self.direct_light(
                surf.point[:, diffuse], shade[:, diffuse], color[:, diffuse], surf.offset[diffuse], None, counters,
                u=self.light_uniforms(sampler, p.pixel[diffuse], p.sample[diffuse], dim[diffuse], u_choice[diffuse]),
                geometric=facing[:, diffuse] if smooth else None,
                lift=self.geometry.terminator_lift(hits, diffuse, facing) if smooth else None)
        # 6. Scatter: the next direction and throughput of every scattering path.
        u_bsdf = sampler.pair(p.pixel[diffuse], p.sample[diffuse], dim[diffuse] + (BSDF_UV - 1))
        new_d, side, beta = self.scatter(p, surf, facing, color, bounds, u_bsdf, u_choice,
                                         shade=shade if smooth else None)
        # 7. Russian roulette and the depth limit.
        keep, beta = self.roulette(beta, p.bounce[:alive], p.specular[:alive], u_rr)
        # 8. Compaction: hand finished paths to the film, keep the rest.
        ended = np.flatnonzero(~keep)
        finished += [(p.pixel.take(ended), p.radiance.take(ended, axis=1)),
                     (p.pixel[alive:surfaces], p.radiance[:, alive:surfaces])]
        pixel = np.concatenate([f[0] for f in finished])
        if len(pixel):
            on_finished(pixel, np.concatenate([f[1] for f in finished], axis=1))
        keep = np.flatnonzero(keep)
        survivors = p.take(keep)
        survivors.o = (surf.point.take(keep, axis=1)
                       + (side.take(keep) * surf.offset.take(keep)) * facing.take(keep, axis=1))
        survivors.d = new_d.take(keep, axis=1)
        survivors.beta = beta.take(keep, axis=1)
        survivors.bounce = survivors.bounce + 1
        return survivors if passing is None else survivors.extend(passing)

    # -- stages ------------------------------------------------------------------------
    def misses(self, p, miss):
        """Rays that leave the scene reach the background, with weight 1 (the report), unless
        the world is a light (shadow rays sample it): then a ray sampled at a diffuse vertex
        (the final MIS rays beyond the depth limit included) counts with its MIS weight, or 0
        without MIS."""
        radiance = p.radiance.take(miss, axis=1)
        if self.has_background:
            weight = np.ones(len(miss))
            if self.world_nee:
                specular = p.specular.take(miss)
                weight[~specular] = 0.0
                if self.mis:
                    diffuse = np.flatnonzero(~specular)
                    m = miss.take(diffuse)
                    p_world = self.lights.world_pdf(p.prev_n.take(m, axis=1), p.d.take(m, axis=1))
                    weight[diffuse] = power_heuristic(1.0, p.prev_pdf.take(m), float(self.settings.shadow_rays),
                                                      p_world)
            radiance += p.beta.take(miss, axis=1) * self.background[:, None] * weight
        return p.pixel.take(miss), radiance

    def lamps_seen(self, p, hits):
        """Emission of point, spot and sun lights reached by glossy and transmission rays before
        their hit (weight 1: only a specular bounce sends such rays, and shadow rays could not)."""
        rays = np.flatnonzero((p.ray_kind == GLOSSY_RAY) | (p.ray_kind == TRANSMISSION_RAY))
        if not len(rays):
            return
        tmax = np.full(len(p.pixel), np.inf)
        tmax[hits.index] = hits.t
        le = self.seen_lamps.radiance(p.o.take(rays, axis=1), p.d.take(rays, axis=1), tmax.take(rays),
                                      p.ray_kind.take(rays) == TRANSMISSION_RAY)
        p.radiance[:, rays] += p.beta.take(rays, axis=1) * le

    def emission(self, p, surf, hits, surfaces):
        """Add emission at emissive surfaces and front faces of Area lights, weighted: 1 after
        the camera or a specular bounce or without shadow rays; after a diffuse bounce 0 under
        `report`/`solid-angle`, the power-heuristic weight under `mis`."""
        mat = surf.material
        lit = np.flatnonzero(self.mats.is_emissive.take(mat[:surfaces]))
        parts = [(lit, self.mats.emission.take(mat.take(lit), axis=1))] if len(lit) else []
        if parts and self.textures is not None:
            parts[0] = (lit, self.textures.emission(parts[0][1], mat.take(lit), hits.kind.take(lit),
                                                    hits.prim.take(lit), hits.u.take(lit), hits.v.take(lit)))
        for (group, kind), (a, b) in hits.runs.items():
            if group == PASS:
                lamps, prim = self.geometry.lights, hits.prim[a:b]
                front = lamps.two_sided.take(prim) | (dot(p.d[:, a:b], surf.normal[:, a:b]) < 0.0)
                idx = np.arange(a, b)[front]
                if len(idx):
                    parts.append((idx, lamps.radiance.take(prim[front], axis=1)))
        for idx, le in parts:
            weight = self.emission_weight(p, surf, hits, idx)
            p.radiance[:, idx] += p.beta.take(idx, axis=1) * le * weight

    def emission_weight(self, p, surf, hits, idx):
        specular = p.specular.take(idx)
        if not self.use_nee or specular.all():
            return 1.0
        if not self.mis:
            return specular.astype(np.float64)
        weight = np.ones(len(idx))
        sel = np.flatnonzero(~specular)
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
        weight[sel] = power_heuristic(1.0, p.prev_pdf.take(hit), float(self.settings.shadow_rays), p_light)
        return weight

    # -- render passes (engine/film/passes.py) ------------------------------------------------
    def miss_features(self, p, miss, features):
        """A path still without a feature hit that leaves the scene: the background's radiance
        times its specular tints is its albedo (Cycles: film_write_emission_or_background_pass);
        its normal stays 0."""
        idx = miss[p.f_open.take(miss)]
        if len(idx) and self.has_background:
            features.add_albedo(p.pixel.take(idx), p.f_thru.take(idx, axis=1) * self.background[:, None])

    def surface_features(self, p, surf, facing, color, bounds, features, hits=None):
        """Cycles' denoising features (film_write_denoising_features_surface): at the first diffuse
        (or black) hit write albedo = specular tints x colour and the facing normal, then stop;
        at mirrors and glass multiply the tints by the colour and look further.  Emission seen
        on the way adds its radiance (unclipped, as Cycles).  Depth: every camera ray's first surface."""
        surfaces = bounds[PASS]
        first = np.flatnonzero(p.bounce[:surfaces] == 0)
        if len(first):
            features.add_depth(p.pixel.take(first), surf.point.take(first, axis=1))
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
                                            hits.v.take(h))
            features.add_albedo(pix.take(e), thru.take(e, axis=1) * le)
        stop = (group == 0) | (group == BLACK)
        diffuse = np.flatnonzero(group == 0)
        if len(diffuse):
            features.add_albedo(pix.take(diffuse), thru.take(diffuse, axis=1) * color.take(idx.take(diffuse), axis=1))
        normal = np.flatnonzero(stop & ~(emissive & (group == BLACK)))     # emitters only: normal 0, as Cycles
        if len(normal):
            features.add_normal(pix.take(normal), facing.take(idx.take(normal), axis=1))
        p.f_open[idx[stop]] = False
        spec = np.flatnonzero(~stop)
        if len(spec):
            p.f_thru[:, idx[spec]] = thru.take(spec, axis=1) * color.take(idx.take(spec), axis=1)

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

    def scatter(self, p, surf, facing, color, bounds, u_bsdf, u_choice, shade=None):
        """New directions, the side to leave on (+1 facing, -1 through) and throughputs of the
        diffuse, mirror and glass paths (groups 0-2); updates their specular/MIS state.

        shade: shading normals facing the ray (smooth shading) or None (flat: `facing`).  Then
        diffuse bounces are sampled about it, mirror and glass use it bent so that the mirror
        direction clears the geometric surface (ensure_valid_reflection), and a direction on the
        wrong side of the geometric surface ends the path (engine/geometry/shading_normals.py)."""
        smooth = shade is not None
        shade = facing if shade is None else shade
        alive = bounds[BLACK]
        diffuse, mirror, glass = (slice(bounds[0], bounds[1]), slice(bounds[1], bounds[2]),
                                  slice(bounds[2], bounds[3]))
        n_diffuse = bounds[1] - bounds[0]
        new_d = np.empty((3, alive))
        side = np.ones(alive)
        d = p.d
        if n_diffuse:
            new_d[:, diffuse] = cosine_directions(u_bsdf[0], u_bsdf[1], shade[:, diffuse])   # eq. 2.13b
            p.specular[diffuse] = False
            p.ray_kind[diffuse] = DIFFUSE_RAY
            if self.mis:
                p.prev_p[:, diffuse] = surf.point[:, diffuse]
                p.prev_n[:, diffuse] = shade[:, diffuse]
                p.prev_pdf[diffuse] = dot(new_d[:, diffuse], shade[:, diffuse]) * (1.0 / np.pi)
        if smooth and bounds[3] > bounds[1]:     # mirror and glass: Cycles' valid-reflection normal
            specular = slice(bounds[1], bounds[3])
            shade = shade.copy()
            shade[:, specular] = ensure_valid_reflection(facing[:, specular], -d[:, specular], shade[:, specular])
        if bounds[2] > bounds[1]:
            new_d[:, mirror] = reflect(d[:, mirror], shade[:, mirror])   # eq. 2.20
            p.specular[mirror] = True
            p.ray_kind[mirror] = GLOSSY_RAY
        if bounds[3] > bounds[2]:
            stack = None if p.media is None else (p.media[glass], p.depth[glass])   # views: updated in place
            cos_in = dot(d[:, glass], surf.normal[:, glass])            # its sign: entering or leaving
            if smooth:
                cos_in = np.copysign(np.abs(dot(d[:, glass], shade[:, glass])), cos_in)
            new_d[:, glass], side[glass] = self.scatter_glass(
                d[:, glass], surf.normal[:, glass], shade[:, glass], cos_in,
                self.mats.ior.take(surf.material[glass]), None, stack, u=u_choice[glass])
            p.specular[glass] = True
            p.ray_kind[glass] = np.where(side[glass] > 0.0, GLOSSY_RAY, TRANSMISSION_RAY)
        beta = p.beta[:, :alive] * color[:, :alive]  # eq. 2.14 (f cos / pdf = colour), 2.16, glass tint
        if smooth:                          # below the geometric surface (or not through it): ends
            wrong = dot(new_d, facing[:, :alive]) * side <= 0.0
            if wrong.any():
                beta = np.where(wrong, 0.0, beta)
        return new_d, side, beta

    def roulette(self, beta, bounce, specular, u):
        """Which paths go on (report 2.4) and their throughput after the survival division.
        Under `mis` a diffuse bounce at the depth limit goes on for its emission (see `bounce`)."""
        s = self.settings
        within = bounce < s.max_depth
        if self.final_rays:
            within |= (bounce == s.max_depth) & ~specular
        keep = (max3(beta) > 0.0) & within
        if s.russian_roulette:
            survive_p = np.where(bounce + 1 >= s.rr_start_depth, np.minimum(max3(beta), 1.0), 1.0)
            keep &= u < survive_p
            beta = beta / np.where(keep, survive_p, 1.0)
        return keep, beta

    # -- direct light, eq. 2.11 ---------------------------------------------------------
    def direct_light(self, point, normal, albedo, offset, rng, counters, u=None, geometric=None,
                     lift=None) -> np.ndarray:
        """<L_direct> with N_s shadow rays per point, divided by N_s: rows (3, M).

        point, normal (facing the viewer) and albedo are rows (3, M); offset (M,).  Each
        sample adds Le f cos(theta_x) V / p_l (eq. 2.11 written per unit solid angle: with
        p_l = P(k) d^2 / (A cos(theta_y)) it is the report's Le f G V A / P(k)), times the
        MIS weight under `mis`.  u: (pick, u1, u2) per shadow ray, else drawn from rng.
        geometric: the geometric normals (facing the viewer) when `normal` is a shading normal
        (smooth shading): shadow rays start off the geometric surface and directions below it
        count 0 (no light leaks, engine/geometry/shading_normals.py).  lift: (lift rows, cutoff) per point,
        the shadow-terminator geometry offset of smooth triangles (Cycles' shadow_ray_offset)."""
        ns = self.settings.shadow_rays
        m = point.shape[1]
        k = m * ns
        # Shadow ray j of point i is column i * ns + j.
        x = np.repeat(point, ns, axis=1) if ns > 1 else point
        nx = np.repeat(normal, ns, axis=1) if ns > 1 else normal
        off_x = np.repeat(offset, ns) if ns > 1 else offset
        ng = nx if geometric is None else (np.repeat(geometric, ns, axis=1) if ns > 1 else geometric)
        u_pick, u1, u2 = u if u is not None else (rng.random(k), rng.random(k), rng.random(k))
        ls = self.lights.sample(x, nx, u_pick, u1, u2)
        if self.textures is not None:                   # textured emitters: Le at the sampled point
            ls.radiance = self.textures.light_radiance(ls.radiance, ls.light, ls.point)
        w = ls.direction
        cos_x = dot(nx, w)
        cos_ly = dot(ls.normal, w)
        ok = (cos_x > 0.0) & (cos_ly != 0.0) & (ls.pdf > 0.0) & (ls.distance > 0.0)
        if self.lights.any_one_sided:                   # front side only: emits towards -w
            ok &= ~(ls.one_sided & (cos_ly >= 0.0))
        amount = None
        if geometric is not None:
            # Below the geometric surface: no light, unless the shadow-terminator lift moves the
            # shadow ray's origin up onto the smooth surface (Cycles: it is then traced from there).
            ng_w = dot(ng, w)
            if lift is not None:
                s_vec, cutoff = (np.repeat(lift[0], ns, axis=1), np.repeat(lift[1], ns)) if ns > 1 else lift
                amount = terminator_amount(cos_x, ng_w, cutoff)
                ok &= (ng_w > 0.0) | (amount > 0.0)
            else:
                ok &= ng_w > 0.0
        valid = np.flatnonzero(ok)
        everything = len(valid) == k

        def pick(a, axis=0):                          # the valid samples (no copy if all are)
            return a if everything else a.take(valid, axis=axis)
        weight = np.zeros(k)
        if len(valid):
            origin = pick(x, 1) + pick(off_x) * pick(ng, 1)
            if amount is not None:                  # grazing light on a smooth triangle: lifted origin
                origin = origin + pick(amount) * pick(s_vec, 1)
            # End point pulled off the light towards x, so the light never occludes itself;
            # the world is at infinity: its shadow rays run to t = inf.
            pull = np.copysign(1.0, pick(cos_ly)) * pick(ls.offset)
            seg = pick(ls.point, 1) - pull * pick(ls.normal, 1) - origin
            finite = np.isfinite(pick(ls.distance))
            with np.errstate(invalid="ignore"):
                seg_len = np.where(finite, np.sqrt(dot(seg, seg)), np.inf)
                direction = np.where(finite, seg / seg_len, pick(w, 1))
            counters.rays["shadow"] += len(valid)
            blocked = self.geometry.occluded(origin, direction, seg_len * SHADOW_TMAX_SCALE, counters)
            cos, pdf = pick(cos_x), pick(ls.pdf)
            sample = cos / pdf                                                  # cos V / p_l
            if self.mis:                            # lights a diffuse bounce cannot reach: weight 1
                p_bsdf = np.where(pick(self.lights.bsdf_reachable.take(ls.light)), cos * (1.0 / np.pi), 0.0)
                sample *= power_heuristic(float(ns), pdf, 1.0, p_bsdf)
            weight[valid] = np.where(blocked, 0.0, sample)
        contrib = ls.radiance * weight
        mean = contrib.reshape(3, m, ns).sum(axis=2) / ns if ns > 1 else contrib
        return mean * albedo * (1.0 / np.pi)                            # f_r = colour / pi (eq. 2.13a)

    # -- glass, report 2.5.4 ----------------------------------------------------------
    def scatter_glass(self, d, normal, facing, cos_in, ior, rng, stack=None, u=None):
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
        reflected = (u if u is not None else rng.random(n)) < fresnel
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
