"""χ² of each kind's sampler against its own pdf_li, for the samplers that
tests/lights/test_light_sampling.py does not already bin against an independent oracle: area
sampling of parallelograms (the report's estimator, and skew parallelograms under solid angle), of
triangles and of polygons, a sphere seen from inside, the world's cosine directions, and the
directions of the rays that sample_emission emits.

Two ways to bin, both with tests/chi_square.py:

* over the sphere of directions (`sphere_chi2`), where the density is smooth over the cells: the
  density of a direction d at the receiver x is pdf_li where the ray x + t d meets the light;
* on the light itself, for planar lights: every planar light is a fan of triangles, each cut into
  sub-triangles; a sample point y should have the density pdf_li(x -> y) |cos theta_y| / |y - x|^2
  per unit area, integrated over each sub-triangle (centroid rule on a finer subdivision).  The
  cells follow the light's edges; over the sphere a polygon's corner can cut a cell in a sliver
  thinner than the midpoint rule's sub-cells, which it then misses.

Either way a sampler that does not draw what pdf_li says fails.  Controls: a pdf off by 10 %,
area-sampled points against the solid-angle pdf, and two-sided emission against the one-sided
density all fail.
"""
import numpy as np
import pytest

from engine.sampling.warps import orthonormal_basis
from tests.chi_square import ALPHA, pooled_chi2, sphere_chi2
from tests.lights import kinds as K

N = 200_000
N_TESTS = 11                                   # Sidak correction over the χ² tests below
ALPHA_EACH = 1.0 - (1.0 - ALPHA) ** (1.0 / N_TESTS)


def at(v, m):
    return np.tile(np.asarray(v, dtype=np.float64)[:, None], m)


# -- binning on planar lights ------------------------------------------------------------------
def sub_triangles(a, b, c, k):
    """The k^2 sub-triangles of triangle a, b, c: (their corners, table[i, j, upper] -> number)."""
    e1, e2 = (b - a) / k, (c - a) / k
    cells, table = [], np.full((k, k, 2), -1)
    for i in range(k):
        for j in range(k - i):
            p = a + i * e1 + j * e2
            table[i, j, 0] = len(cells)
            cells.append((p, p + e1, p + e2))
            if i + j < k - 1:
                table[i, j, 1] = len(cells)
                cells.append((p + e1, p + e1 + e2, p + e2))
    return cells, table


def sub_triangle_of(points, a, b, c, k, table):
    """Number of the sub-triangle holding each point (rows) of triangle a, b, c; -1 outside it."""
    e = np.stack([b - a, c - a], axis=1)
    bary = np.linalg.lstsq(e, points - a[:, None], rcond=None)[0]
    inside = (bary >= -1e-9).all(axis=0) & (bary.sum(axis=0) <= 1 + 1e-9)
    s, t = np.clip(bary[0] * k, 0, k - 1e-9), np.clip(bary[1] * k, 0, k - 1e-9)
    i, j = s.astype(int), t.astype(int)
    j = np.minimum(j, k - 1 - i)
    upper = ((s - i) + (t - j) > 1.0) & (i + j < k - 1)
    return np.where(inside, table[i, j, upper.astype(int)], -1)


def planar_chi2(kind, i, x, corners, solid_angle=True, scale=1.0, pdf_solid_angle=None, k=6, refine=6):
    """p-value of the points sample_li draws on planar light i (corners in order) seen from x
    against pdf_li (times `scale`, with pdf_solid_angle for pdf_li's own branch)."""
    pdf_solid_angle = solid_angle if pdf_solid_angle is None else pdf_solid_angle
    rng = np.random.default_rng(41)
    s = kind.sample_li(at(x, N), np.full(N, i), rng.random(N), rng.random(N), solid_angle=solid_angle)
    assert (s.pdf > 0).all()
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    normal /= np.linalg.norm(normal)
    expected, cell = [], np.full(N, -1)                  # per cell; the cell of each sample
    for a, b, c in [(corners[0], corners[f], corners[f + 1]) for f in range(1, len(corners) - 1)]:
        cells, table = sub_triangles(a, b, c, k)
        mine = np.flatnonzero(cell < 0)
        local = sub_triangle_of(s.point[:, mine], a, b, c, k, table)
        cell[mine[local >= 0]] = len(expected) + local[local >= 0]
        for tri in cells:
            fine, _ = sub_triangles(*tri, refine)
            y = np.array([sum(t) / 3.0 for t in fine]).T                 # centroids (3, refine^2)
            area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) / refine ** 2
            w = y - x[:, None]
            d2 = (w * w).sum(axis=0)
            density = kind.pdf_li(at(x, y.shape[1]), np.full(y.shape[1], i), y, solid_angle=pdf_solid_angle) \
                * np.abs(normal @ w) / d2 ** 1.5                         # per unit area of the light
            expected.append(N * scale * (density * area).sum())
    assert (cell >= 0).all(), "a sample off the light"
    observed = np.bincount(cell, minlength=len(expected))
    return pooled_chi2(observed, np.array(expected))[0]


