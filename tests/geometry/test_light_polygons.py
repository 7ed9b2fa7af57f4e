"""engine/geometry/shapes/light_polygons.py: rays against Area-light polygons, checked against a brute
reference (every ray against the polygon's fan of triangles, Möller-Trumbore in float64), and the
ray-kind visibility and hit surface the integrator uses."""
import numpy as np
import pytest

from engine.geometry.shapes.light_polygons import RAY_KINDS, LightPolygons
from engine.scene.model import AreaLight

EDGE_MARGIN = 1e-7        # rays this close (barycentric) to a polygon edge may go either way


def convex_polygon(rng, corners):
    """A convex polygon: points at sorted angles on a random ellipse, rotated and moved at random."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, corners))
    while np.diff(np.r_[angles, angles[0] + 2 * np.pi]).max() >= np.pi:     # keep the centre inside
        angles = np.sort(rng.uniform(0, 2 * np.pi, corners))
    flat = np.stack([rng.uniform(0.3, 2) * np.cos(angles), rng.uniform(0.3, 2) * np.sin(angles),
                     np.zeros(corners)], axis=1)
    rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return flat @ rotation.T + rng.uniform(-3, 3, 3)


def brute_hits(corners, o, d):
    """(t, margin): nearest t > 0 against the fan triangles (+inf on a miss, either face) and, per
    ray, how near its crossing of the plane is to a line of the polygon's outline (barycentric)."""
    best, margin = np.full(o.shape[1], np.inf), np.full(o.shape[1], np.inf)
    last = len(corners) - 2
    for i in range(1, len(corners) - 1):
        a, b, c = corners[0], corners[i], corners[i + 1]
        e1, e2 = b - a, c - a
        p = np.cross(d.T, e2)
        det = p @ e1
        s = o.T - a
        u = np.einsum("ij,ij->i", s, p) / det
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", d.T, q) / det
        t = q @ e2 / det
        # the point is (1-u-v) a + u b + v c; the fan's inner edges (a-b, a-c) are inside the polygon
        outline = [1 - u - v] + ([v] if i == 1 else []) + ([u] if i == last else [])
        near = np.min(np.abs(outline), axis=0)
        margin = np.where(t > 0, np.minimum(margin, near), margin)
        inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < best)
        best = np.where(inside, t, best)
    return best, margin


