"""Microfacet lobes at a smooth silhouette: the interpolated shading normal faces away from the viewer
(dot(wo, n) < 0) while the geometric normal faces it.  Cycles bends the closure normal of its Glossy,
Glass, Refraction and Principled specular closures towards the geometric normal first
(maybe_ensure_valid_specular_reflection, engine/materials/specular.py specular_normal_at), so such
hits still reflect and refract; built on the raw shading normal every sample there was lost (the
dark silhouettes of smooth rough glass).  The rendered case against Cycles:
tests/addon/test_agreement_silhouette.py."""
from types import SimpleNamespace

import numpy as np

from engine.geometry.shading_normals import ensure_valid_reflection
from engine.materials.dielectric import RoughGlass
from engine.materials.glossy import MicrofacetReflection
from engine.materials.protocol import ShadingPoint
from engine.materials.specular import specular_normal_at
from engine.scene.model import GLASS, Material

N = 2000


def silhouette(smooth=True, inside=False):
    """N hits: ng = z, the viewer 6 degrees above the surface, the shading normal tilted 20 degrees
    away from the viewer (dot(wo, n) < 0)."""
    z = np.array([0.0, 0.0, 1.0])
    wo = np.array([np.cos(np.radians(6.0)), 0.0, np.sin(np.radians(6.0))])
    n = np.array([-np.sin(np.radians(20.0)), 0.0, np.cos(np.radians(20.0))])
    assert wo @ n < 0.0 < wo @ z

    def tile(v):
        return np.tile(v[:, None], (1, N))
    return ShadingPoint(tile(wo), tile(n if smooth else z), tile(z), tile(-z if inside else z), np.ones((3, N)),
                        np.zeros(N, dtype=np.int64), smooth=smooth)


def test_specular_normal_at_is_the_valid_reflection_normal():
    si = silhouette()
    n = specular_normal_at(si)
    np.testing.assert_array_equal(n, ensure_valid_reflection(si.ng, si.wo, si.n))
    assert (np.einsum("ij,ij->j", si.wo, n) > 0.0).all()              # the viewer is above the bent normal
    r = 2.0 * np.einsum("ij,ij->j", si.wo, n) * n - si.wo
    assert (r[2] >= min(0.9 * si.wo[2, 0], 0.01) - 1e-9).all()        # its mirror direction clears the surface
    assert specular_normal_at(si) is n                                # once per hit set (ShadingPoint.memo)
    flat = silhouette(smooth=False)
    assert specular_normal_at(flat) is flat.n                         # flat shading: the normal itself


def test_rough_glass_scatters_at_a_silhouette():
    """Both sides of the interface: every sample has a finite direction, most a non-zero weight
    (before: 0 for every sample, the viewer being below the shading normal)."""
    for inside in (False, True):
        bsdf = RoughGlass([Material("G", GLASS, (1.0, 1.0, 1.0), ior=1.55, roughness=0.175,
                                    distribution="multi_ggx")], None)
        rng = np.random.default_rng(1)
        s = bsdf.sample(silhouette(inside=inside), rng.random(N), (rng.random(N), rng.random(N)))
        assert np.isfinite(s.wi).all() and np.isfinite(s.value).all()
        assert (s.value.max(axis=0) > 0.0).mean() > 0.5, inside
        f, pdf = bsdf.eval(silhouette(inside=inside), s.wi)
        assert (pdf > 0.0).mean() > 0.5


def test_glossy_reflects_at_a_silhouette():
    m = SimpleNamespace(name="G", ior=1.5, roughness=0.3, anisotropy=0.0, distribution="ggx", fresnel="none",
                        multiscatter=False, tangent=(1.0, 0.0, 0.0), rotation=0.0)
    bsdf = MicrofacetReflection([m], None)
    rng = np.random.default_rng(2)
    si = silhouette()
    s = bsdf.sample(si, rng.random(N), (rng.random(N), rng.random(N)))
    assert np.isfinite(s.wi).all()
    assert (s.value.max(axis=0) > 0.0).mean() > 0.5
    assert (s.wi[2][s.value.max(axis=0) > 0.0] > 0.0).mean() > 0.5   # mostly above the geometric surface
