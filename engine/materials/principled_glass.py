"""The Principled BSDF v2's transmission closure (Blender 4.0+): the rough glass that Cycles' svm
closure.h (case CLOSURE_BSDF_PRINCIPLED_ID, "Transmission component"; a public source:
blender/cycles src/kernel/svm/closure.h and kernel/closure/bsdf_microfacet.h) sets up with weight
transmission_weight x (1 - metallic) x W, W the weight left by alpha, sheen and coat
(engine/materials/principled.py):

* a GGX glass closure (reflection and refraction, engine/materials/dielectric_lobe.py), isotropic
  alpha = roughness^2 (the anisotropy is not used), eta = IOR entering, 1 / IOR leaving (or the
  ratio of the media on the path's medium stack, engine/materials/media.py, which a refraction
  updates);
* its Fresnel is Cycles' generalized Schlick in the "real Fresnel" mode (exponent -IOR):
  R = mix(F0 x specular tint, 1, s(h)) with F0 = ((IOR - 1) / (IOR + 1))^2 (the node's IOR; the
  Specular IOR Level does not touch this closure), F0 x tint saturated to [0, 1], and
  s(h) = (F_d(wo.h, eta) - F0(eta)) / (1 - F0(eta)) clamped to [0, 1] (F_d = 1 under total internal
  reflection: R = 1); T = (1 - R) x sqrt(base colour clamped to 1): the base colour tints the light
  that enters and leaves, the square root each time (reflection tint 1, transmission tint
  sqrt(base));
* the lobe is picked by mean(R) / mean(R + T) (Cycles' pdf_reflect over colours);
* with the node's "Multiscatter GGX" (`Material.multiscatter`), microfacet_ggx_preserve_energy with
  Fss = the transmission tint: f x (1 + F_ms (1 - E) / E), E and E_avg from the glass albedo tables
  (engine/materials/dielectric.py energy_scale).

At roughness 0 Cycles' closure is singular (a delta); here alpha is floored as every lobe's
(engine/materials/dielectric_lobe.py dielectric_alpha): the narrowest lobe.  An index-matched
interface (|eta - 1| < 1e-4) passes light straight through with weight T at normal incidence (a
delta, flags PASSED), as Cycles' singular refraction there.  Filter Glossy raises alpha to at least
ShadingPoint.alpha_floor (Cycles' bsdf_blur takes CLOSURE_BSDF_MICROFACET_GGX_GLASS_ID); the
compensation keeps the material's roughness (set up before the blur, as Cycles').

The closure's sampling weight (its share when the Principled picks a closure) is its weight's mean
times mean(R + T) at wo.n, the smooth-surface estimate (Cycles' bsdf_microfacet_estimate_albedo
reads its s(mu) table for the reflected part); it changes the noise only.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..core.vec import dot, normalize
from .dielectric import energy_scale
from .dielectric_lobe import (PASSED, REFLECTED, REFRACTED, MicrofacetDielectric, RealFresnel, dielectric_alpha,
                              refraction_eta)
from .fresnel import INDEX_MATCHED
from .microfacet import shading_frame, to_local, to_world
from .protocol import ShadingPoint
from .specular import specular_normal_at

FLAGS = REFLECTED | REFRACTED | PASSED
WEIGHT_CUTOFF = 1e-5                # Cycles' CLOSURE_WEIGHT_CUTOFF


def _f0(ior):
    ior = np.asarray(ior, dtype=np.float64)
    return ((ior - 1.0) / (ior + 1.0)) ** 2


@dataclass
class GlassSetup:
    """The closure's values at some hits, which depend on the hits and not on wi (`PrincipledGlass.setup`):
    eta and entering (refraction_eta), the frame (x, y, n) on the specular normal,
    F0 f0 and the transmission tint (3, N), wo in that frame (3, N), alpha, the compensation scale
    (3, N) or None, and where the interface is index-matched.

    Not a namespace on purpose: a ShadingPoint memo value that holds one (principled.py `_glass_setup`,
    set up at the transmitting hits only) keeps it whole on a take of the hits (protocol.py take_hits
    gathers arrays, tuples, lists and namespaces, and returns anything else as it is), while the
    value's per-hit rows into it are gathered; `at` reads it at those rows."""
    eta: np.ndarray
    entering: np.ndarray
    frame: tuple
    f0: np.ndarray
    tint: np.ndarray
    wo: np.ndarray
    alpha: np.ndarray
    scale: np.ndarray | None
    matched: np.ndarray

    def __len__(self) -> int:
        return len(self.eta)

    def at(self, rows: np.ndarray) -> "GlassSetup":
        """The values at the hits `rows` of these (ascending or not, repeated or not)."""
        def rows_of(a):
            return None if a is None else a.take(rows, axis=a.ndim - 1)
        values = {f.name: rows_of(getattr(self, f.name)) for f in fields(self) if f.name != "frame"}
        return GlassSetup(frame=tuple(rows_of(a) for a in self.frame), **values)


