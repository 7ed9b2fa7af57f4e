"""Smooth shading: interpolated corner normals against closed forms, every
accelerator, the effect plan, scene files, bad input, and the shading-normal artefacts (light
below the geometric horizon, the shadow terminator) handled as Cycles does."""
import numpy as np
import pytest

import engine.geometry.shading_normals
from engine import RenderSettings, render
from engine.geometry.scene_geometry import Counters, SceneGeometry
from engine.scene.model import DIFFUSE, MIRROR, Camera, Material, Quad, Scene, TriangleMesh
from engine.scene.files import load_scene, save_scene
from engine.geometry.shading_normals import (ensure_valid_reflection, interpolate, smooth_surface_offset,
    terminator_amount)
from engine.core.vec import dot, rows

SILENT = dict(log=lambda *a: None)


def uv_sphere(center, radius, n_u, n_v, material=0, smooth=True, name="Ball"):
    """A UV sphere mesh (outward winding); smooth: corner normals = the true sphere normals."""
    theta = np.linspace(0, np.pi, n_v + 1)
    phi = np.linspace(0, 2 * np.pi, n_u, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_v), np.arange(n_u), indexing="ij")
    a, b = i * n_u + j, i * n_u + (j + 1) % n_u
    c, d = (i + 1) * n_u + (j + 1) % n_u, (i + 1) * n_u + j
    f = np.concatenate([np.stack([a.ravel(), d.ravel(), c.ravel()], 1), np.stack([a.ravel(), c.ravel(), b.ravel()], 1)])
    mesh = TriangleMesh(name, unit * radius + np.asarray(center, float), f, np.full(len(f), material))
    if smooth:
        mesh.normals = unit[f]
    return mesh


def shading_at_hits(mesh, accelerator, origins, directions):
    scene = Scene(Camera.look_at((0, -5, 0), (0, 0, 0)), [Material("M")], meshes=[mesh])
    scene.validate()
    geo = SceneGeometry(scene, accelerator)
    hits = geo.nearest_hits(rows(origins), rows(directions), Counters())
    o, d = rows(origins).take(hits.index, axis=1), rows(directions).take(hits.index, axis=1)
    surf = geo.surface(o, d, hits)
    return hits, surf


def random_rays_at_sphere(n, seed=1):
    rng = np.random.default_rng(seed)
    target = rng.normal(size=(n, 3))
    target *= (0.8 * rng.random(n) ** 0.5 / np.linalg.norm(target, axis=1))[:, None]   # inside the ball
    origin = rng.normal(size=(n, 3))
    origin *= (3.0 / np.linalg.norm(origin, axis=1))[:, None]
    d = target - origin
    return origin, d / np.linalg.norm(d, axis=1)[:, None]


# -- interpolation: closed forms ----------------------------------------------------------------
def test_interpolated_normal_is_the_sphere_normal():
    """On a smooth 64 x 32 UV sphere the Phong normal at a hit is within 0.5 degrees of the true
    sphere normal (point - centre) / r; the flat (geometric) normal is off by up to ~4 degrees, so
    the bound fails without interpolation (negative control)."""
    origins, dirs = random_rays_at_sphere(4000)
    hits, surf = shading_at_hits(uv_sphere((0, 0, 0), 1.0, 64, 32), "embree", origins, dirs)
    assert len(hits.index) > 3500
    true = surf.point / np.linalg.norm(surf.point, axis=0)
    angle = np.degrees(np.arccos(np.clip(dot(surf.shading, true), -1, 1)))
    flat = np.degrees(np.arccos(np.clip(dot(surf.normal, true), -1, 1)))
    assert angle.max() < 0.5, angle.max()
    assert flat.max() > 2.0                       # the control: geometric normals are visibly faceted
    assert np.allclose(np.linalg.norm(surf.shading, axis=0), 1.0, atol=1e-12)


