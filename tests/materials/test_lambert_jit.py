"""The compiled Lambertian sampling (engine/materials/lambert_jit.py) against the NumPy path of
engine/materials/lambert.py: directions and pdfs bit for bit on the diffuse hits of real renders of
built-in scenes (recorded from Lambertian.sample) and on hand-made normals (the Cornell walls' z = 0
and -0.0, z = +-1, u near 1, a NaN normal); a control shows the comparison sees a last-bit change."""
import numpy as np
import pytest

from engine.core.settings import RenderSettings
from engine.materials.lambert import Lambertian
from engine.materials.protocol import ShadingPoint
from tests.backend_capture import recorded, require_compiled, same_bsdf_sample

TWIN = "engine.materials.lambert_jit"       # imported by use_backend, not here: numba may be missing


def capture(scene_name, limit=8):
    """[(shading normals, u1, u2)] of Lambertian.sample in a 16 x 16, 2 spp NumPy render."""
    return recorded(Lambertian, "sample", scene_name,
                    lambda self, si, u_lobe, u: (np.array(si.n), u[0].copy(), u[1].copy()), limit)


def both(n, u1, u2):
    """(NumPy's sample, the compiled one) of the hits with shading normals n."""
    m = n.shape[1]
    si = ShadingPoint(-n, n, n, n, np.ones((3, m)), np.zeros(m, np.int64))
    bsdf = Lambertian([], RenderSettings())
    reference = bsdf.sample(si, None, (u1, u2))
    bsdf.use_backend({"wavefront": "numba"})
    assert bsdf.jit is not None
    return reference, bsdf.sample(si, None, (u1, u2))


same = same_bsdf_sample


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_recorded_hits_sample_the_same(scene):
    require_compiled()
    calls = capture(scene)
    assert len(calls) >= 4
    for n, u1, u2 in calls:
        assert same(*both(n, u1, u2))
        # a slice of the wavefront's rows (as the path tracer passes them), not a copy
        wide = np.concatenate([n, n], axis=1)
        assert same(*both(wide[:, n.shape[1]:], u1, u2))


def test_hand_made_normals():
    require_compiled()
    rng = np.random.default_rng(3)
    n = rng.normal(size=(3, 400))
    n /= np.linalg.norm(n, axis=0)
    n[:, 0], n[:, 1], n[:, 2], n[:, 3] = (1.0, 0.0, 0.0), (0.0, 1.0, -0.0), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)
    n[:, 4] = np.nan
    n[2, 5:40] = 0.0
    n[2, 40:60] = -0.0
    u1, u2 = rng.random(400), rng.random(400)
    u1[60:70], u2[70:80] = np.nextafter(1.0, 0.0), 0.0
    u1[80:90] = 1.0                                         # clamped below 1
    reference, compiled = both(n, u1, u2)
    assert same(reference, compiled)
    assert np.isnan(compiled.wi[:, 4]).all()


def test_control_a_last_bit_change_is_seen():
    """The comparison is exact: float64 trigonometry in place of the float32 one (about 1e-7 rad)
    changes the directions, and `same` says so."""
    require_compiled()
    n, u1, u2 = capture("cornell", limit=1)[0]
    reference, compiled = both(n, u1, u2)
    phi = 2.0 * np.pi * u2
    r = np.sqrt(np.minimum(u1, np.nextafter(1.0, 0.0)))
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - np.minimum(u1, np.nextafter(1.0, 0.0)))])
    from engine.sampling.warps import to_world
    wrong = type(compiled)(to_world(local, n), compiled.value, compiled.pdf, compiled.flags)
    assert np.allclose(wrong.wi, reference.wi, atol=1e-6)
    assert not same(reference, wrong)
