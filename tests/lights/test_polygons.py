"""engine/lights/polygons.py: planar convex polygon emitters, sampled uniformly by area.

Geometry (area, normal from the corner order, centre and bounding radius), the fan-triangle pick in
proportion to area (χ²; control: the same counts fail against equal shares), the density
p_w = d^2 / (A |cos theta_y|) against an independent computation, and which scene emitters the
light set makes polygons of.
"""
import numpy as np
import pytest

from engine.lights import LightSet
from engine.lights.polygons import Polygons
from engine.scene.model import AreaLight, Material, Quad, Scene

from tests.chi_square import ALPHA, pooled_chi2
from tests.lights.kinds import PENTAGON, disk

N = 200_000


def fan_areas(corners):
    return np.array([0.5 * np.linalg.norm(np.cross(corners[k] - corners[0], corners[k + 1] - corners[0]))
                     for k in range(1, len(corners) - 1)])


def test_geometry_of_a_regular_polygon_and_of_a_pentagon():
    r, sides = 0.3, 16
    light = Polygons([disk((1.0, 2.0, 3.0), r, sides), disk((1.0, 2.0, 3.0), r, sides, normal_sign=-1.0), PENTAGON])
    assert light.count == 3
    assert light.area[:2] == pytest.approx(0.5 * sides * r * r * np.sin(2 * np.pi / sides), rel=1e-12)
    assert light.area[2] == pytest.approx(fan_areas(PENTAGON).sum(), rel=1e-12)
    # The normal follows the corner order counter-clockwise; the reversed order flips it.
    assert np.allclose(light.normal.T, [[0, 0, 1], [0, 0, -1], [0, 0, 1]], atol=1e-12)
    assert np.allclose(light.center[:, 0], [1.0, 2.0, 3.0]) and light.radius[0] == pytest.approx(r)
    assert light.radius[2] == pytest.approx(np.linalg.norm(PENTAGON - PENTAGON.mean(axis=0), axis=1).max())


def fan_triangle_of(points, corners):
    """Index of the fan triangle (corner 0, k + 1, k + 2) each point (rows) lies in."""
    rel = points.T - corners[0]
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    angle = [np.cross(corners[k] - corners[0], rel) @ normal for k in range(1, len(corners))]   # side of each diagonal
    return (np.array(angle[1:-1]) >= 0).sum(axis=0) if len(corners) > 3 else np.zeros(points.shape[1], int)


def test_points_are_uniform_over_the_area():
    """The fan triangle is picked in proportion to its area; inside it the point is uniform (the
    barycentric halves of each fan triangle get half its share).  Control: equal shares fail."""
    light = Polygons([PENTAGON])
    rng = np.random.default_rng(11)
    point, normal = light.sample_area(np.zeros(N, int), rng.random(N), rng.random(N))
    assert np.abs(point[2] - PENTAGON[0, 2]).max() < 1e-12 and np.allclose(normal[:, 0], [0, 0, 1])
    fan = fan_triangle_of(point, PENTAGON)
    areas = fan_areas(PENTAGON)
    # Split each fan triangle at the midpoint of its far edge: two halves of equal area.
    a, b, c = PENTAGON[0], PENTAGON[fan + 1], PENTAGON[fan + 2]
    mid = 0.5 * (b + c)
    side = np.einsum("ij,ij->i", np.cross(mid - a, point.T - a), np.cross(b - a, c - a)) > 0
    cells = 2 * fan + side
    counts = np.bincount(cells, minlength=2 * len(areas))
    expected = N * np.repeat(areas / areas.sum() / 2, 2)
    assert pooled_chi2(counts, expected)[0] > ALPHA
    assert pooled_chi2(counts, N * np.full(len(counts), 1 / len(counts)))[0] < 1e-6          # control


def test_pdf_is_the_area_density_seen_from_the_receiver():
    light = Polygons([PENTAGON, disk((0.0, 0.0, 0.0), 1.0, normal_sign=-1.0)])
    rng = np.random.default_rng(12)
    m = 1000
    x = rng.uniform(-2, 2, (3, m)) + np.array([[0.0], [0.0], [0.2]])
    idx = rng.integers(0, 2, m)
    s = light.sample_li(x, idx, rng.random(m), rng.random(m))
    w = s.point - x
    d = np.linalg.norm(w, axis=0)
    cos = np.abs(w[2]) / d                                     # both lights lie in planes z = const
    assert np.allclose(s.pdf, d * d / (light.area[idx] * cos), rtol=1e-12)
    assert np.array_equal(light.pdf_li(x, idx, s.point), s.pdf)
    # By area whatever the estimator: solid_angle changes nothing.
    u = rng.random((2, m))
    by_area, by_solid_angle = (light.sample_li(x, idx, u[0], u[1], solid_angle=flag) for flag in (False, True))
    assert np.array_equal(by_area.point, by_solid_angle.point) and np.array_equal(by_area.pdf, by_solid_angle.pdf)
    with pytest.raises(NotImplementedError):
        light.solid_angle(x, idx)


def test_the_light_set_makes_polygons_of_round_lamps_and_quads_that_are_not_parallelograms():
    mats = [Material("L", emission=(1.0, 1.0, 1.0), color=(0, 0, 0))]
    kite = np.array([[0, 0, 2], [1, -0.5, 2], [2, 0, 2], [1, 1.5, 2]], float)
    rect = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    scene = Scene(None, mats, quads=[Quad("Kite", kite, 0), Quad("Rect", rect, 0)],
                  lights=[AreaLight("Disk", disk((0.0, 0.0, 3.0), 0.5), (2.0, 2.0, 2.0)),
                          AreaLight("Square", rect + [0, 0, 2], (2.0, 2.0, 2.0))])
    lights = LightSet(scene)
    assert lights.kind_names() == ["parallelogram", "polygon"]
    polygons = lights.kinds[1]
    assert polygons.count == 2 and polygons.one_sided.tolist() == [False, True]     # the Area light: front only
    assert lights.quad_light.tolist() == [polygons.first, 0] and lights.area_light_light.tolist() == [polygons.first + 1, 1]