def test_hit_at_a_vertex_returns_its_normal():
    corners = np.array([[[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]]], float)
    for u, v, k in ((0.0, 0.0, 0), (1.0, 0.0, 1), (0.0, 1.0, 2)):
        n = interpolate(corners, np.array([u]), np.array([v]))[:, 0]
        assert np.array_equal(n, corners[0, k]), (k, n)
    mid = interpolate(corners, np.array([0.5]), np.array([0.0]))[:, 0]
    assert np.allclose(mid, (corners[0, 0] + corners[0, 1]) / np.linalg.norm(corners[0, 0] + corners[0, 1]))
    # corners that cancel (opposite normals) at the hit: the geometric normal, never 0 or NaN
    opposite = np.array([[[0, 0, 1], [0, 0, -1], [0, 0, 1]]], float)
    geometric = np.array([[0.0], [0.6], [0.8]])
    n = interpolate(opposite, np.array([0.5]), np.array([0.0]), geometric)
    assert np.array_equal(n, geometric)


@pytest.mark.parametrize("accelerator", ["octree", "brute"])
def test_every_accelerator_interpolates_the_same(accelerator):
    """The octree and brute force return Embree's barycentrics: the same shading normals (to the
    float32 precision of Embree's u, v)."""
    origins, dirs = random_rays_at_sphere(300, seed=2)
    mesh = uv_sphere((0, 0, 0), 1.0, 12, 6)
    h1, s1 = shading_at_hits(mesh, "embree", origins, dirs)
    h2, s2 = shading_at_hits(uv_sphere((0, 0, 0), 1.0, 12, 6), accelerator, origins, dirs)
    assert np.array_equal(h1.index, h2.index) and np.array_equal(h1.prim, h2.prim)
    assert np.abs(s1.shading - s2.shading).max() < 1e-5
    assert np.abs(s1.shading - s1.normal).max() > 0.1          # they really are interpolated


def test_flat_triangles_of_a_smooth_mesh_keep_the_geometric_normal():
    mesh = uv_sphere((0, 0, 0), 1.0, 12, 6)
    mesh.smooth = np.arange(len(mesh.triangles)) % 2 == 0        # every other triangle flat
    origins, dirs = random_rays_at_sphere(500, seed=3)
    hits, surf = shading_at_hits(mesh, "embree", origins, dirs)
    flat = hits.prim % 2 == 1
    assert flat.any() and (~flat).any()
    assert np.array_equal(surf.shading[:, flat], surf.normal[:, flat])
    assert np.abs(surf.shading[:, ~flat] - surf.normal[:, ~flat]).max() > 0.05


# -- effect plan: flat scenes pay nothing ---------------------------------------------------------
def box_room(smooth_ball: bool, ball_material=0):
    mats = [Material("White", DIFFUSE, (0.7, 0.7, 0.7)), Material("Lamp", DIFFUSE, (0, 0, 0), emission=(8, 8, 8)),
            Material("Mirror", MIRROR, (0.9, 0.9, 0.9))]
    lamp = Quad("Lamp", np.array([(-0.3, -0.3, 1.99), (-0.3, 0.3, 1.99), (0.3, 0.3, 1.99), (0.3, -0.3, 1.99)]), 1)
    floor = Quad("Floor", np.array([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], float), 0)
    ball = uv_sphere((0, 0, 0.5), 0.5, 12, 6, ball_material, smooth=smooth_ball)
    cam = Camera.look_at((0, -3, 1.2), (0, 0, 0.5), lens=40)
    return Scene(cam, mats, meshes=[ball], quads=[floor, lamp], resolution=(16, 16))


def test_flat_scene_never_interpolates(monkeypatch):
    calls = []
    for name in ("interpolate", "interpolate_rows", "ensure_valid_reflection"):
        original = getattr(engine.geometry.shading_normals, name)
        monkeypatch.setattr(engine.geometry.shading_normals, name, lambda *a, _o=original, _n=name: calls.append(_n) or _o(*a))
    monkeypatch.setattr("engine.materials.specular.ensure_valid_reflection",
                        lambda *a: calls.append("reflect") or ensure_valid_reflection(*a))
    shading = engine.geometry.shading_normals.SmoothNormals.shading      # both backends (the numba one: one loop)
    monkeypatch.setattr(engine.geometry.shading_normals.SmoothNormals, "shading",
                        lambda self, *a: calls.append("shading") or shading(self, *a))
    flat = render(box_room(False, 2), RenderSettings(samples=2, parallelism="threads"), **SILENT)
    assert flat.stats["effects"]["smooth_normals"] is False and calls == []
    assert "no smooth-shaded faces" in flat.stats["effects_reason"]["smooth_normals"]
    smooth = render(box_room(True, 2), RenderSettings(samples=2, parallelism="threads"), **SILENT)
    assert smooth.stats["effects"]["smooth_normals"] is True
    assert "132 smooth-shaded triangles in 'Ball'" in smooth.stats["effects_reason"]["smooth_normals"]
    assert "shading" in calls and "reflect" in calls


