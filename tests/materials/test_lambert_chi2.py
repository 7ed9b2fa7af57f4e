"""χ² of the Lambertian BSDF's sampler against its own pdf (tests/chi_square.py), about a tilted
shading normal, with a control: the same harness rejects a wrong pdf."""
import numpy as np

from engine import RenderSettings
from engine.materials.lambert import Lambertian
from engine.materials.protocol import ShadingPoint
from tests.chi_square import ALPHA, sphere_chi2

NORMAL = np.array([0.3, -0.5, 0.81])
NORMAL = NORMAL / np.linalg.norm(NORMAL)
WO = np.array([0.0, 0.6, 0.8])


def hits(n):
    normal = np.tile(NORMAL[:, None], (1, n))
    return ShadingPoint(np.tile(WO[:, None], (1, n)), normal, normal, normal, np.full((3, n), 0.7),
                        np.zeros(n, dtype=np.int64))


BSDF = Lambertian([], RenderSettings())


def sample(u):
    n = u.shape[1]
    return BSDF.sample(hits(n), np.zeros(n), (u[0], u[1])).wi


def pdf(d):
    return BSDF.pdf(hits(d.shape[1]), d)


def test_lambertian_sampler_matches_its_pdf():
    p, dof = sphere_chi2(sample, pdf, seed=5)
    assert dof > 100 and p > ALPHA, (p, dof)


def test_chi2_rejects_the_lambertian_sampler_against_a_wrong_pdf():
    """Control: the uniform-hemisphere density about the same normal."""
    def uniform_hemisphere(d):
        return np.where(NORMAL @ d > 0.0, 1.0 / (2.0 * np.pi), 0.0)
    assert sphere_chi2(sample, uniform_hemisphere, seed=5)[0] < 1e-6