def parallelogram_corners(kind, i):
    v0, e1, e2 = kind.v0[:, i], kind.e1[:, i], kind.e2[:, i]
    return np.array([v0, v0 + e1, v0 + e1 + e2, v0 + e2])


def triangle_corners(kind, i):
    return np.array([kind.a[:, i], kind.b[:, i], kind.c[:, i]])


def polygon_corners(kind, i):
    return K.POLYGONS[i]


PLANAR = {   # kind, its corners, light, receiver, solid_angle
    "rectangle by area (the report)": (K.parallelograms, parallelogram_corners, 0, (0.1, 0.05, 1.2), False),
    "skew parallelogram (area under solid angle)": (K.parallelograms, parallelogram_corners, 1, (1.3, -0.6, 0.4),
                                                    True),
    "triangle by area": (K.triangles, triangle_corners, 0, (0.3, 0.2, 1.5), False),
    "disk polygon": (K.polygons, polygon_corners, 0, (0.05, -2.0, 1.5), True),
    "pentagon polygon": (K.polygons, polygon_corners, 1, (0.5, 0.6, 1.0), True),
}


@pytest.mark.parametrize("name", list(PLANAR))
def test_planar_light_sampler_against_its_pdf(name):
    make, corners_of, i, x, solid_angle = PLANAR[name]
    kind = make()
    assert planar_chi2(kind, i, np.array(x), corners_of(kind, i), solid_angle) > ALPHA_EACH


# -- binning over the sphere of directions ------------------------------------------------------
def sphere_hit(center, radius, x, d):
    """Where rays from x first meet the sphere going forward (from inside: where they leave it)."""
    rel = x - center
    b = rel @ d
    c = rel @ rel - radius * radius
    with np.errstate(invalid="ignore"):
        root = np.sqrt(b * b - c)
    t = np.where(-b - root > 0, -b - root, -b + root)
    return np.where(t > 0, x[:, None] + t * d, np.nan)


def directions_chi2(kind, i, x, hit, normal=(0.0, 0.0, 1.0), scale=1.0):
    """p-value of the directions sample_li draws towards light i from x (facing normal `normal`)
    against pdf_li at hit(d), the point where direction d meets the light (NaN: it misses)."""
    def sample(u):
        m = u.shape[1]
        s = kind.sample_li(at(x, m), np.full(m, i), u[0], u[1], at(normal, m))
        return np.where(s.pdf > 0, s.direction, 0.0)

    def pdf(d):
        p = hit(d)
        ok = np.isfinite(p).all(axis=0)
        m = int(ok.sum())
        out = np.zeros(d.shape[1])
        out[ok] = kind.pdf_li(at(x, m), np.full(m, i), p[:, ok], at(normal, m), d[:, ok])
        return out * scale
    return sphere_chi2(sample, pdf, N)[0]


def test_sphere_seen_from_inside_against_its_pdf():
    """From inside a sphere: points uniform over its area, p_w = d^2 / (A cos)."""
    kind = K.spheres()
    center, radius = kind.center[:, 1], kind.radius[1]
    x = center + np.array([0.1, 0.1, -0.2])
    assert directions_chi2(kind, 1, x, lambda d: sphere_hit(center, radius, x, d)) > ALPHA_EACH


def test_world_sampler_against_its_pdf():
    n = (0.3, -0.4, np.sqrt(0.75))
    assert directions_chi2(K.world(), 0, np.zeros(3), lambda d: d, normal=n) > ALPHA_EACH


def emitted_chi2(kind, i, pdf):
    """p-value of the directions of the rays sample_emission emits from light i against pdf(d)."""
    def sample(u):
        m = u.shape[1]
        v = np.random.default_rng(5).random((2, m))
        return kind.sample_emission(np.full(m, i), v[0], v[1], u[0], u[1]).direction
    return sphere_chi2(sample, pdf, N)[0]


def cosine_pdf(normal, two_sided):
    return lambda d: (np.abs(normal @ d) / (2 * np.pi) if two_sided else np.maximum(normal @ d, 0.0) / np.pi)


