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


def at_hits(n, u1, u2, idx):
    """(NumPy's directions and pdfs at the hits idx, lambert_jit.sample_at's, the rows sample_at left
    alone) for the hits with shading normals n: what principled.py's diffuse picks draw."""
    from engine.materials import lambert_jit
    m = n.shape[1]
    si = ShadingPoint(-n, n, n, n, np.ones((3, m)), np.zeros(m, np.int64)).take(idx)
    reference = Lambertian([], RenderSettings()).sample(si, None, (u1.take(idx), u2.take(idx)))
    wi = np.full((3, m), 7.0)
    pdf = lambert_jit.sample_at(idx, u1, u2, n, wi)
    untouched = np.delete(wi, idx, axis=1)
    return reference, wi.take(idx, axis=1), pdf, untouched


@pytest.mark.parametrize("scene", ["cornell", "caustic"])
def test_sample_at_a_take_of_recorded_hits(scene):
    """lambert_jit.sample_at (principled_jit.py's diffuse picks, written in place) on recorded hits:
    NumPy's directions and pdfs at every other hit, the rest of wi untouched; on a slice of the
    wavefront's rows too."""
    require_compiled()
    for n, u1, u2 in capture(scene, limit=4):
        idx = np.arange(0, n.shape[1], 2)
        for normals in (n, np.concatenate([n, n], axis=1)[:, n.shape[1]:]):
            reference, wi, pdf, untouched = at_hits(normals, u1, u2, idx)
            assert np.array_equal(reference.wi, wi) and np.array_equal(reference.pdf, pdf)
            assert (untouched == 7.0).all()


def test_sample_at_hand_made_hits():
    """sample_at on the hand-made normals (z = 0, -0.0, +-1, NaN) and uniforms (near and at 1), on
    an empty take, and a control: a normal 1 ulp off at one hit is told apart."""
    require_compiled()
    rng = np.random.default_rng(8)
    n = rng.normal(size=(3, 100))
    n /= np.linalg.norm(n, axis=0)
    n[:, 0], n[:, 1], n[:, 2], n[:, 3], n[:, 4] = (1.0, 0.0, 0.0), (0.0, 1.0, -0.0), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0), np.nan
    n[2, 5:20], n[2, 20:30] = 0.0, -0.0
    u1, u2 = rng.random(100), rng.random(100)
    u1[30:35], u1[35:40], u2[40:45] = np.nextafter(1.0, 0.0), 1.0, 0.0
    idx = np.flatnonzero(rng.random(100) < 0.7)
    idx[:5] = np.arange(5)
    reference, wi, pdf, _ = at_hits(n, u1, u2, idx)
    assert np.array_equal(reference.wi, wi, equal_nan=True) and np.array_equal(reference.pdf, pdf, equal_nan=True)
    assert np.isnan(wi[:, 4]).all()
    reference, wi, pdf, untouched = at_hits(n, u1, u2, np.empty(0, dtype=np.int64))
    assert wi.shape == (3, 0) and len(pdf) == 0 and (untouched == 7.0).all()
    moved = n.copy()
    moved[0, idx[10]] = np.nextafter(moved[0, idx[10]], 2.0)
    reference = at_hits(n, u1, u2, idx)[0]
    assert not np.array_equal(reference.wi, at_hits(moved, u1, u2, idx)[1])
