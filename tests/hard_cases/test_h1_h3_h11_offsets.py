"""Secondary rays never re-hit their own surface and never skip a thin gap (docs/hard-cases.md H1-H3, H11)."""
import numpy as np
import pytest

from engine.geometry.scene_geometry import NONE, Counters, SceneGeometry
from engine.sampling.warps import cosine_hemisphere, to_world
from engine.scene.model import Camera, Material, Scene, Sphere, TriangleMesh
from engine.core.vec import rows


def plane_mesh(center, normal, size, name="Plane"):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    helper = np.array([1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    c = np.asarray(center, float)
    verts = np.array([c - size * u - size * v, c + size * u - size * v, c + size * u + size * v,
                      c - size * u + size * v])
    return TriangleMesh(name, verts, np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]))


def scene_of(meshes=(), spheres=()):
    return Scene(Camera.look_at((0, 0, 10), (0, 0, 0), up=(0, 1, 0)), [Material("m")], list(meshes), list(spheres))


def intersect(geo, o, d, counters=None):
    """geo.intersect for (N, 3) rays (the tracer takes rows)."""
    return geo.intersect(rows(o), rows(d), counters or Counters())


def surface_of_hits(geo, origins, directions, counters=None):
    """(hits, surface with point and normal as (N, 3)) for (N, 3) rays, in hit order."""
    hits = geo.nearest_hits(rows(origins), rows(directions), counters or Counters())
    s = geo.surface(rows(origins[hits.index]), rows(directions[hits.index]), hits)
    s.point, s.normal = s.point.T, s.normal.T
    return hits, s


def spawn_from_hits(geo, origins, directions, rng):
    hits, s = surface_of_hits(geo, origins, directions)
    assert len(hits.miss) == 0
    origins, directions = origins[hits.index], directions[hits.index]
    facing = np.where((np.einsum("ij,ij->i", directions, s.normal) < 0)[:, None], s.normal, -s.normal)
    n = len(origins)
    new_d = to_world(cosine_hemisphere(rng.random(n), rng.random(n)), rows(facing)).T
    return s.point + s.offset[:, None] * facing, new_d, facing, s


@pytest.mark.parametrize("distance", [1.0, 1e2, 1e4, 1e5, 1e6])
@pytest.mark.parametrize("normal", [(0, 0, 1), (1, 2, 3)])
def test_no_self_hits_on_planes_far_from_origin(distance, normal):
    rng = np.random.default_rng(int(distance) % 1000)
    n_hat = np.asarray(normal, float) / np.linalg.norm(normal)
    center = distance * np.array([0.6, -0.48, 0.64])
    geo = SceneGeometry(scene_of([plane_mesh(center, normal, 0.1 * max(distance, 10))]))
    m = 20000
    jitter = rng.uniform(-0.05, 0.05, (m, 3)) * max(distance, 10)
    jitter -= np.einsum("ij,j->i", jitter, n_hat)[:, None] * n_hat
    targets = center + jitter
    origins = targets + n_hat * max(distance, 10)
    o, d, _, _ = spawn_from_hits(geo, origins, np.tile(-n_hat, (m, 1)), rng)
    t, kind, *_ = intersect(geo, o, d)
    assert (kind == NONE).sum() == m, f"{m - (kind == NONE).sum()} self-hits at {distance}"


@pytest.mark.parametrize("height, gap", [(1.0, 1e-5), (1000.0, 1e-2), (1e5, 1.0)])
def test_thin_gap_is_not_skipped(height, gap):
    """Rays leaving the lower plane upward must hit a plane `gap` above (6e-6 x scale)."""
    rng = np.random.default_rng(3)
    lower = plane_mesh((0, 0, height), (0, 0, 1), 1.0, "Lower")
    upper = plane_mesh((0, 0, height + gap), (0, 0, 1), 1e3, "Upper")
    geo = SceneGeometry(scene_of([lower, upper]))
    m = 5000
    xy = rng.uniform(-0.5, 0.5, (m, 2))
    origins = np.concatenate([xy, np.full((m, 1), height - 1.0)], axis=1)
    counters = Counters()
    d = np.tile([0, 0, 1.0], (m, 1))
    # Only the lower plane is hit first: it is closer; spawn above it.
    o, new_d, facing, _ = spawn_from_hits(geo, origins, d, rng)
    assert (facing[:, 2] < 0).all()  # seen from below
    # Go through: origin on the far side of the lower plane, heading up.
    _, hits = surface_of_hits(geo, origins, d, counters)
    o = hits.point + hits.offset[:, None] * np.array([0, 0, 1.0])
    t, kind, prim, u, v = intersect(geo, o, d, counters)
    assert (kind != NONE).all()
    assert np.allclose(o[:, 2] + t, height + gap, atol=gap * 0.5)


@pytest.mark.parametrize("radius, center", [(1e-3, (0, 0, 1e4)), (1.0, (0, 0, 0)), (1e4, (0, 0, 0)),
                                            (1.0, (1e5, 1e5, 1e5))])
def test_sphere_reintersection_and_inner_chord(radius, center):
    rng = np.random.default_rng(6)
    c = np.asarray(center, float)
    geo = SceneGeometry(scene_of(spheres=[Sphere("S", tuple(c), radius, 0)]))
    m = 5000
    dirs = rng.normal(size=(m, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    origins = c + dirs * radius * 3
    o, d, facing, s = spawn_from_hits(geo, origins, -dirs, rng)
    t, kind, *_ = intersect(geo, o, d)
    assert (kind == NONE).all(), "outward rays re-hit their own sphere"
    # Inward: the far side at chord 2 r cos(theta).
    inward = -d
    o_in = s.point - s.offset[:, None] * facing
    t, kind, *_ = intersect(geo, o_in, inward)
    cos_theta = np.einsum("ij,ij->i", inward, -s.normal)
    assert (kind != NONE).all()
    # Starting `offset` inside the surface shortens the chord by about offset / cos(theta).
    bound = 2 * s.offset / cos_theta + 1e-9 * radius
    assert (np.abs(t - 2 * radius * cos_theta) <= bound).all()
    assert (s.offset < 1e-6 * radius).all()