# -- scene files and bad input --------------------------------------------------------------------
def test_scene_file_round_trip_keeps_normals(tmp_path):
    scene = box_room(True)
    scene.meshes[0].smooth = np.arange(len(scene.meshes[0].triangles)) % 3 != 0
    scene.meshes[0].terminator_offset = 0.25
    save_scene(scene, str(tmp_path / "s.json"))
    back = load_scene(str(tmp_path / "s.json"))
    back.validate()
    scene.validate()
    assert np.array_equal(back.meshes[0].normals, scene.meshes[0].normals)
    assert np.array_equal(back.meshes[0].smooth, scene.meshes[0].smooth)
    assert back.meshes[0].terminator_offset == 0.25
    import json
    assert json.loads((tmp_path / "s.json").read_text())["version"] == 5
    flat = box_room(False)
    save_scene(flat, str(tmp_path / "f.json"))
    assert json.loads((tmp_path / "f.json").read_text())["version"] == 4      # older readers still read it
    assert load_scene(str(tmp_path / "f.json")).meshes[0].normals is None


def test_bad_normals_fall_back_to_the_geometric_normal_with_a_warning():
    scene = box_room(True)
    n = scene.meshes[0].normals
    n[0, 0] = 0.0
    n[1, 1] = np.nan
    n[2, 2] = np.inf
    n[3] = 0.0                                      # a whole triangle
    warnings = scene.validate()
    assert any("Object 'Ball'" in w and "6 of 396 shading normals" in w for w in warnings), warnings
    mesh = scene.meshes[0]
    assert np.isfinite(mesh.normals).all()
    v = mesh.vertices[mesh.triangles[3]]
    g = np.cross(v[1] - v[0], v[2] - v[0])
    assert np.allclose(mesh.normals[3], g / np.linalg.norm(g))
    result = render(scene, RenderSettings(samples=4, parallelism="threads"), **SILENT)
    assert result.stats["nonfinite_samples"] == 0 and np.isfinite(result.image).all()


@pytest.mark.parametrize("normals, message", [
    (np.zeros((5, 3)), "5 normals for 144 triangles"),
    ("abc", "normals must be numbers"),
])
def test_wrongly_shaped_normals_are_one_clear_error(normals, message):
    from engine.core.errors import SceneError
    scene = box_room(True)
    scene.meshes[0].normals = normals
    with pytest.raises(SceneError, match=message):
        scene.validate()


# -- artefacts: light below the geometric horizon -----------------------------------------------------
def tilted_floor(theta_deg, background=1.0, lamp_below=False, albedo=0.8, terminator_offset=0.1):
    """A large floor (two triangles, z = 0) whose corner normals are all tilted by theta towards +x,
    seen from above; a white world or, with lamp_below, a lamp under the floor only.

    The shadow-terminator lift assumes normals that vary like a curved surface's: with the same
    tilted normal at every corner of a 400 m triangle Cycles' envelope lifts shadow-ray origins by
    ~170 m (in Cycles too), so the closed-form test turns it off."""
    t = np.radians(theta_deg)
    big = 200.0
    v = np.array([(-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0)], float)
    floor = TriangleMesh("Floor", v, np.array([[0, 1, 2], [0, 2, 3]]), [0, 0])
    floor.normals = np.broadcast_to([np.sin(t), 0.0, np.cos(t)], (2, 3, 3)).copy()
    floor.terminator_offset = terminator_offset
    mats = [Material("Floor", DIFFUSE, (albedo,) * 3), Material("Lamp", DIFFUSE, (0, 0, 0), emission=(50, 50, 50))]
    quads = []
    if lamp_below:   # seen by the tilted shading normal, below the geometric surface
        quads = [Quad("Lamp", np.array([(3, -1, -0.5), (3, 1, -0.5), (3, 1, -2.5), (3, -1, -2.5)], float), 1)]
    cam = Camera.look_at((0, 0, 2), (0, 0, 0), up=(0, 1, 0), lens=50)
    return Scene(cam, mats, meshes=[floor], quads=quads, background=(background,) * 3 if not lamp_below else (0,) * 3,
                 resolution=(16, 16))