def rays_at(rng, corners, count):
    """Origins on both sides of the polygon, aimed at points in and around it, some away from it."""
    centre = corners.mean(axis=0)
    size = np.abs(corners - centre).max()
    o = centre[:, None] + rng.uniform(-3 * size, 3 * size, (3, count))
    inside = rng.dirichlet(np.ones(len(corners)), count) @ corners          # points of the polygon
    aim = (centre + rng.uniform(0, 3, (count, 1)) * (inside - centre)).T      # ... and around it
    d = aim - o
    d[:, : count // 8] *= -1.0                               # pointing away: no hit behind the origin
    return o, d / np.linalg.norm(d, axis=0)


@pytest.mark.parametrize("corners", [3, 4, 5, 8])
def test_hits_agree_with_the_brute_reference(corners):
    rng = np.random.default_rng(corners)
    polygons = [convex_polygon(rng, corners) for _ in range(3)]
    lights = LightPolygons([AreaLight(f"Lamp{i}", v, (1, 1, 1)) for i, v in enumerate(polygons)])
    hits = 0
    for k, v in enumerate(polygons):
        o, d = rays_at(rng, v, 400)
        t = lights.intersect_one(k, o, d, np.full(400, np.inf))
        ref, margin = brute_hits(v, o, d)
        clear = margin > EDGE_MARGIN
        assert clear.mean() > 0.95
        assert np.array_equal(np.isinf(t[clear]), np.isinf(ref[clear])), k
        hit = clear & np.isfinite(ref)
        np.testing.assert_allclose(t[hit], ref[hit], rtol=1e-10, atol=1e-12)
        hits += hit.sum()
        assert 0.2 < hit.mean() < 0.8                  # both outcomes are tested
    assert hits > 500


def test_nearer_hit_so_far_and_rays_parallel_to_the_plane_miss():
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    lights = LightPolygons([AreaLight("Lamp", square, (1, 1, 1))])
    o = np.array([[0, 0, 2], [0, 0, -2], [0.5, 0, 1], [0, 0, 2], [-3, 0, 0]], float).T
    d = np.array([[0, 0, -1], [0, 0, 1], [0, 0, -1], [0, 0, -1], [1, 0, 0]], float).T
    t = lights.intersect_one(0, o, d, np.array([np.inf, np.inf, np.inf, 1.5, np.inf]))
    assert t[:3].tolist() == [2.0, 2.0, 1.0]             # from above and from below (either face)
    assert np.isinf(t[3])                                 # a nearer surface was found first
    assert np.isinf(t[4])                                 # in the plane of the light


def test_rays_of_hidden_kinds_are_skipped():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    lights = LightPolygons([AreaLight("All", v, (1, 1, 1), visible_camera=True),
                            AreaLight("Default", v, (1, 1, 1)),
                            AreaLight("Mirror only", v, (1, 1, 1), visible_diffuse=False,
                                      visible_transmission=False)])
    kinds = np.array([RAY_KINDS.index(k) for k in ("camera", "diffuse", "glossy", "transmission", "glossy")])
    assert lights.rays_that_see(0, kinds) is None
    assert lights.rays_that_see(1, kinds).tolist() == [1, 2, 3, 4]
    assert lights.rays_that_see(2, kinds).tolist() == [2, 4]
    assert lights.rays_that_see(2, None) is None


def test_surface_is_on_the_plane_with_the_lights_normal():
    rng = np.random.default_rng(5)
    polygons = [convex_polygon(rng, 5) for _ in range(2)]
    lights = LightPolygons([AreaLight(f"Lamp{i}", v, (1, 2, 3), two_sided=i == 1) for i, v in enumerate(polygons)])
    assert lights.radiance.shape == (3, 2) and lights.two_sided.tolist() == [False, True]
    for k, v in enumerate(polygons):
        o, d = rays_at(rng, v, 200)
        t = lights.intersect_one(k, o, d, np.inf)
        hit = np.flatnonzero(np.isfinite(t))
        p, n, offset = lights.surface(o[:, hit], d[:, hit], t[hit], np.full(len(hit), k))
        normal = np.cross(v[1] - v[0], v[2] - v[0])
        normal /= np.linalg.norm(normal)
        np.testing.assert_allclose(n, np.repeat(normal[:, None], len(hit), axis=1), atol=1e-12)
        assert np.abs(normal @ (p - v[0][:, None])).max() < 1e-12 * (1 + np.abs(p).max())
        np.testing.assert_allclose(p, o[:, hit] + t[hit] * d[:, hit], atol=1e-9)
        assert (offset > 0).all() and (offset < 1e-10).all()


def test_control_a_slightly_smaller_polygon_disagrees_with_the_reference():
    """The comparison can fail: the polygon shrunk by 2 % about its centre misses rays the brute
    reference of the full one hits."""
    rng = np.random.default_rng(4)
    v = convex_polygon(rng, 4)
    smaller = v.mean(axis=0) + 0.98 * (v - v.mean(axis=0))
    o, d = rays_at(rng, v, 2000)
    ref, margin = brute_hits(v, o, d)
    t = LightPolygons([AreaLight("Smaller", smaller, (1, 1, 1))]).intersect_one(0, o, d, np.inf)
    clear = margin > EDGE_MARGIN
    assert not np.array_equal(np.isinf(t[clear]), np.isinf(ref[clear]))


def test_normals_built_for_all_lights_at_once_are_those_of_one_light_at_a_time():
    """LightPolygons builds its normals as arrays over every light (10,000 Area lights in 0.1 s);
    they are bit for bit the fan sum of np.cross and np.linalg.norm of each light alone."""
    rng = np.random.default_rng(11)
    corners = [convex_polygon(rng, int(rng.integers(3, 33))) * 10.0 ** rng.uniform(-3, 4) for _ in range(200)]
    lights = LightPolygons([AreaLight(f"l{i}", c, (1.0, 1.0, 1.0)) for i, c in enumerate(corners)])
    for k, c in enumerate(corners):
        n = np.zeros(3)
        for i in range(1, len(c) - 1):
            n += np.cross(c[i] - c[0], c[i + 1] - c[0])
        assert np.array_equal(lights.normal[k], n / max(np.linalg.norm(n), 1e-300))
        assert lights.scale[k] == np.abs(c).max() and np.array_equal(lights.origin[k], c[0])