@pytest.mark.parametrize("name, make, i", [("one-sided parallelogram", K.parallelograms, 0),
                                           ("two-sided parallelogram", K.parallelograms, 1),
                                           ("one-sided polygon", K.polygons, 0)])
def test_emitted_directions_are_lambertian(name, make, i):
    kind = make()
    assert emitted_chi2(kind, i, cosine_pdf(kind.normal[:, i], not kind.one_sided[i])) > ALPHA_EACH


def test_point_lights_emit_in_every_direction():
    assert emitted_chi2(K.point_lights(), 1, lambda d: np.full(d.shape[1], 1 / (4 * np.pi))) > ALPHA_EACH


def cone_to_sphere(directions, axis, one_minus):
    """Directions in the cone of 1 - cos = one_minus about `axis`, mapped onto the whole sphere by
    the map that takes the cone's uniform density to the sphere's (cos to the axis stretched onto
    [-1, 1], the azimuth kept); directions outside the cone become zeros (counted in no cell).
    A cone's sharp edge cuts the χ² grid's cells, so its samplers are tested through this map."""
    t1, t2 = orthonormal_basis(axis[:, None])
    local = np.stack([(t1 * directions).sum(axis=0), (t2 * directions).sum(axis=0), axis @ directions])
    z = 1.0 - 2.0 * (1.0 - local[2]) / one_minus
    inside = z >= -1.0
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0) / np.maximum(local[0] ** 2 + local[1] ** 2, 1e-300))
    out = np.stack([local[0] * r, local[1] * r, z])
    return np.where(inside, out, 0.0)


def emitted_in_cone_chi2(kind, i, axis, one_minus, scale=1.0):
    """p-value of the directions light i emits, mapped from the cone onto the sphere, against the
    sphere's uniform density (times scale)."""
    def sample(u):
        m = u.shape[1]
        v = np.random.default_rng(5).random((2, m))
        return cone_to_sphere(kind.sample_emission(np.full(m, i), v[0], v[1], u[0], u[1]).direction, axis, one_minus)
    return sphere_chi2(sample, lambda d: np.full(d.shape[1], scale / (4 * np.pi)), N)[0]


def spot_cone(kind, i):
    k = kind.spot_slot[i]
    return kind.spot_axis[:, k], 1.0 - kind.spot_cos_half[k]


@pytest.mark.parametrize("i", [2, 3])
def test_spot_lights_emit_uniformly_in_their_cone(i):
    kind = K.point_lights()
    assert emitted_in_cone_chi2(kind, i, *spot_cone(kind, i)) > ALPHA_EACH


def test_a_soft_sun_emits_uniformly_in_its_cone():
    kind = K.suns()
    assert emitted_in_cone_chi2(kind, 1, -kind.axis[:, 1], kind.one_minus_cos[1]) > ALPHA_EACH


def test_the_world_emits_in_every_direction():
    assert emitted_chi2(K.world(), 0, lambda d: np.full(d.shape[1], 1 / (4 * np.pi))) > ALPHA_EACH


# -- controls ----------------------------------------------------------------------------
def test_a_spot_emitting_over_the_whole_sphere_fails():
    """Control: a point light's rays (the whole sphere) fail the spot's cone test, and so do the
    spot's rays against a cone 10 % narrower."""
    kind = K.point_lights()
    axis, one_minus = spot_cone(kind, 2)
    assert emitted_in_cone_chi2(kind, 1, axis, one_minus) < 1e-6          # the point light's sphere
    assert emitted_in_cone_chi2(kind, 2, axis, one_minus * 0.9) < 1e-6    # a cone 10 % too narrow


def test_a_pdf_off_by_ten_percent_fails():
    make, corners_of, i, x, solid_angle = PLANAR["pentagon polygon"]
    kind = make()
    assert planar_chi2(kind, i, np.array(x), corners_of(kind, i), solid_angle, scale=1.1) < 1e-6
    assert directions_chi2(K.world(), 0, np.zeros(3), lambda d: d, scale=1.1) < 1e-6


def test_area_sampled_points_fail_against_the_solid_angle_pdf():
    kind = K.parallelograms()
    x = np.array([0.1, 0.05, 1.9])
    assert planar_chi2(kind, 0, x, parallelogram_corners(kind, 0), False, pdf_solid_angle=True) < 1e-6


def test_two_sided_emission_fails_against_the_one_sided_density():
    kind = K.parallelograms()
    assert emitted_chi2(kind, 1, cosine_pdf(kind.normal[:, 1], False)) < 1e-6