@pytest.mark.parametrize("estimator", ["mis", "solid-angle"])
def test_grazing_shading_normals_lose_the_light_below_the_surface(estimator):
    """Closed form (a white-furnace variant): a diffuse floor of albedo rho under a white world with
    shading normals tilted by theta.  The cosine lobe about the shading normal reaches the world only
    above the geometric surface, a fraction (1 + cos theta) / 2 of it, so L = rho (1 + cos theta) / 2
    (Cycles: directions below the geometric surface are rejected).  Without interpolation L = rho;
    an estimator that let those directions through (re-hitting the floor) would be brighter."""
    rho, theta = 0.8, 60.0
    result = render(tilted_floor(theta, albedo=rho, terminator_offset=0.0), RenderSettings(samples=64, estimator=estimator, seed=5,
                                                                     parallelism="threads"), **SILENT)
    img = result.image[..., 1]
    mean = img.mean()
    se = np.sqrt(result.variance[..., 1].sum()) / img.size
    expected = rho * (1 + np.cos(np.radians(theta))) / 2
    assert abs(mean - expected) < 4 * se + 1e-3, (mean, expected, se)
    assert abs(rho - expected) > 20 * se                  # the flat answer is far outside the bound


def test_no_light_leaks_from_below_the_geometric_surface():
    """A lamp under the floor that the tilted shading normals face: the floor's top side stays black,
    both for light samples (lifted shadow rays still meet the floor) and for bounce rays (rejected).
    Control: the same lamp mirrored above the floor lights it."""
    dark = render(tilted_floor(80.0, lamp_below=True), RenderSettings(samples=16, parallelism="threads"), **SILENT)
    assert dark.image.max() == 0.0
    lit_scene = tilted_floor(80.0, lamp_below=True)
    lit_scene.quads[0].corners = lit_scene.quads[0].corners * np.array([1, 1, -1])[None]   # above; winding flips
    lit_scene.quads[0].corners = lit_scene.quads[0].corners[::-1].copy()
    lit = render(lit_scene, RenderSettings(samples=16, parallelism="threads"), **SILENT)
    assert lit.image.mean() > 0.01


def test_mirror_direction_clears_the_geometric_surface():
    """ensure_valid_reflection: with a shading normal tilted 50 degrees and a grazing view, the plain
    mirror direction goes below the surface; the bent normal's reflection lies just above it
    (at min(0.9 i.ng, 0.01)), and a normal whose reflection is fine is returned unchanged."""
    ng = rows([[0, 0, 1]] * 3)
    n = rows([[np.sin(np.radians(50)), 0, np.cos(np.radians(50))], [0, 0, 1], [0.1, 0, np.sqrt(0.99)]])
    i = rows([[-0.95, 0, np.sqrt(1 - 0.95 ** 2)], [-0.6, 0, 0.8], [-0.6, 0, 0.8]])     # towards the viewer
    plain = 2 * dot(n, i) * n - i
    assert plain[2, 0] < 0                                               # below the surface
    bent = ensure_valid_reflection(ng, i, n)
    r = 2 * dot(bent, i) * bent - i
    assert np.allclose(np.linalg.norm(bent, axis=0), 1.0)
    assert r[2, 0] == pytest.approx(min(0.9 * i[2, 0], 0.01), abs=1e-6)
    assert np.array_equal(bent[:, 1:], n[:, 1:])


