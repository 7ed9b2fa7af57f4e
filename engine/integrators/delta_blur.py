"""Filter Glossy on the delta lobes: Cycles blurs a sharp mirror, glass or refraction closure too.

Cycles' Glossy, Glass and Refraction BSDFs at roughness 0 are microfacet closures of alpha 0
(GGX or Beckmann), so its Filter Glossy (surface_shader_prepare_closures, bsdf_blur:
docs/cycles34-filter-glossy.md) raises their alpha to the path's blur roughness like any other:
after a diffuse or rough bounce a perfect mirror becomes a GGX lobe of alpha sqrt(1 - blur) / 2,
smooth glass a GGX glass of that alpha (its energy compensation set up from the closure's own
roughness 0: none, the single-scatter losses of that alpha stay), smooth refraction a GGX
refraction.  Blender 3.x's Sharp distribution makes other closures (REFLECTION, REFRACTION,
SHARP_GLASS) that 3.4's bsdf_blur leaves sharp: Material.sharp_closure (engine/scene/model.py).

The tracer's mirror, smooth glass and smooth refraction are delta BSDFs (engine/materials/mirror.py,
glass.py, dielectric.py SmoothRefraction); the material table gives each such material a blurred
row (MaterialTable.blurred_group: BLURRED_MIRROR, ROUGH_GLASS, ROUGH_REFRACTION, engine/materials/
table.py), whose BSDF is the non-delta lobe at the material's roughness 0 reading si.alpha_floor.
`DeltaBlur.regroup` moves the hits of paths with an alpha floor (engine/integrators/light_paths.py
blur_alpha) from the delta rows to those rows before the path tracer builds its spans, so shadow
rays, MIS, the least pdf, the bounce types, the caustics toggles and the denoising features treat
them as the non-delta lobes they are, with no other change to engine/integrators/path_tracer.py.
Paths without a floor (Filter Glossy 0, camera rays, paths of delta bounces only) keep their hits
as they are: the same HitSet, the same numbers.

The caustic photons (engine/integrators/photons/) carry the light of sharp specular chains to the
diffuse surfaces (L S+ D): with them on, a blurred lobe would add that light a second time, so the
effect plan (engine/integrators/effects.py filter_glossy) keeps delta lobes sharp then.
"""
from __future__ import annotations

import numpy as np

from ..geometry.scene_geometry import KINDS, HitSet
from .light_paths import blur_alpha


def regroup(hits: HitSet, group: np.ndarray, n_groups: int) -> HitSet:
    """`hits` with each hit in group `group` (N,) instead (in hits' order), sorted again by (group,
    primitive kind) as SceneGeometry.nearest_hits sorts them (stable: hits keep their order within
    a run)."""
    kinds = len(KINDS)
    key = group.astype(np.int64) * kinds + (hits.kind.astype(np.int64) - 1)
    order = np.argsort(key, kind="stable")
    bounds = np.searchsorted(key.take(order), np.arange(n_groups * kinds + 1)).tolist()
    runs = {}
    for g in range(n_groups):
        for k in KINDS:
            slot = g * kinds + (k - 1)
            if bounds[slot + 1] > bounds[slot]:
                runs[(g, k)] = (bounds[slot], bounds[slot + 1])
    groups = [(bounds[g * kinds], bounds[(g + 1) * kinds]) for g in range(n_groups)]
    return HitSet(hits.index.take(order), hits.miss, hits.t.take(order), hits.kind.take(order),
                  hits.prim.take(order), hits.u.take(order), hits.v.take(order), hits.material.take(order),
                  runs, groups, {k for _, k in runs})


class DeltaBlur:
    """The blur of a render's delta hits: `scatter_group` and `blurred_group` (per material id, -1:
    stays) from the material table, the Filter Glossy value of engine/integrators/light_paths.py
    LightPaths, n_groups the scatter groups (engine/materials/table.py N_SCATTER_GROUPS)."""

    def __init__(self, scatter_group: np.ndarray, blurred_group: np.ndarray, filter_glossy: float, n_groups: int):
        self.scatter_group = scatter_group
        self.blurred_group = blurred_group
        self.filter_glossy = filter_glossy
        self.n_groups = n_groups

    @classmethod
    def of(cls, mats, light_paths, n_groups: int) -> "DeltaBlur | None":
        """The blur of a render (None: nothing to blur): LightPaths with Filter Glossy on and delta lobes
        to blur (LightPaths.blur_delta) and a material that has a blurred row."""
        if light_paths is None or not light_paths.blur_delta or not (mats.blurred_group >= 0).any():
            return None
        return cls(mats.scatter_group, mats.blurred_group, light_paths.filter_glossy, n_groups)

    def regroup(self, hits: HitSet, min_pdf: np.ndarray) -> HitSet:
        """hits with the delta hits of paths with an alpha floor (min_pdf: the paths' least pdf, by ray)
        moved to their materials' blurred rows; `hits` itself where there are none."""
        if not len(hits.index):
            return hits
        twin = self.blurred_group.take(hits.material)
        candidates = np.flatnonzero(twin >= 0)
        if not len(candidates):
            return hits
        group = np.empty(len(hits.index), dtype=np.int64)
        for g, (start, stop) in enumerate(hits.groups):
            group[start:stop] = g
        # The hits' own (delta) rows only: not the rays made to absorb (the depth limit) nor lamps.
        own = group.take(candidates) == self.scatter_group.take(hits.material.take(candidates))
        floor = blur_alpha(min_pdf.take(hits.index.take(candidates)), self.filter_glossy)
        moved = candidates[own & (floor > 0.0)]
        if not len(moved):
            return hits
        group[moved] = twin.take(moved)
        return regroup(hits, group, self.n_groups)
