"""The material table: the scene's materials as arrays, and the BSDF of each material kind.

Hits are sorted by their scatter group before shading (engine/geometry/scene_geometry.py
nearest_hits), so that each BSDF scatters one contiguous slice of the wavefront.  The scatter
groups are, in this order: one per row of `SCATTERING` (the BSDF of a material kind), then
ABSORB (surfaces that absorb everything: the path ends there) and PASS_THROUGH (Blender Area
lights: their emission counts, then the ray goes on through them).

A new BSDF is one class (engine/materials/protocol.py) and one row here, for a material kind of
the scene model (engine/scene/model.py).  Some rows are not kinds: ROUGH_DIFFUSE takes the diffuse
materials with a diffuse roughness above 0 (`scatter_kind`); those of roughness 0 stay Lambertian.
The MIX row (engine/materials/mix.py) scatters through the other rows: a mix's leaves are
materials of the table too, with ids after the scene's (engine/scene/model.py with_mix_leaves).
ROUGH_GLASS and ROUGH_REFRACTION take the glass and refraction materials with a roughness above 0;
those of roughness 0 stay delta (smooth glass, smooth refraction).  Filter Glossy's blurred delta
hits (engine/integrators/delta_blur.py) scatter in `blurred_group`'s rows: BLURRED_MIRROR for
mirrors, ROUGH_GLASS and ROUGH_REFRACTION (at the material's roughness 0) for smooth glass and
refraction.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import rows
from ..scene.model import (DIFFUSE, GLASS, GLOSSY, MIRROR, MIX, PRINCIPLED, REFRACTION, TRANSLUCENT, TRANSPARENT,
                           with_mix_leaves)
from ..scene.model import PrincipledV1 as PrincipledV1Inputs
from .dielectric import RoughGlass, RoughRefraction, SmoothRefraction
from .glass import SmoothGlass
from .glossy import MicrofacetReflection
from .lambert import Lambertian
from .mirror import BlurredMirror, PerfectMirror
from .mix import MixBSDF
from .principled import PrincipledV2
from .principled_v1 import PrincipledV1
from .oren_nayar import RoughDiffuse
from .protocol import has_non_delta, sends_glossy_rays
from .translucent import Translucent
from .transparent import Transparent

# (material kind, its BSDF); the row is the kind's scatter group.
ROUGH_DIFFUSE = "rough diffuse"     # a scatter row, not a material kind: see scatter_kind
PRINCIPLED_V1 = "principled v1"     # a scatter row: Principled materials whose `principled` is a PrincipledV1
ROUGH_GLASS = "rough glass"         # a scatter row: glass of roughness above 0
ROUGH_REFRACTION = "rough refraction"
BLURRED_MIRROR = "blurred mirror"   # a scatter row: mirror hits Filter Glossy blurs (engine/integrators/delta_blur.py)
SCATTERING = ((DIFFUSE, Lambertian), (MIRROR, PerfectMirror), (GLASS, SmoothGlass),
              (GLOSSY, MicrofacetReflection), (PRINCIPLED, PrincipledV2),
              (ROUGH_DIFFUSE, RoughDiffuse), (MIX, MixBSDF), (PRINCIPLED_V1, PrincipledV1),
              (ROUGH_GLASS, RoughGlass), (REFRACTION, SmoothRefraction),
              (ROUGH_REFRACTION, RoughRefraction), (TRANSPARENT, Transparent), (TRANSLUCENT, Translucent),
              (BLURRED_MIRROR, BlurredMirror))
KIND_CODE = {kind: group for group, (kind, _) in enumerate(SCATTERING)}
ABSORB = len(SCATTERING)            # black surfaces: absorb everything
PASS_THROUGH = ABSORB + 1           # Area lights: emission, then the ray goes on
N_SCATTER_GROUPS = PASS_THROUGH + 1
# Material kinds whose BSDF has a non-delta lobe: their hits take shadow rays (engine/integrators/effects.py).
NON_DELTA_KINDS = frozenset(kind for kind, bsdf in SCATTERING if has_non_delta(bsdf.flags))
ROUGH_ROWS = {GLASS: ROUGH_GLASS, REFRACTION: ROUGH_REFRACTION}     # kind -> its row at roughness > 0
VERSIONED_ROWS = (ROUGH_DIFFUSE, ROUGH_GLASS, ROUGH_REFRACTION)    # BSDFs made with Scene.cycles_version
# The delta rows Filter Glossy blurs, and the non-delta row that scatters their blurred hits.
BLURRED_ROWS = {MIRROR: BLURRED_MIRROR, GLASS: ROUGH_GLASS, REFRACTION: ROUGH_REFRACTION}


def scatter_kind(material) -> str:
    """The row that scatters `material`: its kind's, ROUGH_DIFFUSE for a diffuse material with
    a diffuse roughness above 0 (Cycles' Oren-Nayar closure; at 0 its Lambertian one),
    PRINCIPLED_V1 for a Principled material with Blender 3.x's inputs (a PrincipledV1), ROUGH_GLASS
    / ROUGH_REFRACTION for a glass / refraction material with a roughness above 0 (or an image
    texture on that roughness: engine/materials/textures.py per_hit)."""
    textured = getattr(material, "has_input_texture", lambda name: False)
    if material.kind == DIFFUSE and (getattr(material, "diffuse_roughness", 0.0) > 0.0 or textured("diffuse_roughness")):
        return ROUGH_DIFFUSE
    if material.kind == PRINCIPLED and isinstance(getattr(material, "principled", None), PrincipledV1Inputs):
        return PRINCIPLED_V1
    rough = ROUGH_ROWS.get(material.kind)
    if rough is not None and ((getattr(material, "roughness", 0.0) or 0.0) > 0.0 or textured("roughness")):
        return rough
    return material.kind


class MaterialTable:
    """Materials as arrays indexed by material id (colours as rows (3, M)), and the BSDFs.

    bsdfs[g] scatters the hits of scatter group g < ABSORB; scatter_group[m] is the group of
    material m: its kind's, or ABSORB where its colour is black (a textured colour scatters
    whatever its unlinked value: `textured_color`, a bool per material, or None).  cycles_version:
    the scene's (engine/scene/model.py Scene), for the BSDFs whose model follows it."""

    def __init__(self, materials, settings, textured_color=None, cycles_version=(5, 0)):
        materials, leaf_ids = with_mix_leaves(materials)     # mix leaves: ids after the scene's materials
        self.kind = np.array([KIND_CODE[scatter_kind(m)] for m in materials], dtype=np.int8)
        color = np.array([m.color for m in materials], dtype=np.float64).reshape(-1, 3)
        emission = np.array([m.emission for m in materials], dtype=np.float64).reshape(-1, 3)
        self.color, self.emission = rows(color), rows(emission)
        self.is_emissive = emission.max(axis=1) > 0
        # Blender 4.x / 5.0 raise a Normal input's normal for every BSDF but Diffuse (engine/nodes/normals.py).
        self.specular_normal = np.array([m.kind != DIFFUSE for m in materials], dtype=bool)
        # ... but the Principled BSDF (v2) raises only its specular layers' normal, itself
        # (engine/materials/specular.py specular_normal_at): its diffuse and sheen keep the input's
        self.raised_normal = self.specular_normal & np.array([scatter_kind(m) != PRINCIPLED for m in materials],
                                                             dtype=bool)
        scatters = color.max(axis=1) > 0.0
        if textured_color is not None:
            scatters = scatters | textured_color
        # the Principled BSDFs' specular layer reflects on a black base
        scatters = scatters | (self.kind == KIND_CODE[PRINCIPLED]) | (self.kind == KIND_CODE[PRINCIPLED_V1])
        scatters = scatters | (self.kind == KIND_CODE[MIX])            # its leaves have their own colours
        self.scatter_group = np.where(scatters, self.kind, ABSORB).astype(np.int8)
        # Each material's row where Filter Glossy blurs its hits, -1 where it stays as it is: a
        # scattering mirror, smooth glass or refraction that is no Sharp closure of Blender 3.x.
        twins = [KIND_CODE[BLURRED_ROWS[scatter_kind(m)]]
                 if scatter_kind(m) in BLURRED_ROWS and not getattr(m, "sharp_closure", False) else -1
                 for m in materials]
        self.blurred_group = np.where(scatters, np.array(twins, dtype=np.int8), -1).astype(np.int8)
        self.bsdfs = [bsdf(materials, settings, cycles_version) if kind in VERSIONED_ROWS else bsdf(materials, settings)
                      for kind, bsdf in SCATTERING]
        self.bsdfs[KIND_CODE[MIX]].bind(self, leaf_ids)
        # Groups whose BSDF has a lobe that given directions meet (light samples, MIS, 2D uniforms).
        self.non_delta = [has_non_delta(b.flags) for b in self.bsdfs]
        # Whether any material's BSDF sends non-delta glossy or transmission rays (its flags say).
        self.glossy = any(sends_glossy_rays(self.bsdfs[row].flags) for row in np.unique(self.kind))

    def use_backend(self, backends: dict) -> None:
        """The BSDFs' kernels on the render's backends (engine/materials/protocol.py BSDF.use_backend)."""
        for bsdf in self.bsdfs:
            bsdf.use_backend(backends)