# -- the shadow terminator ----------------------------------------------------------------------------
def test_terminator_lift_moves_origins_onto_the_smooth_surface():
    """Cycles' geometry offset on a coarse sphere (12 x 6): the lifted triangle centroids lie within
    3 % of the true sphere (the flat centroids are 3-6 % inside it), never below the triangle."""
    mesh = uv_sphere((0, 0, 0), 1.0, 12, 6)
    mesh.validate(1)                                                    # drops the pole's degenerate triangles
    V = mesh.vertices[mesh.triangles]
    ng = np.cross(V[:, 1] - V[:, 0], V[:, 2] - V[:, 0])
    ng /= np.linalg.norm(ng, axis=1)[:, None]
    third = np.full(len(V), 1 / 3)
    lift = smooth_surface_offset(V, mesh.normals, third, third, ng.T)
    centroid = V.mean(axis=1).T
    flat_r, lifted_r = np.linalg.norm(centroid, axis=0), np.linalg.norm(centroid + lift, axis=0)
    assert (1 - flat_r).min() > 0.03                                    # control: the flat surface is inside
    assert np.abs(lifted_r - 1).max() < 0.03 and np.abs(lifted_r - 1).mean() < 0.5 * (1 - flat_r).mean()
    assert (dot(lift, ng.T) >= 0).all()
    # the amount: full for light at or below the geometric horizon, none once N_g.L > cutoff
    amount = terminator_amount(np.array([0.05, 0.3, 0.3, 0.3]), np.array([-0.1, 0.0, 0.05, 0.2]),
                               np.array([0.1, 0.1, 0.1, 0.1]))
    assert np.allclose(amount, [1.0, 1.0, 0.5, 0.0])
    assert terminator_amount(np.array([0.05]), np.array([-0.1]), np.array([0.0]))[0] == 0.0


def test_terminator_offset_brightens_the_coarse_sphere_terminator():
    """A 12 x 6 smooth sphere lit from the side by a lamp: shadow rays from the lit side near the
    terminator are blocked by the neighbouring facets unless lifted, so the sphere is brighter with
    the offset (Cycles' default 0.1) than without it (0), by more than the noise."""
    def scene(offset):
        mats = [Material("Ball", DIFFUSE, (0.8, 0.8, 0.8)), Material("Lamp", DIFFUSE, (0, 0, 0), emission=(20,) * 3)]
        ball = uv_sphere((0, 0, 0), 1.0, 12, 6, 0)
        ball.terminator_offset = offset
        lamp = Quad("Lamp", np.array([(4, -0.3, -0.3), (4, -0.3, 0.3), (4, 0.3, 0.3), (4, 0.3, -0.3)], float), 1)
        return Scene(Camera.look_at((0, -4, 0), (0, 0, 0), lens=60), mats, meshes=[ball], quads=[lamp],
                     resolution=(24, 24))
    settings = RenderSettings(samples=128, max_depth=0, seed=9, parallelism="threads")
    lifted, plain = render(scene(0.1), settings, **SILENT), render(scene(0.0), settings, **SILENT)
    diff = lifted.image[..., 1].sum() - plain.image[..., 1].sum()
    se = np.sqrt(lifted.variance[..., 1].sum() + plain.variance[..., 1].sum())
    assert diff > 5 * se, (diff, se)


def test_worker_processes_get_the_normals():
    """The scene goes to `python -m engine worker` processes pickled: their image of a smooth mirror
    ball is render()'s (normals, smooth flags and terminator offsets arrive), not the flat one's."""
    from engine.pools.spec import make_pool
    settings = RenderSettings(samples=4, tile_size=8, seed=3)
    ref = render(box_room(True, 2), settings, **SILENT)
    remote = render(box_room(True, 2), settings, pool=make_pool("workers", 2, **SILENT), **SILENT)
    flat = render(box_room(False, 2), settings, **SILENT)
    assert np.array_equal(remote.image, ref.image)
    assert not np.array_equal(remote.image, flat.image)


@pytest.mark.parametrize("field, value, message", [
    ("normals", [[0, 0, 1]] * 4, "Object 'Tri': 4 normals for 1 triangles"),
    ("normals", [[0, 0, "up"]] * 3, "Object 'Tri': normals"),
    ("smooth", [2], "Object 'Tri': smooth"),
])
def test_bad_normals_in_a_scene_file_are_one_line_naming_the_object(tmp_path, field, value, message):
    import json
    from engine.core.errors import SceneError
    mesh = {"name": "Tri", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
            "normals": [[0, 0, 1]] * 3}
    mesh[field] = value
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"format": "tncg15-scene", "version": 4, "materials": [{"name": "m"}],
                                "camera": {"look_at": {"position": [0, 0, 2], "target": [0, 0, 0], "up": [0, 1, 0]}},
                                "meshes": [mesh]}))
    with pytest.raises(SceneError, match=message):
        load_scene(str(path)).validate()


