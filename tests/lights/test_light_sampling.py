"""Solid-angle light samplers, the light tree and their pdfs (docs/light-sampling.md §2-§7).

Chi-square tests bin the samples into cells that partition the light exactly; a cell's
expected share is its solid angle over the light's (Van Oosterom-Strackee, independent of
the samplers' own arcsin / atan2 forms) where the sampler works by solid angle, its area share
where it falls back to area sampling.  Configurations: far and tiny, near field (1e-3 of the
light's size), off to the side, grazing, and both faces of the light.
"""
import numpy as np
import pytest

from engine.lights import LightSet
from engine.lights.parallelograms import Parallelograms
from engine.lights.selection import LightTree
from engine.lights.spheres import Spheres
from engine.lights.triangles import Triangles
from engine.scene.model import Camera, Material, Quad, Scene, Sphere, TriangleMesh

from tests.chi_square import ALPHA, pooled_chi2

N = 200_000
N_CONFIGS = 23                      # Sidak correction over the chi-square configurations below
ALPHA_EACH = 1.0 - (1.0 - ALPHA) ** (1.0 / N_CONFIGS)


def vos_omega(x, a, b, c):
    """Solid angle of triangle(s) a, b, c ((K, 3)) seen from x ((3,)): Van Oosterom-Strackee."""
    ra, rb, rc = a - x, b - x, c - x
    la, lb, lc = (np.linalg.norm(r, axis=-1) for r in (ra, rb, rc))
    num = np.abs(np.einsum("...i,...i", ra, np.cross(rb, rc)))
    den = (la * lb * lc + np.einsum("...i,...i", ra, rb) * lc + np.einsum("...i,...i", ra, rc) * lb
           + np.einsum("...i,...i", rb, rc) * la)
    return 2.0 * np.arctan2(num, den)


def lambert_irradiance(x, n, corners):
    """Omega_perp = integral of cos over a polygon wholly above x's tangent plane (Lambert)."""
    u = corners - x
    u /= np.linalg.norm(u, axis=1)[:, None]
    total = 0.0
    for i in range(len(u)):
        a, b = u[i], u[(i + 1) % len(u)]
        c = np.cross(a, b)
        theta = np.arctan2(np.linalg.norm(c), a @ b)
        total += theta * (n @ c) / np.linalg.norm(c)
    return 0.5 * abs(total)


def at(x, n):
    return np.tile(np.asarray(x, float)[:, None], n)


RECT = dict(v0=np.array([-0.5, -0.25, 0.0]), e1=np.array([1.0, 0.0, 0.0]), e2=np.array([0.0, 0.5, 0.0]))
RECT_CONFIGS = {                                    # receiver x for the 1 x 0.5 rectangle at z = 0
    "above the centre": (0.0, 0.0, 0.7),
    "near field 1e-3 below": (0.1, 0.05, -1e-3),    # the back face, as the ceiling sees a lamp
    "off to the side": (2.0, 1.5, 0.3),
    "far and small": (30.0, -20.0, 50.0),
    "very far (area fallback)": (3000.0, -2000.0, 5000.0),
    "grazing (area fallback)": (0.0, 3.0, 1e-7),
}


