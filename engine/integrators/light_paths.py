"""Cycles' Light Paths options in the path tracer (engine/integrators/path_tracer.py): bounce limits
per type, clamping, Filter Glossy and the caustics toggles, as Cycles' kernel computes them (a
public source: blender/cycles src/kernel/integrator/path_state.h, film/light_passes.h,
integrator/surface_shader.h, svm/closure.h).  docs/user-guide.md "Light paths" describes them.

* Bounce limits (path_state_next): every scatter counts as a diffuse (diffuse reflection), a
  glossy (glossy or mirror reflection), a transmission (any other transmission) or a transparent
  bounce (a straight pass-through: the Transparent BSDF, the Principled BSDF's alpha; its limit is
  reached one pass earlier, as Cycles', and the tracer's total counts it too, where Cycles' does not).  The bounce
  that makes a type's count exceed its limit is traced, but its next hit only emits (Cycles'
  terminate-on-next-surface: the path tracer's "final" rays).  The total (max_depth) caps every
  type, so a type's limit at or above the total changes nothing.
* Clamping (film_clamp_light): each contribution added to a path's radiance, reduced to the sum of
  |R| + |G| + |B|, is scaled down to at most 3 x the clamp (Cycles multiplies the user's value by
  3): "direct" for light reaching the camera after at most one bounce (emission seen by the camera
  ray or by the first bounce ray, shadow rays of the first hit), "indirect" for the rest.  With
  several shadow rays per hit the clamp applies to their mean (Cycles has one).
* Filter Glossy (surface_shader_prepare_closures, bsdf_microfacet_blur): each path keeps the
  smallest pdf of its non-delta bounces (Cycles' min_ray_pdf; delta bounces leave it, as Cycles'
  singular pdf of 1e6 does); at a later hit with blur = min_pdf / filter < 1 the microfacet lobes'
  alphas are raised to at least sqrt(1 - blur) / 2 (ShadingPoint.alpha_floor, read by
  engine/materials/glossy.py, dielectric.py, principled_glass.py and the Principled v1's
  principled_v1.py, principled_v1_glass.py).  The energy compensation and the Principled layer
  weights keep the closure's own roughness, as Cycles' (they are set up before the blur); the v1's
  multiscatter compensation follows the raised alphas, as Cycles 3.4's random walk.  Perfect mirrors,
  smooth glass and smooth refraction (Cycles' microfacet closures of alpha 0) are blurred too: their
  hits become GGX lobes of the floor's alpha (engine/integrators/delta_blur.py), but Blender 3.x's
  Sharp closures, which Cycles 3.4 leaves sharp, and delta lobes under caustic photons, which carry
  that light already (the effect plan says which).  The one difference left: a mirror or glass leaf
  of a Mix shader (engine/materials/mix.py) stays sharp.
* Caustics (svm/closure.h CAUSTICS_TRICKS): after a diffuse bounce (a diffuse reflection or
  transmission, Paths.after_diffuse; a straight pass-through keeps the state), Reflective Caustics off leaves
  out the glossy and mirror reflection closures, Refractive Caustics off the refraction ones.  A
  BSDF without a diffuse lobe whose every lobe is left out is a black surface there (no shadow
  rays, the path ends; its emission counts); glass with one of its two lobes left out drops the
  samples of that lobe (the same mean as Cycles' glass with that tint 0); a BSDF with a diffuse
  and a glossy lobe (Principled) reads ShadingPoint.glossy_off and weights its lobes as Cycles'
  closure set without the glossy ones.
"""
from __future__ import annotations

import numpy as np

from ..materials.protocol import DIFFUSE_LOBE, REFLECTION_LOBE, STRAIGHT_LOBE, TRANSMISSION_LOBE

DIFFUSE_BOUNCE, GLOSSY_BOUNCE, TRANSMISSION_BOUNCE, TRANSPARENT_BOUNCE = 0, 1, 2, 3   # rows of Paths.counts
BOUNCE_TYPES = ("diffuse", "glossy", "transmission", "transparent")
CLAMP_SCALE = 3.0              # Cycles: the clamp is on |R| + |G| + |B|, the user's value x 3


