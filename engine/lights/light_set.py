"""The light set of a scene: its emitters, the pmf that picks one for a shading point, and the
maps from emissive primitives to lights (MIS).

The lights are numbered kind after kind (engine/lights/emitters.py gives the kinds and their
order); each kind (engine/lights/protocol.py) owns a contiguous range of numbers.  They form two
groups, each picked among by its own selection pmf (engine/lights/selection.py):

* the lights at finite distance (emissive surfaces, Area lights, point and spot lights), picked
  by power for the report's estimator or by the light tree;
* the lights at infinity (suns, and the world under the mis / solid-angle estimators), numbered
  after them and picked by power, as pbrt-v4 samples infinite lights apart from its BVH.

A light sample first picks the group (the lights at infinity with probability `distant_share`),
then a light in it, then a point on the light: its `pdf` is P(group) x P(k | x, n) x p_w, the
density of the direction x -> y, and `pdf` / `world_pdf` give that density for a direction a BSDF
ray found (MIS).

Emissive surfaces emit from both sides, as Cycles mesh lights; Area lights (Blender Area lights)
from their front only unless marked two-sided.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.vec import dot, max_abs3
from .emitters import SceneEmitters
from .protocol import LiSample
from .seen import SeenLamps
from .selection import LightTree, PowerSelection

# Shadow-ray end points are pulled off the light by this relative amount (as the
# triangle spawn offset) so the ray never reports the light itself as occluder.
LIGHT_OFFSET = 2.0 ** -20


@dataclass
class LightSample:
    point: np.ndarray      # (3, N) on the light (the world: one unit along `direction`)
    direction: np.ndarray  # (3, N) unit direction from the receiver to the point
    distance: np.ndarray   # (N,) to the point; inf for the world
    normal: np.ndarray     # (3, N) unit normal of the light at the point (the world: -direction)
    radiance: np.ndarray   # (3, N) emitted radiance Le
    pdf: np.ndarray        # (N,) P(group) * P(k | x, n) * p_w(x -> point); 0: no sample
    light: np.ndarray      # (N,) light index
    offset: np.ndarray     # (N,) distance along the normal that clears the light
    one_sided: np.ndarray  # (N,) bool: emits only towards the side its normal faces


def _gather_samples(m, parts) -> LiSample:
    """One LiSample of m rays from (rays, LiSample) parts that cover them."""
    out = LiSample(np.empty((3, m)), np.empty((3, m)), np.empty(m), np.empty((3, m)), np.empty((3, m)), np.empty(m))
    for rays, s in parts:
        out.point[:, rays], out.direction[:, rays], out.distance[rays] = s.point, s.direction, s.distance
        out.normal[:, rays], out.radiance[:, rays], out.pdf[rays] = s.normal, s.radiance, s.pdf
    return out


class LightGroup:
    """Lights that one selection pmf picks among, numbered `first` .. `first + count - 1` in the
    set.  The set picks the group when the light-picking uniform falls in [lo, lo + share)."""

    def __init__(self, kinds, first: int, selection, lo: float, share: float):
        self.kinds, self.first, self.selection, self.lo, self.share = kinds, first, selection, lo, share
        self.count = sum(kind.count for kind in kinds)
        self.kind_of = (np.concatenate([np.full(k.count, i) for i, k in enumerate(kinds)]) if kinds
                        else np.zeros(0, np.int64))                  # group light number -> kind
        self.in_kind = (np.concatenate([np.arange(k.count) for k in kinds]) if kinds
                        else np.zeros(0, np.int64))                  # group light number -> number in its kind

    def sample(self, x, n, u_pick, u1, u2, solid_angle: bool):
        """(LiSample with pdf P(k | x, n) p_w, light numbers in the set) for u_pick in the group's
        interval (rescaled to [0, 1) to pick the light)."""
        s, light, pmf = self.sample_unpicked(x, n, u_pick, u1, u2, solid_angle)
        s.pdf = s.pdf * pmf
        return s, light

    def sample_unpicked(self, x, n, u_pick, u1, u2, solid_angle: bool):
        """(LiSample with pdf p_w, light numbers in the set, P(k | x, n)): `sample` before its pdf is
        multiplied by the pick's."""
        light, pmf = self.selection.sample(x, n, u_pick if self.share == 1.0 else (u_pick - self.lo) / self.share)
        if len(self.kinds) == 1:
            s = self.kinds[0].sample_li(x, light, u1, u2, n, solid_angle)
        else:
            kind_of, parts = self.kind_of.take(light), []
            for i, kind in enumerate(self.kinds):
                sel = np.flatnonzero(kind_of == i)
                if len(sel):
                    parts.append((sel, kind.sample_li(x.take(sel, axis=1), self.in_kind.take(light.take(sel)),
                                                      u1.take(sel), u2.take(sel), n.take(sel, axis=1), solid_angle)))
            s = _gather_samples(len(u_pick), parts)
        return s, (light + self.first if self.first else light), pmf

    def pdf(self, x, n, light, point, solid_angle: bool):
        """P(k | x, n) p_w of the directions from x to `point` on lights `light` (set numbers)."""
        light = light - self.first
        pdf = np.empty(len(light))
        if len(self.kinds) == 1:
            pdf[:] = self.kinds[0].pdf_li(x, light, point, n, None, solid_angle)
        else:
            kind_of = self.kind_of.take(light)
            for i, kind in enumerate(self.kinds):
                sel = np.flatnonzero(kind_of == i)
                if len(sel):
                    pdf[sel] = kind.pdf_li(x.take(sel, axis=1), self.in_kind.take(light.take(sel)),
                                           point.take(sel, axis=1), n.take(sel, axis=1), None, solid_angle)
        return pdf * self.selection.pmf(x, n, light)