@pytest.mark.parametrize("where", list(RECT_CONFIGS))
def test_spherical_rectangle_chi2(where):
    light = Parallelograms(RECT["v0"][None], RECT["e1"][None], RECT["e2"][None])
    x = np.array(RECT_CONFIGS[where])
    rng = np.random.default_rng(31)
    s = light.sample_li(at(x, N), np.zeros(N, int), rng.random(N), rng.random(N))
    point, pdf = s.point, s.pdf
    assert np.isfinite(point).all() and (pdf > 0).all()
    k = 8
    s = np.clip(((point.T - RECT["v0"]) @ RECT["e1"]) / (RECT["e1"] @ RECT["e1"]), 0, 1 - 1e-12)
    t = np.clip(((point.T - RECT["v0"]) @ RECT["e2"]) / (RECT["e2"] @ RECT["e2"]), 0, 1 - 1e-12)
    assert np.abs((point.T - RECT["v0"]) @ np.array([0, 0, 1.0])).max() < 1e-9    # on the light
    counts = np.bincount((s * k).astype(int) * k + (t * k).astype(int), minlength=k * k)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    c00 = RECT["v0"] + (i.ravel()[:, None] / k) * RECT["e1"] + (j.ravel()[:, None] / k) * RECT["e2"]
    c10, c01 = c00 + RECT["e1"] / k, c00 + RECT["e2"] / k
    c11 = c10 + RECT["e2"] / k
    omega = vos_omega(x, c00, c10, c11) + vos_omega(x, c00, c11, c01)
    by_solid_angle = "fallback" not in where
    assert np.allclose(pdf, 1.0 / omega.sum(), rtol=1e-6) == by_solid_angle
    expected = N * (omega / omega.sum() if by_solid_angle else np.full(k * k, 1.0 / (k * k)))
    p, _ = pooled_chi2(counts, expected)
    assert p > ALPHA_EACH, (where, p)


TRI = (np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.2, 0.8, 0.0]))
TRI_CONFIGS = {
    "above": (0.3, 0.2, 0.5),
    "near field 1e-3 below": (0.4, 0.3, -1e-3),
    "off to the side": (-2.0, 1.0, 0.4),
    "far and small": (40.0, 30.0, -60.0),
    "very far (area fallback)": (4000.0, 3000.0, -6000.0),
}


def subtriangles(a, b, c, k):
    """The k^2 sub-triangles of a triangle, keyed by (i, j, upper)."""
    cells = {}
    e1, e2 = (b - a) / k, (c - a) / k
    for i in range(k):
        for j in range(k - i):
            p = a + i * e1 + j * e2
            cells[(i, j, 0)] = (p, p + e1, p + e2)
            if i + j < k - 1:
                cells[(i, j, 1)] = (p + e1, p + e1 + e2, p + e2)
    return cells


@pytest.mark.parametrize("where", list(TRI_CONFIGS))
def test_spherical_triangle_chi2(where):
    a, b, c = TRI
    light = Triangles(a[None], b[None], c[None])
    x = np.array(TRI_CONFIGS[where])
    rng = np.random.default_rng(32)
    s = light.sample_li(at(x, N), np.zeros(N, int), rng.random(N), rng.random(N))
    point, pdf = s.point, s.pdf
    assert np.isfinite(point).all() and (pdf > 0).all()
    k = 6
    cells = subtriangles(a, b, c, k)
    keys = list(cells)
    index = {key: n for n, key in enumerate(keys)}
    m = np.linalg.lstsq(np.stack([b - a, c - a], axis=1), (point.T - a).T, rcond=None)[0]   # (2, N)
    s, t = np.clip(m[0] * k, 0, k - 1e-9), np.clip(m[1] * k, 0, k - 1e-9)
    i, j = s.astype(int), t.astype(int)
    upper = ((s - i) + (t - j) > 1.0).astype(int)
    j = np.minimum(j, k - 1 - i)
    upper = np.where(i + j >= k - 1, 0, upper)
    lookup = np.array([index[(ii, jj, uu)] for ii, jj, uu in zip(i, j, upper)])
    counts = np.bincount(lookup, minlength=len(keys))
    omega = np.array([vos_omega(x, *(v[None] for v in cells[key]))[0] for key in keys])
    by_solid_angle = "fallback" not in where
    assert np.allclose(pdf, 1.0 / vos_omega(x, a[None], b[None], c[None])[0], rtol=1e-6) == by_solid_angle
    p, _ = pooled_chi2(counts, N * (omega / omega.sum() if by_solid_angle else np.full(len(keys), 1.0 / len(keys))))
    assert p > ALPHA_EACH, (where, p)


