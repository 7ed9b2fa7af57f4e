"""Photons through the specular surfaces (L S+ D): each photon is traced with the scene's nearest-hit
query and the BSDFs' own sampling (engine/materials/protocol.py), as the path tracer's camera paths
are, and

* at a hit whose BSDF has a non-delta lobe, after at least one delta bounce, it is stored (its
  position, its direction of arrival, its flux, the facing geometric normal);
* it goes on only while its bounces take delta lobes (mirror, smooth glass, straight pass-through):
  a non-delta sample ends it, as does an absorbing surface, leaving the scene, or the depth limit;
* Russian roulette on the flux's largest ratio to its emitted value after the first bounce;
* Area lights let it through unchanged, as they do camera rays.

The delta lobes' weights (f cos / pdf: the tint, and 1 for Fresnel-picked lobes) carry flux as they
carry radiance: this tracer scales neither by the squared IOR ratio.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.vec import dot, max3
from ...materials.protocol import BSDFFlags, ShadingPoint
from ...materials.table import ABSORB, N_SCATTER_GROUPS, PASS_THROUGH
from ..light_paths import bounce_type


@dataclass
class Stored:
    position: np.ndarray    # (3, M)
    incoming: np.ndarray    # (3, M) unit, towards where the photon came from
    flux: np.ndarray        # (3, M)
    normal: np.ndarray      # (3, M) unit geometric normal on the photon's side
    segments: np.ndarray    # (M,) the photon path's segments from the light to it (bounces + 1)
    label: np.ndarray       # (M,) the label its emitted photon had (its pass)
    chain: np.ndarray = None  # (3, M) its glossy, transmission and transparent bounces but the first
                              # (engine/integrators/light_paths.py's types; the first is the camera path's last)
    traced: int = 0         # photons traced (after emission's culling)
    rays: int = 0           # rays cast


CHUNK = 1 << 17     # photons traced together at most: a bounce of that many takes about 0.1 s (Esc within that)


def trace_photons(tracer, origin, direction, flux, counters, rng, max_depth: int, label=None,
                  cancel=None) -> Stored | None:
    """Trace the emitted photons (rows) through `tracer`'s scene (engine/integrators/path_tracer.py
    PathTracer: its geometry, material table, BSDFs and textures); label (N,): carried to the stored
    photons (default 0).  In wavefronts of at most CHUNK photons, one after the other (with the same
    `rng`, so the photons depend on CHUNK, never on the worker).  None as soon as `cancel` (anything
    with is_set()) is set: it is checked before and in the middle of every bounce."""
    n = origin.shape[1]
    if n <= CHUNK:
        return _trace(tracer, origin, direction, flux, counters, rng, max_depth, label, cancel)
    parts = []
    for first in range(0, n, CHUNK):
        span = slice(first, min(n, first + CHUNK))
        part = _trace(tracer, origin[:, span], direction[:, span], flux[:, span], counters, rng, max_depth,
                      None if label is None else np.asarray(label)[span], cancel)
        if part is None:
            return None
        parts.append(part)
    arrays = [np.concatenate([getattr(p, name) for p in parts], axis=-1)
              for name in ("position", "incoming", "flux", "normal", "segments", "label", "chain")]
    return Stored(*arrays, traced=sum(p.traced for p in parts), rays=sum(p.rays for p in parts))


def _trace(tracer, origin, direction, flux, counters, rng, max_depth: int, label, cancel) -> Stored | None:
    geometry, mats, textures = tracer.geometry, tracer.mats, tracer.textures
    o, d, phi = origin, direction, flux
    start = np.maximum(max3(flux), 1e-300)
    bounce = np.zeros(o.shape[1], dtype=np.int32)
    tag = np.zeros(o.shape[1], dtype=np.int64) if label is None else np.asarray(label, dtype=np.int64)
    chain = np.zeros((3, o.shape[1]), dtype=np.int16)
    out = Stored(*(np.zeros((3, 0)) for _ in range(4)), np.zeros(0, np.int32), np.zeros(0, np.int64),
                 np.zeros((3, 0), np.int16), traced=o.shape[1])
    parts = []
    while o.shape[1]:
        if cancel is not None and cancel.is_set():
            return None
        out.rays += o.shape[1]
        hits = geometry.nearest_hits(o, d, counters, tracer.scatter_group, N_SCATTER_GROUPS,
                                     light_group=PASS_THROUGH)
        if cancel is not None and cancel.is_set():          # the query is about half of a bounce
            return None
        idx = hits.index
        o, d, phi, bounce, start, tag, chain = (o.take(idx, axis=1), d.take(idx, axis=1), phi.take(idx, axis=1),
                                                bounce.take(idx), start.take(idx), tag.take(idx),
                                                chain.take(idx, axis=1))
        surf = geometry.surface(o, d, hits)
        bounds = [s for s, _ in hits.groups] + [hits.groups[-1][1]]
        alive = bounds[ABSORB]
        through = np.arange(bounds[PASS_THROUGH], bounds[PASS_THROUGH + 1])
        towards = np.where(dot(d, surf.normal) < 0.0, 1.0, -1.0)
        facing = surf.normal * towards
        smooth = surf.shading is not surf.normal
        shade = surf.shading * towards if smooth else facing
        # Stored: hits on a BSDF with a non-delta lobe after a delta bounce.
        non_delta = np.array(mats.non_delta + [False, False])
        group = np.searchsorted(np.asarray(bounds), np.arange(len(idx)), side="right") - 1
        keep = np.flatnonzero(non_delta.take(group) & (bounce >= 1))
        if len(keep):
            parts.append((surf.point.take(keep, axis=1), -d.take(keep, axis=1), phi.take(keep, axis=1),
                          facing.take(keep, axis=1), bounce.take(keep) + 1, tag.take(keep), chain.take(keep, axis=1)))
        color = mats.color.take(surf.material, axis=1)
        if textures is not None:
            color = textures.color(color, surf.material, hits.kind, hits.prim, hits.u, hits.v)
        si = ShadingPoint(-d[:, :alive], shade[:, :alive], facing[:, :alive], surf.normal[:, :alive],
                          color[:, :alive], surf.material[:alive], smooth, None,
                          None if textures is None else textures.at(hits)[:alive])
        new_d = np.zeros((3, alive))
        value = np.zeros((3, alive))
        flags = np.zeros(alive, dtype=np.int8)
        u_lobe = rng.random(alive)
        for g, bsdf in enumerate(mats.bsdfs):
            span = slice(bounds[g], bounds[g + 1])
            if span.stop == span.start or not (bsdf.flags & BSDFFlags.DELTA):
                continue
            n = span.stop - span.start
            s = bsdf.sample(si[span], u_lobe[span], rng.random((2, n)) if mats.non_delta[g] else None)
            new_d[:, span], value[:, span], flags[span] = s.wi, s.value, s.flags
        delta = (flags & BSDFFlags.DELTA) != 0
        transmitted = (flags & BSDFFlags.TRANSMISSION) != 0
        side = np.where(transmitted, -1.0, 1.0)
        if smooth:
            delta &= dot(new_d, si.ng) * side > 0.0
        phi_next = phi[:, :alive] * value
        survive = np.minimum(max3(phi_next) / start[:alive], 1.0)
        go = delta & (bounce[:alive] + 1 < max_depth) & (survive > 0.0)
        go &= rng.random(alive) < survive
        go = np.flatnonzero(go)
        nxt_o = surf.point.take(go, axis=1) + (side.take(go) * surf.offset.take(go)) * facing.take(go, axis=1)
        nxt_d = new_d.take(go, axis=1)
        nxt_phi = phi_next.take(go, axis=1) / survive.take(go)
        nxt_start = start.take(go)
        nxt_bounce = bounce.take(go) + 1
        nxt_tag = tag.take(go)
        nxt_chain = chain.take(go, axis=1)
        later = np.flatnonzero(bounce.take(go) >= 1)            # every bounce but the photon's first
        nxt_chain[bounce_type(flags.take(go).take(later)) - 1, later] += 1
        if len(through):                    # Area lights: on through them, unchanged
            p = surf.point.take(through, axis=1)
            dt = d.take(through, axis=1)
            nxt_o = np.concatenate([nxt_o, p + surf.offset.take(through) * dt], axis=1)
            nxt_d = np.concatenate([nxt_d, dt], axis=1)
            nxt_phi = np.concatenate([nxt_phi, phi.take(through, axis=1)], axis=1)
            nxt_start = np.concatenate([nxt_start, start.take(through)])
            nxt_bounce = np.concatenate([nxt_bounce, bounce.take(through)])
            nxt_tag = np.concatenate([nxt_tag, tag.take(through)])
            nxt_chain = np.concatenate([nxt_chain, chain.take(through, axis=1)], axis=1)
        o, d, phi, start, bounce, tag, chain = nxt_o, nxt_d, nxt_phi, nxt_start, nxt_bounce, nxt_tag, nxt_chain
    if parts:
        out.position, out.incoming, out.flux, out.normal = (np.concatenate([p[i] for p in parts], axis=1)
                                                            for i in range(4))
        out.segments = np.concatenate([p[4] for p in parts])
        out.label = np.concatenate([p[5] for p in parts])
        out.chain = np.concatenate([p[6] for p in parts], axis=1)
    return out
