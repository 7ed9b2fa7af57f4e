"""Sampling routines: chi-square goodness of fit (docs/hard-cases.md §3.1) and edge cases."""
import numpy as np
import pytest

from engine.lights import LightSet
from engine.sampling.warps import (cosine_directions, cosine_hemisphere, orthonormal_basis, to_world,
    uniform_triangle)
from engine.scene.model import Camera, Material, Quad, Scene, Sphere, TriangleMesh
from tests.chi_square import ALPHA, pooled_chi2, sphere_chi2


def test_sphere_chi2_accepts_cosine_sampling_and_rejects_uniform():
    """The shared harness (tests/chi_square.py) on a sampler with a closed-form density, and its
    control: the same density against uniform hemisphere sampling."""
    def cosine(u):
        return cosine_hemisphere(u[0], u[1])
    def uniform(u):
        z = u[0]
        r = np.sqrt(1 - z * z)
        return np.stack([r * np.cos(2 * np.pi * u[1]), r * np.sin(2 * np.pi * u[1]), z])
    def cos_pdf(d):
        return np.maximum(d[2], 0.0) / np.pi
    assert sphere_chi2(cosine, cos_pdf, seed=3)[0] > ALPHA
    assert sphere_chi2(uniform, cos_pdf, seed=3)[0] < 1e-6


def cosine_cells(z_bins, phi_bins, n):
    """Exact expected counts of cosine sampling over (z = cos theta, phi) cells."""
    z = np.linspace(0, 1, z_bins + 1)
    per_z = (z[1:] ** 2 - z[:-1] ** 2)          # integral of cos over the z band, normalised
    return n * np.repeat(per_z[:, None], phi_bins, axis=1).ravel() / phi_bins


def histogram_directions(d, z_bins, phi_bins):
    z = np.clip(d[:, 2], 0, np.nextafter(1, 0))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    iz = np.minimum((z * z_bins).astype(int), z_bins - 1)
    ip = np.minimum((phi / (2 * np.pi) * phi_bins).astype(int), phi_bins - 1)
    return np.bincount(iz * phi_bins + ip, minlength=z_bins * phi_bins)


def test_cosine_hemisphere_chi2():
    rng = np.random.default_rng(10)
    n = 1_000_000
    d = cosine_hemisphere(rng.random(n), rng.random(n)).T      # rows -> (N, 3)
    assert (d[:, 2] > 0).all()
    p, dof = pooled_chi2(histogram_directions(d, 40, 40), cosine_cells(40, 40, n))
    assert dof > 100
    assert p > ALPHA


def test_chi2_rejects_a_wrong_hemisphere_sampler():
    """The same harness must fail a uniform-hemisphere sampler (the test has power)."""
    rng = np.random.default_rng(11)
    n = 200_000
    z = rng.random(n)
    r = np.sqrt(1 - z * z)
    phi = 2 * np.pi * rng.random(n)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    p, _ = pooled_chi2(histogram_directions(d, 40, 40), cosine_cells(40, 40, n))
    assert p < 1e-6


@pytest.mark.parametrize("normal", [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1, 0), (1, 0, -0.0), (0, 1, -0.0),
                                    (0.00038527316, 0.00038460016, -0.99999988079),
                                    (-0.00019813581, -0.00008946839, -0.99999988079)])
def test_orthonormal_basis_is_orthonormal(normal):
    n = np.array([normal], dtype=float)
    n /= np.linalg.norm(n)
    t, b = orthonormal_basis(n.T)
    m = np.stack([t[:, 0], b[:, 0], n[0]])
    assert np.isfinite(m).all()
    assert np.abs(m @ m.T - np.eye(3)).max() < 1e-10


def test_cosine_sample_at_u_one_keeps_positive_pdf():
    # docs/hard-cases.md S1: u -> 1 would give z = 0, pdf 0 and 0/0 downstream.
    u = np.array([np.nextafter(1.0, 0.0), 1.0, float(np.float32(1 - 2 ** -25))])
    d = cosine_hemisphere(u, np.full(3, 0.3)).T
    assert (d[:, 2] > 0).all()
    assert np.allclose(np.linalg.norm(d, axis=1), 1, atol=1e-12)