def bounce_type(flags: np.ndarray) -> np.ndarray:
    """The row of Paths.counts each sampled lobe counts in (path_state_next)."""
    transmitted = (flags & TRANSMISSION_LOBE) != 0
    diffuse = (flags & DIFFUSE_LOBE) != 0
    kind = np.where(transmitted, TRANSMISSION_BOUNCE, np.where(diffuse, DIFFUSE_BOUNCE, GLOSSY_BOUNCE))
    return np.where((flags & STRAIGHT_LOBE) != 0, TRANSPARENT_BOUNCE, kind)   # Cycles' LABEL_TRANSPARENT


def after_diffuse(flags: np.ndarray, before: np.ndarray) -> np.ndarray:
    """Whether the next hit follows a diffuse bounce (Cycles' PATH_RAY_VISIBILITY_DIFFUSE): the lobe
    taken was diffuse (reflection or transmission); a straight pass-through keeps `before`."""
    return np.where((flags & STRAIGHT_LOBE) != 0, before, (flags & DIFFUSE_LOBE) != 0)


def clamp_contribution(contribution: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """contribution (3, N) scaled down where |R| + |G| + |B| exceeds CLAMP_SCALE x limit (N,)
    (limit inf: unchanged)."""
    total = np.abs(contribution).sum(axis=0)
    bound = CLAMP_SCALE * limit
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):    # (a tiny total: where() keeps 1)
        scale = np.where(total > bound, bound / total, 1.0)
    return contribution * scale


def blur_alpha(min_pdf: np.ndarray, filter_glossy: float) -> np.ndarray:
    """The alpha floor (N,) after bounces whose smallest pdf is min_pdf: sqrt(1 - blur) / 2 where
    blur = min_pdf / filter_glossy < 1, else 0 (surface_shader_prepare_closures)."""
    blur = min_pdf / filter_glossy
    return np.where(blur < 1.0, np.sqrt(np.maximum(1.0 - blur, 0.0)) * 0.5, 0.0)


