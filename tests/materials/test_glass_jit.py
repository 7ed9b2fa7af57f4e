"""The compiled smooth-glass sampling (engine/materials/glass_jit.py) against the NumPy path of
engine/materials/glass.py: directions, pdfs and flags bit for bit on the glass hits of real renders of
built-in scenes (recorded from SmoothGlass.sample) and on hand-made ones (both Fresnel models, total
internal reflection, index-matched glass, grazing and NaN directions); a control shows the comparison
sees a last-bit change."""
from types import SimpleNamespace

import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.materials.glass import SmoothGlass
from engine.materials.protocol import ShadingPoint
from tests.backend_capture import recorded, require_compiled, same_bsdf_sample

TWIN = "engine.materials.glass_jit"         # imported by use_backend, not here: numba may be missing


def capture(scene_name, limit=8):
    """[(bsdf, ShadingPoint fields, u_lobe)] of SmoothGlass.sample in a 16 x 16, 2 spp NumPy render."""
    def record(self, si, u_lobe, u=None):
        if si.media is None and not si.smooth:
            return self, tuple(np.array(a) for a in (si.wo, si.n, si.ng, si.normal, si.color, si.material)), u_lobe.copy()
        return None
    return recorded(SmoothGlass, "sample", scene_name, record, limit)


def both(bsdf, fields, u_lobe, sliced=False):
    """(NumPy's sample, the compiled one); sliced: the rows as views of wider arrays (as the path tracer's)."""
    if sliced:
        m = len(u_lobe)
        fields = tuple(np.concatenate([a, a], axis=-1)[..., m:] if a.ndim == 2 else a for a in fields)
    bsdf.jit = None
    reference = bsdf.sample(ShadingPoint(*fields), u_lobe)
    bsdf.use_backend({"wavefront": "numba"})
    assert bsdf.jit is not None
    try:
        return reference, bsdf.sample(ShadingPoint(*fields), u_lobe)
    finally:
        bsdf.jit = None


same = same_bsdf_sample


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_recorded_hits_sample_the_same(scene):
    require_compiled()
    calls = capture(scene)
    assert len(calls) >= 4
    for bsdf, fields, u_lobe in calls:
        assert same(*both(bsdf, fields, u_lobe))
        assert same(*both(bsdf, fields, u_lobe, sliced=True))


@pytest.mark.parametrize("fresnel", ["schlick", "exact"])
def test_hand_made_hits(fresnel):
    require_compiled()
    rng = np.random.default_rng(7)
    m = 2000
    materials = [SimpleNamespace(ior=ior) for ior in (1.5, 1.00001, 2.4, 1.0)]
    bsdf = SmoothGlass(materials, RenderSettings(fresnel=fresnel))
    normal = rng.normal(size=(3, m))
    normal /= np.linalg.norm(normal, axis=0)
    wo = rng.normal(size=(3, m))
    wo /= np.linalg.norm(wo, axis=0)
    wo[:, :100] = normal[:, :100]                                       # normal incidence
    graze = np.cross(normal[:, 100:200].T, rng.normal(size=(100, 3))).T      # in the plane: cos 0
    wo[:, 100:200] = graze / np.linalg.norm(graze, axis=0)
    wo[:, 200] = np.nan
    facing = np.where((wo * normal).sum(axis=0) >= 0.0, normal, -normal)   # ng, n: towards the viewer
    material = rng.integers(0, len(materials), m)
    u_lobe = rng.random(m)
    u_lobe[300:310] = 0.0
    reference, compiled = both(bsdf, (wo, facing, facing, normal, rng.random((3, m)), material), u_lobe)
    assert same(reference, compiled)
    leaving = (wo * normal).sum(axis=0) < 0.0
    assert (reference.pdf == 1.0).any() and leaving.any()                 # total internal reflection


def test_control_a_last_bit_change_is_seen():
    """Directions to the viewer one ulp off (the error a reordered dot product makes) change the
    sampled directions, and `same` says so."""
    require_compiled()
    bsdf, (wo, n, ng, normal, color, material), u_lobe = capture("caustic", limit=1)[0]
    reference, _ = both(bsdf, (wo, n, ng, normal, color, material), u_lobe)
    _, wrong = both(bsdf, (np.nextafter(wo, np.inf), n, ng, normal, color, material), u_lobe)
    assert np.allclose(reference.wi, wrong.wi, atol=1e-12)
    assert not same(reference, wrong)