def test_to_world_keeps_directions_in_the_normal_hemisphere():
    rng = np.random.default_rng(12)
    n = rng.normal(size=(5000, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    d = to_world(cosine_hemisphere(rng.random(5000), rng.random(5000)), n.T).T
    assert (np.einsum("ij,ij->i", d, n) > 0).all()


def test_integrator_bounce_equals_the_tested_sampler_in_the_normal_frame():
    """cosine_directions (what the integrator calls) is the chi-square-tested cosine_hemisphere
    rotated by the tested orthonormal basis, including normals along the axes and -0.0."""
    rng = np.random.default_rng(16)
    n = rng.normal(size=(5000, 3))
    n[:6] = [(1, 0, 0), (0, -1, 0), (1, 0, -0.0), (0, 0, -1), (0, 0, 1), (0, 1, -0.0)]
    n = (n / np.linalg.norm(n, axis=1)[:, None]).T.copy()
    u1, u2 = rng.random(5000), rng.random(5000)
    expected = to_world(cosine_hemisphere(u1, u2), n)
    assert np.abs(cosine_directions(u1, u2, n) - expected).max() < 1e-12


def _light_scene(shape="parallelogram"):
    """A 2x1 light at z = 1: one quad (sampled as a parallelogram) or two mesh triangles."""
    mats = [Material("L", emission=(1, 1, 1), color=(0, 0, 0))]
    corners = np.array([[0, 0, 1], [2, 0, 1], [2, 1, 1], [0, 1, 1]], float)
    camera = Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0))
    if shape == "parallelogram":
        return Scene(camera, mats, quads=[Quad("Light", corners, 0)])
    return Scene(camera, mats, meshes=[TriangleMesh("Light", corners, np.array([[0, 1, 2], [0, 2, 3]]), [0, 0])])


def area_density(x, s):
    """Density per unit area of light samples s drawn at receivers x: p_w |cos theta_y| / d^2."""
    w = s.point - x
    d2 = (w * w).sum(axis=0)
    return s.pdf * np.abs((s.normal * w).sum(axis=0)) / (d2 * np.sqrt(d2))


@pytest.mark.parametrize("shape", ["parallelogram", "triangles"])
def test_light_area_sampler_chi2(shape):
    """The report's estimator: points on a 2x1 light uniform over its area (pdf 1/A, eq. 2.11)."""
    lights = LightSet(_light_scene(shape), solid_angle=False, spatial=False)
    assert lights.kind_names() == (["parallelogram"] if shape == "parallelogram" else ["triangle"])
    rng = np.random.default_rng(13)
    n = 400_000
    x = np.tile([[0.3], [0.2], [0.0]], n)
    normal = np.tile([[0.0], [0.0], [1.0]], n)
    s = lights.sample(x, normal, rng.random(n), rng.random(n), rng.random(n))
    assert np.allclose(area_density(x, s), 0.5)
    assert np.allclose(s.point[2], 1.0)
    bx, by = 20, 10
    ix = np.minimum((s.point[0] / 2 * bx).astype(int), bx - 1)
    iy = np.minimum((s.point[1] * by).astype(int), by - 1)
    counts = np.bincount(ix * by + iy, minlength=bx * by)
    p, _ = pooled_chi2(counts, np.full(bx * by, n / (bx * by)))
    assert p > ALPHA


def test_chi2_rejects_a_non_uniform_triangle_sampler():
    rng = np.random.default_rng(14)
    n = 200_000
    u1, u2 = rng.random(n), rng.random(n)
    b1, b2 = u1 * (1 - u2), u1 * u2          # missing sqrt: clusters at vertex 0
    right_b1, right_b2 = uniform_triangle(u1, u2)
    bins = 10

    def counts(b1, b2):
        return np.bincount(np.minimum(((b1 + b2) ** 2 * bins).astype(int), bins - 1), minlength=bins)
    expected = np.full(bins, n / bins)      # (b1 + b2)^2 is uniform for a uniform sampler
    assert pooled_chi2(counts(right_b1, right_b2), expected)[0] > ALPHA
    assert pooled_chi2(counts(b1, b2), expected)[0] < 1e-6


def test_lights_picked_by_power():
    mats = [Material("Dim", color=(0, 0, 0), emission=(1, 1, 1)),
            Material("Bright", color=(0, 0, 0), emission=(3, 3, 3))]
    q = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    scene = Scene(Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)), mats,
                  quads=[Quad("Dim", q, 0), Quad("Bright", q + [5, 0, 0], 1)],
                  spheres=[Sphere("Zero", (9, 9, 9), 1.0, 0)])
    lights = LightSet(scene, solid_angle=False, spatial=False)
    rng = np.random.default_rng(15)
    n = 100_000
    x = np.tile([[20.0], [20.0], [20.0]], n)
    s = lights.sample(x, -x / np.sqrt(1200.0), rng.random(n), rng.random(n), rng.random(n))
    # Estimator of total power over area: E[Le / p_A] = sum(A_i * Le_i)
    assert np.mean(s.radiance[0] / area_density(x, s)) == pytest.approx(1 + 3 + 4 * np.pi, rel=1e-9)