class LightPaths:
    """The options a render uses, from the settings and the effect plan (engine/integrators/effects.py:
    bounce_limits, clamp, filter_glossy, caustics), and what they do to the paths.  bsdfs: the
    material table's BSDFs, one per scatter group (engine/materials/table.py)."""

    def __init__(self, settings, plan, bsdfs):
        # Cycles: the pass-through that makes the transparent count reach its limit is the last
        # (path_state_next), one earlier than the other types (the kernel's limit is theirs + 1).
        self.limits = np.array([settings.diffuse_bounces, settings.glossy_bounces, settings.transmission_bounces,
                                settings.transparent_bounces - 1], dtype=np.int64)
        self.bounce_limits = bool(plan.enabled.get("bounce_limits"))
        self.clamping = bool(plan.enabled.get("clamp"))
        self.limit_direct = settings.clamp_direct if settings.clamp_direct > 0 else np.inf
        self.limit_indirect = settings.clamp_indirect if settings.clamp_indirect > 0 else np.inf
        self.filter_glossy = settings.filter_glossy if plan.enabled.get("filter_glossy") else 0.0
        # Filter Glossy blurs delta lobes too (engine/integrators/delta_blur.py), but with caustic photons.
        self.blur_delta = self.filter_glossy > 0 and not plan.enabled.get("photon_caustics")
        self.caustics = bool(plan.enabled.get("caustics"))
        self.reflective, self.refractive = settings.caustics_reflective, settings.caustics_refractive
        flags = [int(b.flags) for b in bsdfs]
        # Groups with lobes but no diffuse one: every reflection lobe is glossy or a mirror, every
        # transmission lobe a refraction.  Those with both (Principled) filter their own lobes.
        sides = REFLECTION_LOBE | TRANSMISSION_LOBE
        self.specular_only = np.array([bool(f & sides) and not f & DIFFUSE_LOBE for f in flags] + [False, False])
        self.reflects = np.array([bool(f & REFLECTION_LOBE) for f in flags] + [False, False])
        self.transmits = np.array([bool(f & TRANSMISSION_LOBE) for f in flags] + [False, False])
        # A straight pass-through (Transparent BSDF, alpha) is no refraction: never left out.
        self.passes = np.array([bool(f & STRAIGHT_LOBE) for f in flags] + [False, False])

    @property
    def on(self) -> bool:
        return self.bounce_limits or self.clamping or self.filter_glossy > 0 or self.caustics

    # -- bounce limits ----------------------------------------------------------------------------
    def count(self, counts: np.ndarray, flags: np.ndarray) -> None:
        """Add each path's scatter (the first len(flags) columns of counts (3, N)) to its type."""
        kind = bounce_type(flags)
        counts[kind, np.arange(len(flags))] += 1

    def past_limit(self, counts: np.ndarray) -> np.ndarray:
        """(N,) the paths whose last bounce took a type past its limit: their next hit only emits."""
        return (counts > self.limits[:, None]).any(axis=0)

    def chain_budget(self, counts: np.ndarray, receiver_flags: int) -> np.ndarray:
        """(3, N) the glossy, transmission and transparent bounces a caustic photon's specular chain
        may make, but its first (engine/integrators/photons/), at a receiver whose paths have made
        `counts` (4, N) bounces: the receiver's own bounce (diffuse where its BSDF has a diffuse lobe,
        else glossy) and each bounce of the chain before the last must keep every type within its
        limit; the last may pass it (its next hit, the light, only emits)."""
        made = counts.astype(np.int64)
        made[DIFFUSE_BOUNCE if receiver_flags & DIFFUSE_LOBE else GLOSSY_BOUNCE] += 1
        budget = self.limits[:, None] - made
        return np.where((budget < 0).any(axis=0), -1, budget[1:])

    # -- clamping ---------------------------------------------------------------------------------
    def clamp(self, contribution: np.ndarray, direct: np.ndarray) -> np.ndarray:
        """contribution (3, N) clamped by Clamp Direct where `direct` (N,), else by Clamp Indirect."""
        if not self.clamping:
            return contribution
        return clamp_contribution(contribution, np.where(direct, self.limit_direct, self.limit_indirect))

    # -- Filter Glossy ----------------------------------------------------------------------------
    def alpha_floor(self, min_pdf: np.ndarray) -> np.ndarray | None:
        floor = blur_alpha(min_pdf, self.filter_glossy)
        return floor if floor.any() else None

    # -- caustics ---------------------------------------------------------------------------------
    def glossy_off(self, after_diffuse: np.ndarray) -> np.ndarray | None:
        """(N,) hits whose glossy and mirror reflection is left out, or None."""
        return after_diffuse if not self.reflective and after_diffuse.any() else None

    def no_closure(self, group: np.ndarray, after_diffuse: np.ndarray) -> np.ndarray:
        """(N,) hits of a BSDF without a diffuse lobe whose every lobe is left out: black there."""
        gone = self.specular_only.take(group) & after_diffuse & ~self.passes.take(group)
        if self.reflective and self.refractive:
            return np.zeros_like(gone)
        if self.reflective:
            gone &= ~self.reflects.take(group)
        if self.refractive:
            gone &= ~self.transmits.take(group)
        return gone

    def no_light_samples(self, group: np.ndarray, after_diffuse: np.ndarray) -> np.ndarray | None:
        """(N,) hits whose shadow rays are left out: a BSDF without a diffuse lobe takes light on
        its reflection side only (engine/materials/protocol.py), which Reflective Caustics off removes."""
        if self.reflective:
            return None
        off = self.specular_only.take(group) & after_diffuse
        return off if off.any() else None

    def dropped_samples(self, group: np.ndarray, after_diffuse: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """(N,) samples of a left-out lobe of a BSDF without a diffuse lobe."""
        drop = np.zeros(len(flags), dtype=bool)
        if not self.reflective:
            drop |= (flags & REFLECTION_LOBE) != 0
        if not self.refractive:
            drop |= ((flags & TRANSMISSION_LOBE) != 0) & ((flags & STRAIGHT_LOBE) == 0)
        return drop & after_diffuse & self.specular_only.take(group)