@pytest.mark.parametrize("distance", [1.001, 1.5, 3.0, 1e4])
def test_sphere_cone_chi2(distance):
    """From outside: directions uniform in the cone, i.e. uniform in cos(theta) and phi."""
    centre, radius = np.array([0.3, -0.2, 0.1]), 1.0
    light = Spheres([centre], [radius])
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    x = centre - distance * radius * axis
    rng = np.random.default_rng(33)
    s = light.sample_li(at(x, N), np.zeros(N, int), rng.random(N), rng.random(N))
    point, normal, pdf = s.point, s.normal, s.pdf
    assert np.abs(np.linalg.norm(point.T - centre, axis=1) - radius).max() < 1e-9 * distance
    w = point.T - x
    w /= np.linalg.norm(w, axis=1)[:, None]
    assert (np.einsum("ij,ij->i", w, normal.T) < 1e-9).all()              # the visible cap only
    cos_max = np.sqrt(1.0 - (radius / (distance * radius)) ** 2)
    one_minus = (1.0 - w @ axis) / (1.0 - cos_max)
    t1 = np.cross(axis, [0, 0, 1.0])
    t1 /= np.linalg.norm(t1)
    phi = np.arctan2(w @ np.cross(axis, t1), w @ t1) % (2 * np.pi)
    kz, kp = 10, 8
    cells = np.minimum((one_minus * kz).astype(int), kz - 1) * kp + np.minimum((phi / (2 * np.pi) * kp).astype(int), kp - 1)
    p, _ = pooled_chi2(np.bincount(cells, minlength=kz * kp), np.full(kz * kp, N / (kz * kp)))
    assert p > ALPHA_EACH
    assert np.allclose(pdf, 1.0 / (2 * np.pi * (1.0 - cos_max)), rtol=1e-6)


def cone_chi2(w, axis, one_minus_cos_max, kz=10, kp=8):
    """p-value of unit rows-of-directions w (N, 3) being uniform in the cone about `axis`."""
    one_minus = (1.0 - w @ axis) / one_minus_cos_max
    t1 = np.cross(axis, [0.3, 0.5, 0.8])
    t1 /= np.linalg.norm(t1)
    phi = np.arctan2(w @ np.cross(axis, t1), w @ t1) % (2 * np.pi)
    assert one_minus.max() <= 1.0 + 1e-6
    cells = (np.minimum((one_minus * kz).astype(int), kz - 1) * kp
             + np.minimum((phi / (2 * np.pi) * kp).astype(int), kp - 1))
    return pooled_chi2(np.bincount(cells, minlength=kz * kp), np.full(kz * kp, len(w) / (kz * kp)))[0]


@pytest.mark.parametrize("distance", [0.05, 1.0, 200.0])
def test_point_light_disk_cone_chi2(distance):
    """Point and spot lights of radius r: directions uniform in the cone of the disk facing the
    receiver (half-angle atan(r / d)), points on that disk, pdf 1 / (2 pi (1 - cos))."""
    from engine.lights.points import PointLights
    from engine.scene.model import PointLight
    centre, r = np.array([0.2, -0.1, 0.4]), 0.1
    lights = PointLights([PointLight("Bulb", tuple(centre), (1.0, 1.0, 1.0), r)])
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    x = centre - distance * axis
    rng = np.random.default_rng(7)
    s = lights.sample_li(at(x, N), np.zeros(N, int), rng.random(N), rng.random(N))
    point, pdf = s.point, s.pdf
    assert np.abs((point.T - centre) @ axis).max() < 1e-9 * max(distance, 1.0)       # on the facing disk
    assert np.linalg.norm(point.T - centre, axis=1).max() <= r * (1 + 1e-9)
    w = point.T - x
    w /= np.linalg.norm(w, axis=1)[:, None]
    one_minus_max = 1.0 - distance / np.hypot(distance, r)
    assert cone_chi2(w, axis, one_minus_max) > ALPHA_EACH
    assert np.allclose(pdf, 1.0 / (2 * np.pi * one_minus_max), rtol=1e-6)