class LightSet:
    """All emitters of a scene.  solid_angle: sample each light by solid angle where stable
    (else by area, as eq. 2.11); spatial: pick lights with the light tree (else by power);
    lamps_hittable: rays can reach Area lights (the geometry tests them); world: the constant
    background is a light too.

    kinds: every LightKind, in light-number order; local, distant: the two LightGroups (distant:
    None without lights at infinity); world: the WorldLight or EnvironmentLight, or None;
    environment: the image world (engine/lights/environment.py EnvironmentMap) or None; triangle_light, quad_light,
    area_light_light, sphere_light: the light of each primitive (-1: none); seen: the lamps
    mirror and glass rays meet (engine/lights/seen.py) or None."""

    DISTANT_SHARE = (0.1, 0.9)        # bounds of the suns' and world's selection probability beside lamps
    # Cycles' sun-guided sky (scene/light.cpp device_update_background: sun_weight 4, map_weight 1):
    # a light sample of a sky with one sun disc takes the disc's cone with probability 0.8 and the
    # importance map (the disc in it too) with 0.2, so sky directions get 0.2 x the map's sky share.
    SKY_MAP_WEIGHT = 0.2

    def __init__(self, scene, solid_angle: bool = True, spatial: bool = True, lamps_hittable: bool = False,
                 world: bool = False, backend: str = "numpy", shapes_backend: str = "numpy",
                 wavefront_backend: str = "numpy"):
        self.solid_angle, self.backend = solid_angle, backend    # backend: the light tree's (engine/core/backend.py)
        emitters = SceneEmitters(scene, solid_angle, lamps_hittable, world)    # the emitters, per kind
        local_kinds, distant_kinds = emitters.local_kinds(), emitters.distant_kinds()
        self.kinds = local_kinds + distant_kinds
        # The kinds with compiled sampling: local ones (parallelograms) on shapes_backend (the kernel
        # "emission"'s), those at infinity (suns, the world: the warps of every bounce) on the
        # wavefront's, as the shadow rays and the samples' tails (engine/lights/light_set_jit.py).
        for kind in self.kinds:
            if hasattr(kind, "use_backend"):
                kind.use_backend(wavefront_backend if kind.at_infinity else shapes_backend)
        self.compiled_shadows = None
        if "numba" in (shapes_backend, wavefront_backend):
            from . import light_set_jit
            self.compiled_shadows = light_set_jit
        start = 0
        for kind in self.kinds:                                   # each kind's range of light numbers
            kind.first, start = start, start + kind.count
        self._primitive_maps(emitters)
        self._light_tables(emitters, local_kinds, distant_kinds)
        self._groups(local_kinds, distant_kinds, spatial)
        self.world = emitters.world
        self.environment = emitters.environment    # the image world's EnvironmentMap, or None
        self.seen = SeenLamps.of(scene)        # round lamps and suns that mirror and glass rays meet

    def _primitive_maps(self, emitters):
        """The light of each emissive primitive, so an emitter found by BSDF sampling knows the
        density the light set had for it (MIS)."""
        self.triangle_light = emitters.light_of_triangles()
        self.quad_light = emitters.light_of(emitters.quad_refs)
        self.area_light_light = emitters.light_of(emitters.area_light_refs)
        self.sphere_light = emitters.light_of(emitters.sphere_refs)

    def _light_tables(self, emitters, local, distant):
        """Per light: radiance, sides, whether a diffuse bounce ray can reach it (MIS needs both
        strategies: emissive surfaces always, Area lights when rays test them and their diffuse
        visibility is on, point lights and suns never, the world by escaping rays), and for the
        lights at finite distance their area, flux and the report's power."""

        def joined(values, empty, axis=0):
            return np.concatenate(values, axis=axis) if values else empty
        self.radiance = joined([k.radiance for k in self.kinds], np.zeros((3, 0)), axis=1)
        self.one_sided = joined([k.one_sided for k in self.kinds], np.zeros(0, bool))
        self.any_one_sided = bool(self.one_sided.any())
        self.bsdf_reachable = np.concatenate([emitters.local_reachable()]
                                             + [np.full(k.count, k.reached_by_escaping_rays) for k in distant])
        self.area = joined([k.area for k in local], np.zeros(0))
        self.power = joined([k.power() for k in local], np.zeros(0))               # emitted flux
        self.report_power = joined([k.report_power() for k in local], np.zeros(0))
        self.distant_power = joined([k.power() for k in distant], np.zeros(0))
        self.count = int((self.report_power > 0).sum()) + int((self.distant_power > 0).sum())

    def _groups(self, local_kinds, distant_kinds, spatial):
        """The selection pmf of each group, and the share of the lights at infinity: their flux
        against the lamps', clipped to DISTANT_SHARE (all of it without lamps)."""
        n_local = sum(k.count for k in local_kinds)
        if spatial and n_local > 1:
            bounds = [k.bounds() for k in local_kinds]
            selection = LightTree(np.concatenate([b.center.T for b in bounds]), np.concatenate([b.radius for b in bounds]),
                                  np.concatenate([b.axis.T for b in bounds]), np.concatenate([b.cos_o for b in bounds]),
                                  self.power, self.power, backend=self.backend)
        else:
            selection = PowerSelection(self.report_power if n_local else np.ones(0))
        self.distant_share = 0.0
        if distant_kinds:
            lamps, far = float(self.power.sum()), float(self.distant_power.sum())
            self.distant_share = 1.0 if lamps <= 0 else float(np.clip(far / (far + lamps), *self.DISTANT_SHARE))
        q = self.distant_share
        self.local = LightGroup(local_kinds, 0, selection, q, 1.0 - q)
        self.distant = LightGroup(distant_kinds, n_local, PowerSelection(self.distant_weights(distant_kinds)), 0.0, q) \
            if distant_kinds else None

    def distant_weights(self, distant_kinds):
        """The selection weights of the lights at infinity: their flux, except for a Sky Texture's
        world and its one sun disc, picked as Cycles' sun-guided sky does (SKY_MAP_WEIGHT): the
        baked sky (without the disc) with SKY_MAP_WEIGHT x its share of the pair's flux, the disc
        with the rest.  The pair keeps its flux against other suns.  The baked sky's directions are
        then left mostly to BSDF samples (MIS), which find a smooth sky better than its map: the
        light samples go to the sun, which BSDF samples almost never find."""
        weights = self.distant_power.copy()
        suns = [k for k in distant_kinds if k.name == "sun"]
        env = [k for k in distant_kinds if k.name == "environment"]
        if not (suns and env) or int(suns[0].sky_disc.sum()) != 1:
            return weights
        n_local = len(self.power)
        disc = suns[0].first - n_local + int(np.flatnonzero(suns[0].sky_disc)[0])   # numbers in the group
        sky = env[0].first - n_local
        total = weights[disc] + weights[sky]
        if total > 0:
            weights[sky] = self.SKY_MAP_WEIGHT * weights[sky]
            weights[disc] = total - weights[sky]
        return weights

    # -- sampling --------------------------------------------------------------------------
    def sample(self, x, n, u_pick, u1, u2) -> LightSample:
        """One light sample per receiver x with facing normal n (rows): u_pick picks the group
        ([0, distant_share): the lights at infinity) and, rescaled, the light in it; u1, u2 the
        point on the light."""
        m = len(u_pick)
        q = self.distant_share
        if q == 0:                           # no lights at infinity: every ray's is local (no index arrays)
            return self._sample_in(self.local, x, n, u_pick, u1, u2)
        far = u_pick < q
        if self.compiled_shadows is not None and (far.all() or not far.any()):    # one group for all: no copies
            return self._sample_in(self.distant if m and far[0] else self.local, x, n, u_pick, u1, u2)
        parts, lights = [], []
        for group, rays in ((self.local, np.flatnonzero(~far)), (self.distant, np.flatnonzero(far))):
            if len(rays) == m:                                     # the whole wavefront: no copies
                s, light = group.sample(x, n, u_pick, u1, u2, self.solid_angle)
                rays = slice(None)
            elif len(rays):
                s, light = group.sample(x.take(rays, axis=1), n.take(rays, axis=1), u_pick.take(rays),
                                        u1.take(rays), u2.take(rays), self.solid_angle)
            else:
                continue
            s.pdf = s.pdf * group.share
            parts.append((rays, s))
            lights.append((rays, light))
        if len(parts) == 1:
            s, light = parts[0][1], lights[0][1]
        else:
            s, light = _gather_samples(m, parts), np.empty(m, dtype=np.int64)
            for rays, lt in lights:
                light[rays] = lt
        return LightSample(s.point, s.direction, s.distance, s.normal, s.radiance, s.pdf, light,
                           LIGHT_OFFSET * max_abs3(s.point), self.one_sided.take(light))

    def _sample_in(self, group, x, n, u_pick, u1, u2) -> LightSample:
        """`sample` where every ray picks a light of `group`."""
        s, light, pmf = group.sample_unpicked(x, n, u_pick, u1, u2, self.solid_angle)
        if self.compiled_shadows is not None:         # the rest in one loop, the same numbers
            pdf, offset, one_sided = self.compiled_shadows.finish_sample(s.pdf, pmf, group.share, s.point, light,
                                                                         self.one_sided, LIGHT_OFFSET)
            return LightSample(s.point, s.direction, s.distance, s.normal, s.radiance, pdf, light, offset, one_sided)
        s.pdf = s.pdf * pmf * group.share
        return LightSample(s.point, s.direction, s.distance, s.normal, s.radiance, s.pdf, light,
                           LIGHT_OFFSET * max_abs3(s.point), self.one_sided.take(light))

    def pdf(self, x, n, light, point) -> np.ndarray:
        """P(k | x, n) * p_w of the direction from x to `point` on lamp or emissive surface k: the
        density with which `sample` at (x, n) produces that direction (MIS at an emission hit)."""
        return self.local.pdf(x, n, light, point, self.solid_angle) * self.local.share

    def world_pdf(self, n, d) -> np.ndarray:
        """Density with which `sample` at a receiver with facing normal n produces the world
        direction d (MIS for a bounce ray that escapes)."""
        picked = self.distant.selection.prob[self.world.first - self.distant.first]
        return self.distant.share * self.world.pdf_li(None, None, None, n, d, pmf=picked)

    def shadow_rays(self, ls: LightSample, valid, x, lift, ng, cos_ly, raised=None):
        """The shadow rays of the light samples `valid` (indices into ls; None: all of them), as
        (origin, unit direction, length) rows: from x + lift ng (receivers x, their geometric normals
        ng and offsets along them, lift; raised = (amount, s): plus amount s, the shadow-terminator
        offset) to the sample's point pulled off the light along its normal by ls.offset, on the
        side cos_ly = <normal, direction> says, so the light never occludes itself; lights at
        infinity: along the sample's direction to length inf.  Arrays are per sample (all of ls)."""
        if self.compiled_shadows is not None:                 # the same numbers in one loop
            return self.compiled_shadows.shadow_rays(ls, valid, x, lift, ng, cos_ly, raised)

        def pick(a, axis=0):
            return a if valid is None else a.take(valid, axis=axis)
        origin = pick(x, 1) + pick(lift) * pick(ng, 1)
        if raised is not None:
            origin = origin + pick(raised[0]) * pick(raised[1], 1)
        pull = np.copysign(1.0, pick(cos_ly)) * pick(ls.offset)
        seg = pick(ls.point, 1) - pull * pick(ls.normal, 1) - origin
        finite = np.isfinite(pick(ls.distance))
        with np.errstate(invalid="ignore"):
            length = np.where(finite, np.sqrt(dot(seg, seg)), np.inf)
            direction = np.where(finite, seg / length, pick(ls.direction, 1))
        return origin, direction, length

    def kind_names(self) -> list[str]:
        return [kind.name for kind in self.kinds]