class PrincipledGlass:
    """The transmission closure of every material (zero weight where a material has none):
    transmission (M,) the node's Transmission Weight clamped to [0, 1] (0 below the cutoff)."""

    def __init__(self, materials, transmission, specular_tint):
        m = len(materials)
        self.transmission = np.where(transmission > WEIGHT_CUTOFF, np.clip(transmission, 0.0, 1.0), 0.0)
        self.ior = np.array([max(x.ior, 1e-5) for x in materials], dtype=np.float64).reshape(m)
        self.roughness = np.array([min(max(x.roughness, 0.0), 1.0) for x in materials], dtype=np.float64).reshape(m)
        self.alpha = dielectric_alpha(self.roughness)
        self.f0 = np.clip(_f0(self.ior)[None, :] * np.asarray(specular_tint, dtype=np.float64).reshape(3, m), 0.0, 1.0)
        self.compensate = np.array([bool(getattr(x, "multiscatter", False)) for x in materials], dtype=bool).reshape(m)
        self.lobe = MicrofacetDielectric(reflection=True, transmission=True)

    # -- per hit -------------------------------------------------------------------------------
    def setup(self, si: ShadingPoint) -> GlassSetup:
        """The closure's values at the hits `si` (`GlassSetup`; alpha: `_alpha`).  principled.py computes
        them once per bounce where the closure is set up and reads them by index (`GlassSetup.at`)."""
        mat = si.material
        eta, entering = refraction_eta(si, self.ior.take(mat))
        n = specular_normal_at(si)
        frame = (*(shading_frame(n) if self.lobe.compiled is None else self.lobe.compiled.frame(n)), n)
        tint = np.sqrt(np.clip(si.color, 0.0, 1.0))
        wo = to_local(si.wo, *frame)
        return GlassSetup(eta=eta, entering=entering, frame=frame, f0=self.f0.take(mat, axis=1), tint=tint,
                          wo=wo, alpha=self._alpha(si, mat), scale=self._scale(mat, wo[2], eta, tint),
                          matched=np.abs(eta - 1.0) < INDEX_MATCHED)

    @staticmethod
    def _fresnel(eta, f0, tint) -> RealFresnel:
        """cos -> (R, T) (3, N) each: the generalized Schlick's real-Fresnel mode (see the module)."""
        return RealFresnel(eta, f0, tint)

    def _scale(self, mat, mu, eta, tint):
        """The multiscatter compensation (3, N) where a material has it (1 elsewhere), or None."""
        on = self.compensate.take(mat)
        if not on.any():
            return None
        scale = energy_scale if self.lobe.compiled is None else self.lobe.compiled.energy_scale     # the same numbers
        return np.where(on, scale(self.roughness.take(mat), mu, eta, tint), 1.0)

    def _alpha(self, si: ShadingPoint, mat) -> np.ndarray:
        """Each hit's alpha, at least si.alpha_floor (Filter Glossy, engine/integrators/light_paths.py:
        the running Blender's Cycles blurs this GGX glass closure too); the compensation keeps the
        material's roughness (set up before the blur)."""
        alpha = self.alpha.take(mat)
        return alpha if si.alpha_floor is None else np.maximum(alpha, si.alpha_floor)

    def sample_weight(self, si: ShadingPoint) -> np.ndarray:
        """mean(R + T) (N,) at wo.n: the closure's albedo estimate (without its weight)."""
        mat = si.material                           # setup's eta, F0 and tint (not its frame)
        eta, _ = refraction_eta(si, self.ior.take(mat))
        f0, tint = self.f0.take(mat, axis=1), np.sqrt(np.clip(si.color, 0.0, 1.0))
        return self._albedo(eta, f0, tint, dot(si.wo, specular_normal_at(si)))

    def sample_weight_at(self, setup: GlassSetup) -> np.ndarray:
        """sample_weight from the hits' setup (wo's z in the frame is the same dot product)."""
        return self._albedo(setup.eta, setup.f0, setup.tint, setup.wo[2])

    def _albedo(self, eta, f0, tint, cos) -> np.ndarray:
        if self.lobe.compiled is not None:          # dielectric_jit.py albedo_coloured: the same numbers
            return self.lobe.compiled.albedo_coloured(cos, self._fresnel(eta, f0, tint))
        r, t = self._fresnel(eta, f0, tint)(np.clip(cos, 0.0, 1.0))
        return (r + t).mean(axis=0)

    def eval(self, si: ShadingPoint, wi: np.ndarray, setup: GlassSetup | None = None):
        """(f cos (3, N), pdf (N,)) of the closure without its weight; wi on either side; setup: the
        hits' `setup` when known."""
        at = self.setup(si) if setup is None else setup
        wi_l = to_local(wi, *at.frame)
        f, pdf = self.lobe.eval(at.wo, wi_l, at.alpha, at.eta, np.zeros(len(at.eta), bool),
                                fresnel=self._fresnel(at.eta, at.f0, at.tint))
        if at.scale is not None:
            f = f * at.scale
        if at.matched.any():
            f, pdf = np.where(at.matched, 0.0, f), np.where(at.matched, 0.0, pdf)
        return f, pdf

    def sample(self, si: ShadingPoint, u_lobe, u1, u2, setup: GlassSetup | None = None):
        """(wi (3, N), weight (3, N) = f cos / pdf without the closure weight, pdf (N,), flags (N,),
        refracted (N,) bool, entering (N,) bool).  The caller moves the refracted paths across the
        surface on their medium stacks (si may be a copy); setup: the hits' `setup` when known."""
        at = self.setup(si) if setup is None else setup
        fresnel = self._fresnel(at.eta, at.f0, at.tint)
        wi_l, weight, pdf, refracted, ok = self.lobe.sample(at.wo, at.alpha, at.eta, np.zeros(len(at.eta), bool),
                                                            u_lobe, u1, u2, fresnel=fresnel)
        wi = normalize(to_world(wi_l, *at.frame))
        if at.scale is not None:
            weight = weight * at.scale
        flags = np.where(refracted, np.int8(REFRACTED), np.int8(REFLECTED))
        matched = at.matched
        if matched.any():
            straight = fresnel(np.ones(len(at.eta)))[1]
            wi = np.where(matched, -si.wo, wi)
            weight = np.where(matched, straight, weight)
            pdf = np.where(matched, 1.0, pdf)
            flags = np.where(matched, np.int8(PASSED), flags)
            refracted, ok = refracted | matched, ok | matched
        weight = np.where(ok, weight, 0.0)
        return wi, weight, np.where(ok, pdf, 0.0), flags.astype(np.int8), refracted & ok, at.entering