@pytest.mark.parametrize("angle", [1e-3, 0.1])
def test_sun_cone_chi2(angle):
    """A sun of angular diameter `angle`: directions uniform in the cone of half-angle angle / 2."""
    from engine.lights.distant import SunLights
    from engine.scene.model import SunLight
    travel = np.array([1.0, 2.0, -2.0]) / 3.0
    suns = SunLights([SunLight("Sun", tuple(travel), (1.0, 1.0, 1.0), angle)], 1.0)
    rng = np.random.default_rng(8)
    s = suns.sample_li(at((0.0, 0.0, 0.0), N), np.zeros(N, int), rng.random(N), rng.random(N))
    d, pdf = s.direction, s.pdf
    one_minus_max = 1.0 - np.cos(angle / 2)
    assert cone_chi2(d.T, -travel, one_minus_max) > ALPHA_EACH
    assert np.allclose(pdf, 1.0 / (2 * np.pi * one_minus_max), rtol=1e-6) and np.isinf(s.distance).all()


def test_chi2_rejects_the_area_sampler_as_a_solid_angle_sampler():
    """Control: the same rectangle test fails when points are drawn by area (near field)."""
    light = Parallelograms(RECT["v0"][None], RECT["e1"][None], RECT["e2"][None])
    x = np.array(RECT_CONFIGS["near field 1e-3 below"])
    rng = np.random.default_rng(34)
    point = light.sample_li(at(x, N), np.zeros(N, int), rng.random(N), rng.random(N), solid_angle=False).point
    k = 8
    s = np.clip(point[0] + 0.5, 0, 1 - 1e-12)
    t = np.clip((point[1] + 0.25) / 0.5, 0, 1 - 1e-12)
    counts = np.bincount((s * k).astype(int) * k + (t * k).astype(int), minlength=k * k)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    c00 = RECT["v0"] + (i.ravel()[:, None] / k) * RECT["e1"] + (j.ravel()[:, None] / k) * RECT["e2"]
    c10, c01 = c00 + RECT["e1"] / k, c00 + RECT["e2"] / k
    omega = vos_omega(x, c00, c10, c10 + RECT["e2"] / k) + vos_omega(x, c00, c10 + RECT["e2"] / k, c01)
    assert pooled_chi2(counts, N * omega / omega.sum())[0] < 1e-6


def _mixed_scene():
    """A rectangle, a non-rectangular parallelogram, emissive triangles, a sphere and a disk light."""
    from engine.scene.model import AreaLight
    mats = [Material("Warm", emission=(3.0, 2.0, 1.0), color=(0, 0, 0)),
            Material("Cold", emission=(0.5, 0.7, 2.0), color=(0.5, 0.5, 0.5))]
    rect = Quad("Rect", np.array([[0, 0, 2], [1, 0, 2], [1, 1, 2], [0, 1, 2]], float), 0)
    skew = Quad("Skew", np.array([[2, 0, 1], [3, 0, 1], [3.5, 1, 1], [2.5, 1, 1]], float), 1)
    v = np.array([[-2, 0, 0.5], [-1, 0, 0.6], [-1.5, 1, 1.5], [-2.5, 1.2, 0.7]], float)
    mesh = TriangleMesh("Tris", v, np.array([[0, 1, 2], [0, 2, 3]]), [0, 1])
    t = np.linspace(0, -2 * np.pi, 16, endpoint=False)
    disk = np.stack([0.3 * np.cos(t), 0.3 * np.sin(t), np.full(16, 1.8)], axis=1) + [0, -2, 0]
    return Scene(Camera.look_at((0, -5, 1), (0, 0, 1)), mats, meshes=[mesh], quads=[rect, skew],
                 spheres=[Sphere("Bulb", (0.5, -1, 0.5), 0.2, 1)],
                 lights=[AreaLight("Disk", disk, (4.0, 4.0, 4.0)), AreaLight("Panel", np.array(
                     [[-1, 2, 1], [-1, 2, 2], [0, 2, 2], [0, 2, 1]], float), (1.0, 1.0, 1.0), two_sided=True)])


