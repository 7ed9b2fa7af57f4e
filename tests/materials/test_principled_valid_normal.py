"""The Principled BSDF v2's microfacet lobes see Cycles' valid-reflection normal under smooth
shading (engine/materials/principled.py _views; Cycles' closure.h valid_reflection_N =
maybe_ensure_valid_specular_reflection, applied to the metallic, specular and transmission
closures), not the raw shading normal.  Where the mirror direction of wo about the interpolated
normal points below the geometric surface (a low-poly smooth cone's tip and base: the Ignis
evaluation scene sun.blend, docs/materials.md "Files made by others"), the raw normal sends a
near-mirror metal's reflection into the surface: it went dark there against Cycles."""
import numpy as np

from engine.core.vec import dot, normalize
from engine.geometry.shading_normals import ensure_valid_reflection
from engine.materials.principled import PrincipledV2
from engine.materials.protocol import ShadingPoint
from engine.materials.specular import specular_normal_at
from engine.scene.model import PRINCIPLED, Material, Principled

N = 4000
NG = np.array([0.0, 0.0, 1.0])
SHADING = normalize(np.array([[0.8], [0.0], [0.6]]))[:, 0]       # tilted 53 degrees from ng
WO = normalize(np.array([[-0.55], [0.0], [0.835]]))[:, 0]        # its mirror about SHADING is below ng


def hits(smooth=True):
    def tile(v):
        return np.tile(np.asarray(v, dtype=np.float64)[:, None], (1, N))
    return ShadingPoint(tile(WO), tile(SHADING if smooth else NG), tile(NG), tile(NG), tile((0.9, 0.9, 0.9)),
                        np.zeros(N, dtype=np.int64), smooth=smooth)


def metal(roughness=0.06):
    return PrincipledV2([Material("M", PRINCIPLED, (0.9, 0.9, 0.9), roughness=roughness,
                                  principled=Principled(metallic=1.0))], None)


def test_the_raw_shading_normal_reflects_below_the_surface():
    """The case is one (control): the mirror direction of wo about SHADING is below ng."""
    r = 2.0 * SHADING.dot(WO) * SHADING - WO
    assert WO.dot(SHADING) > 0.0 and r.dot(NG) < 0.0


def test_microfacet_lobes_see_the_valid_reflection_normal():
    """The metal and specular lobes build their frames on the valid normal (specular_normal_at of
    the views they are given); the diffuse lobe keeps the shading normal."""
    bsdf, si = metal(), hits()
    metal_view, specular_view, diffuse_view = bsdf._views(si)
    valid = ensure_valid_reflection(si.ng, si.wo, si.n)
    assert np.allclose(specular_normal_at(metal_view), valid) and np.allclose(specular_normal_at(specular_view), valid)
    assert not np.allclose(valid, si.n)
    assert diffuse_view.n is si.n                              # the diffuse lobe keeps the shading normal


def test_near_mirror_metal_reflects_above_the_surface():
    """With the valid normal the reflection leaves just above the geometric surface, carrying
    most of the metal's reflectance; with the raw one (the old behaviour) no sample left above
    the surface: the light was lost."""
    rng = np.random.default_rng(3)
    si = hits()
    s = metal().sample(si, rng.random(N), (rng.random(N), rng.random(N)))
    above = dot(s.wi, si.ng) > 0.0
    assert above.mean() > 0.8
    throughput = np.where(above, s.value.mean(axis=0), 0.0).mean()
    assert throughput > 0.5, throughput
