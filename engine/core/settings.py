"""Render settings: every knob the study, the CLI and the Blender panels expose."""
from __future__ import annotations

import numbers
import os
from dataclasses import dataclass, asdict

from .errors import SceneError

FRESNEL_MODELS = ("schlick", "exact")
ACCELERATORS = ("auto", "embree", "octree", "brute")
# report: eq. 2.11 as written (area sampling, pdf 1/A, power pmf, no MIS);
# solid-angle: solid-angle light sampling and a spatial light pmf, emission after diffuse dropped;
# mis: solid-angle light sampling combined with the cosine BSDF sample by MIS (power heuristic).
ESTIMATORS = ("mis", "solid-angle", "report")
# sobol: Owen-scrambled Sobol' points per pixel (engine/sampling/qmc.py); random: independent uniforms.
SAMPLERS = ("sobol", "random")
# Render passes besides Combined (engine/film/passes.py says what each is).
PASSES = ("albedo", "normal", "depth", "samples", "variance")
INT32_MAX = 2**31 - 1
# Allowed range of every integer knob, checked by validate() and by both command lines.
INT_LIMITS = {
    "samples": (1, INT32_MAX),
    "shadow_rays": (0, 1024),
    "max_depth": (0, INT32_MAX - 1),
    "rr_start_depth": (0, INT32_MAX),
    "threads": (0, 1024),
    "seed": (0, INT32_MAX),
    "tile_size": (8, 16384),
    "min_samples": (0, INT32_MAX),
    "sample_net": (0, INT32_MAX),
}


@dataclass
class RenderSettings:
    samples: int = 16             # camera rays per pixel (report 2.3)
    shadow_rays: int = 1          # N_s in eq. 2.11
    max_depth: int = 8            # bounces after the camera hit; 0 = direct light only (report 3.4)
    russian_roulette: bool = True  # report 2.4
    rr_start_depth: int = 3       # roulette only from this bounce on
    fresnel: str = "schlick"      # eq. 2.17, or exact dielectric Fresnel as Cycles
    nested_dielectrics: bool = False  # medium stack: glass in glass refracts by the IOR ratio
    estimator: str = "mis"        # ESTIMATORS: how direct light is estimated
    sampler: str = "sobol"        # SAMPLERS: where the uniform numbers come from
    # The size of each pixel's Sobol' net (engine/sampling/qmc.py: sample i depends on it); 0 = samples.
    # Estimate Render Time's pilot (engine/rendering/estimate.py) renders the real render's first passes with
    # the real render's nets, and so the very samples that render starts with.
    sample_net: int = 0
    threads: int = 0              # 0 = all cores
    seed: int = 0
    tile_size: int = 64
    accelerator: str = "auto"
    parallelism: str = "auto"     # threads | processes (forked, Linux, outside Blender) | auto
    # Stopping rules (engine/rendering/stopping.py): the render stops at whichever comes first of `samples`,
    # the time limit and the noise target; 0 = off.  min_samples: every pixel gets at least these
    # (0 = auto) before the noise target may stop it; adaptive: with a noise target, blocks whose
    # estimated error reached it get no more samples.
    time_limit: float = 0.0       # seconds of rendering
    noise_target: float = 0.0     # estimated relative error of the image (README: Stopping rules)
    min_samples: int = 0
    adaptive: bool = True

    def stopping_rules(self) -> bool:
        """True when the frame renders in passes (engine/rendering/stopping.py)."""
        return self.time_limit > 0 or self.noise_target > 0
    passes: tuple = ()            # engine/film/passes.py PASSES: extra render passes (albedo, normal, depth, ...)
    denoise: bool = False         # OIDN on the result, guided by albedo and normal (engine/film/denoise.py)

    def resolved_threads(self) -> int:
        return self.threads if self.threads > 0 else (os.cpu_count() or 1)

    def validate(self) -> None:
        for name, (low, high) in INT_LIMITS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
                raise SceneError(f"{name.replace('_', ' ')} must be an integer from {low} to {high:,}, "
                                 f"got {value!r}")
        if self.fresnel not in FRESNEL_MODELS:
            raise SceneError(f"unknown Fresnel model '{self.fresnel}' (expected schlick or exact)")
        if self.estimator not in ESTIMATORS:
            raise SceneError(f"unknown estimator '{self.estimator}' (expected one of {', '.join(ESTIMATORS)})")
        if self.sampler not in SAMPLERS:
            raise SceneError(f"unknown sampler '{self.sampler}' (expected one of {', '.join(SAMPLERS)})")
        if self.accelerator not in ACCELERATORS:
            raise SceneError(f"unknown accelerator '{self.accelerator}' (expected one of {', '.join(ACCELERATORS)})")
        for name, high in (("time_limit", 1e9), ("noise_target", 1.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not 0.0 <= value <= high:
                raise SceneError(f"{name.replace('_', ' ')} must be a number from 0 (off) to {high:g}, got {value!r}")
        bad = [p for p in self.passes if p not in PASSES]
        if bad:
            raise SceneError(f"unknown pass '{bad[0]}' (known: {', '.join(PASSES)})")
        if self.parallelism not in ("auto", "threads", "processes"):
            raise SceneError(f"unknown parallelism '{self.parallelism}' (expected auto, threads or processes)")

    def as_dict(self) -> dict:
        return asdict(self)