@pytest.mark.parametrize("solid_angle", [False, True])
def test_pdf_of_a_sampled_direction_equals_the_sampled_pdf(solid_angle):
    """sample() at (x, n) and pdf() of the same light and point agree (the MIS requirement),
    over every kind, the tree's pmf and both sides of the predicates."""
    lights = LightSet(_mixed_scene(), solid_angle=solid_angle, spatial=solid_angle)
    assert sorted(lights.kind_names()) == ["parallelogram", "polygon", "sphere", "triangle"]
    rng = np.random.default_rng(35)
    n = 50_000
    x = rng.uniform(-3, 3, (3, n))
    x[:, :200] = [[0.5], [0.5], [2.0 - 1e-7]]            # grazing under the rectangle: area branch
    x[:, 200:400] = [[0.5], [-1.0], [0.5 + 0.2 + 1e-9]]  # on the sphere: area branch
    nrm = rng.normal(size=(3, n))
    nrm /= np.linalg.norm(nrm, axis=0)
    s = lights.sample(x, nrm, rng.random(n), rng.random(n), rng.random(n))
    ok = s.pdf > 0
    assert ok.mean() > 0.9 and np.isfinite(s.pdf).all() and np.isfinite(s.point).all()
    again = lights.pdf(x[:, ok], nrm[:, ok], s.light[ok], s.point[:, ok])
    assert np.allclose(again, s.pdf[ok], rtol=1e-9, atol=0)


@pytest.mark.parametrize("where", ["above", "near field 1e-3", "near field 1e-2"])
@pytest.mark.parametrize("kind", ["rectangle", "triangles"])
def test_light_samples_integrate_cosine_to_lamberts_formula(where, kind):
    """E[cos theta_x / p_w] = Omega_perp (Lambert's polygon formula) within a 4-sigma interval."""
    corners = np.array([[-0.5, -0.25, 0], [0.5, -0.25, 0], [0.5, 0.25, 0], [-0.5, 0.25, 0]], float)
    # Two materials of one emission: the triangles are not merged into one parallelogram light.
    mats = [Material("L", emission=(1, 1, 1), color=(0, 0, 0)), Material("L2", emission=(1, 1, 1), color=(0, 0, 0))]
    if kind == "rectangle":
        scene = Scene(None, mats, quads=[Quad("L", corners, 0)])
    else:
        scene = Scene(None, mats, meshes=[TriangleMesh("L", corners, np.array([[0, 1, 2], [0, 2, 3]]), [0, 1])])
    height = {"above": 0.4, "near field 1e-3": 1e-3, "near field 1e-2": 1e-2}[where]
    x = np.array([0.2, 0.1, -height])
    n = np.array([0.0, 0.0, 1.0])
    lights = LightSet(scene)
    assert lights.kind_names() == ["parallelogram" if kind == "rectangle" else "triangle"]
    rng = np.random.default_rng(36)
    s = lights.sample(at(x, N), at(n, N), rng.random(N), rng.random(N), rng.random(N))
    w = s.point.T - x
    cos = (w @ n) / np.linalg.norm(w, axis=1)
    values = np.where(s.pdf > 0, cos / np.where(s.pdf > 0, s.pdf, 1), 0.0)
    expected = lambert_irradiance(x, n, corners)
    assert abs(values.mean() - expected) < 4 * values.std() / np.sqrt(N) + 1e-12, (values.mean(), expected)
    # Solid-angle sampling keeps the per-sample weight bounded by Omega in the near field.
    assert values.max() <= 2 * np.pi + 1e-9