def test_normal_pass_is_the_shading_normal():
    """Cycles' Denoising Normal is the closure's (shading) normal: on the floor with shading normals
    tilted 30 degrees it is that normal in camera space, not the geometric (0, 0, 1)."""
    scene = tilted_floor(30.0)
    r = render(scene, RenderSettings(samples=2, passes=("normal",), threads=1), **SILENT)
    axes = np.asarray(scene.camera.matrix)[:3, :3] * np.array([1.0, 1.0, -1.0])
    t = np.radians(30.0)
    assert np.allclose(r.passes["normal"], axes.T @ np.array([np.sin(t), 0.0, np.cos(t)]), atol=1e-6)
    assert not np.allclose(axes.T @ np.array([0.0, 0.0, 1.0]), axes.T @ np.array([np.sin(t), 0.0, np.cos(t)]),
                           atol=0.1)                                     # control: the flat answer differs


def test_terminator_lift_has_the_numbers_of_the_two_bounds_made_apart():
    """smooth_surface_offset makes the dot products of both tangent-plane bounds once (sign * d is
    exact): the lift is bit for bit the form with the bounds made apart on the corner views."""
    from engine.geometry.shading_normals import tangent_plane_bound
    rng = np.random.default_rng(6)
    m = 300
    V = rng.normal(size=(m, 3, 3))
    N = rng.normal(size=(m, 3, 3))
    N /= np.linalg.norm(N, axis=2)[:, :, None]
    u, v = rng.random(m) * 0.5, rng.random(m) * 0.5
    ng = rng.normal(size=(3, m))
    w0, w1, w2 = 1.0 - u - v, u, v
    v0, v1, v2 = V[:, 0].T, V[:, 1].T, V[:, 2].T
    n0, n1, n2 = N[:, 0].T, N[:, 1].T, N[:, 2].T
    p = v0 * w0 + v1 * w1 + v2 * w2
    n = n0 * w0 + n1 * w1 + n2 * w2
    a, b, c = dot(n2 - n0, v0 - v2), dot(n2 - n1, v1 - v2), dot(n1 - n0, v1 - v0)
    h = a * w0 * (w0 - 1.0) + (a + b + c) * w0 * w1 + b * w1 * (w1 - 1.0)
    front = np.maximum(tangent_plane_bound(p, (v0, v1, v2), (n0, n1, n2), 1.0), h * 0.5)
    back = np.minimum(-tangent_plane_bound(p, (v0, v1, v2), (n0, n1, n2), -1.0), h * 0.5)
    expected = n * np.where(dot(n, ng) > 0.0, front, back)
    lift = smooth_surface_offset(V, N, u, v, ng)
    assert np.array_equal(lift, expected)
    assert not np.array_equal(smooth_surface_offset(V, N, u, np.nextafter(v, 1.0), ng), expected)   # control


def test_phong_normals_from_corner_rows_are_the_same_numbers():
    from engine.geometry.shading_normals import interpolate_rows
    rng = np.random.default_rng(7)
    corners = rng.normal(size=(500, 3, 3))
    corners[:5, 1] = -corners[:5, 0]                                    # some cancel: the fallback
    corners[:5, 2] = 0.0
    u, v = rng.random(500) * 0.5, rng.random(500) * 0.5
    u[:5], v[:5] = 0.5, 0.0
    fallback = rng.normal(size=(3, 500))
    rows_ = np.ascontiguousarray(corners.reshape(-1, 9).T)
    for fb in (None, fallback):
        assert np.array_equal(interpolate_rows(rows_, u, v, fb), interpolate(corners, u, v, fb))
    assert not np.array_equal(interpolate_rows(rows_, v, u, fallback), interpolate(corners, u, v, fallback))  # control