def test_light_tree_pmf_sums_to_one_and_matches_its_samples():
    rng = np.random.default_rng(37)
    k = 37
    centers = rng.uniform(-5, 5, (k, 3))
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    power = rng.uniform(0.1, 3.0, k)
    cos_o = np.where(rng.random(k) < 0.5, 1.0, -1.0)
    tree = LightTree(centers, rng.uniform(0.01, 0.5, k), normals, cos_o, power, power)
    assert tree.depth == 6
    for _ in range(3):
        x = rng.uniform(-6, 6, 3)
        nrm = rng.normal(size=3)
        nrm /= np.linalg.norm(nrm)
        all_lights = np.arange(k)
        pmf = tree.pmf(at(x, k), at(nrm, k), all_lights)
        assert pmf.sum() == pytest.approx(1.0, abs=1e-12) and (pmf > 0).all()
        n = 100_000
        light, sampled_pmf = tree.sample(at(x, n), at(nrm, n), rng.random(n))
        assert np.allclose(sampled_pmf, pmf[light], rtol=1e-12)
        p, _ = pooled_chi2(np.bincount(light, minlength=k), n * pmf)
        assert p > ALPHA / 3


def test_light_tree_prefers_the_lamp_next_to_the_receiver():
    """36 small two-sided lamps 1 cm under a ceiling: a ceiling point above one of them picks it
    with most of its samples (the power pmf would give it 1/36)."""
    g = (np.arange(6) - 2.5) * 0.3
    centers = np.array([(a, b, 1.99) for a in g for b in g])
    k = len(centers)
    tree = LightTree(centers, np.full(k, 0.057), np.tile([0, 0, -1.0], (k, 1)), np.full(k, -1.0),
                     np.ones(k), np.ones(k))
    x, n = centers[14] + [0.01, 0.0, 0.01], np.array([0.0, 0.0, -1.0])
    pmf = tree.pmf(at(x, k), at(n, k), np.arange(k))
    assert pmf[14] > 0.5 and pmf.argmax() == 14


@pytest.mark.parametrize("tris", [[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]], [[0, 3, 2], [0, 2, 1]]])
def test_a_quad_made_of_two_triangles_is_one_parallelogram_light(tris):
    """Blender lamp planes arrive as two triangles: both map to one rectangle light with the
    triangles' orientation; the report's estimator keeps the two triangles."""
    corners = np.array([[0, 0, 1], [2, 0, 1], [2, 1, 1], [0, 1, 1]], float)
    scene = Scene(None, [Material("L", emission=(1, 1, 1), color=(0, 0, 0))],
                  meshes=[TriangleMesh("L", corners, np.array(tris), [0, 0])])
    lights = LightSet(scene)
    assert lights.kind_names() == ["parallelogram"] and lights.triangle_light.tolist() == [0, 0]
    winding = np.cross(*(corners[tris[0][1:]] - corners[tris[0][0]]))
    assert np.allclose(lights.kinds[0].normal[:, 0], winding / np.linalg.norm(winding))
    assert lights.area.tolist() == [2.0]
    assert LightSet(scene, solid_angle=False, spatial=False).kind_names() == ["triangle"]


def test_light_tree_pmf_stays_right_with_powers_across_40_decades():
    """Powers from 1e-40 to 1 (float32 would underflow) and a tree with empty leaves: sample() and
    pmf() agree and the pmf sums to 1."""
    rng = np.random.default_rng(38)
    k = 5                                                        # 8 leaves, 3 of them empty
    centers = rng.uniform(-1, 1, (k, 3))
    power = 10.0 ** rng.uniform(-40, 0, k)
    tree = LightTree(centers, np.full(k, 0.1), np.tile([0, 0, 1.0], (k, 1)), np.full(k, -1.0), power, power)
    x, nrm = np.array([3.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    pmf = tree.pmf(at(x, k), at(nrm, k), np.arange(k))
    assert pmf.sum() == pytest.approx(1.0, abs=1e-12)
    light, sampled = tree.sample(at(x, 20000), at(nrm, 20000), rng.random(20000))
    assert np.allclose(sampled, pmf[light], rtol=1e-12)
