"""Fuzzer: random scenes and rays at scales from 1e-4 to 1e5 never give NaN, Inf,
negative radiance or an exception.  A failure names the seed that reproduces it:

    .venv/bin/python -c "from tests.hard_cases.test_fuzz import fuzz_one; fuzz_one(SEED)"
"""
import numpy as np
import pytest

from engine import RenderSettings, render
from engine.scene.builtin import torus
from engine.geometry.scene_geometry import Counters, SceneGeometry
from engine.scene.model import DIFFUSE, GLASS, MIRROR, Camera, Material, Quad, Scene, Sphere, TriangleMesh
from engine.core.errors import SceneError

SCENES_PER_RUN = 1000


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def random_scene(seed: int) -> Scene:
    rng = np.random.default_rng(seed)
    scale = 10.0 ** rng.uniform(-4, 5)
    offset = rng.normal(size=3) * scale * 10.0 ** rng.uniform(0, 2)
    rot = random_rotation(rng)

    def place(p):
        return (np.asarray(p, float) * scale) @ rot.T + offset

    kinds = [DIFFUSE, MIRROR, GLASS]
    mats = []
    for i in range(rng.integers(1, 5)):
        kind = kinds[rng.integers(0, 3)]
        emission = tuple(rng.uniform(0, 5, 3)) if rng.random() < 0.4 else (0.0, 0.0, 0.0)
        mats.append(Material(f"M{i}", kind, tuple(rng.uniform(0, 1, 3)), ior=float(rng.uniform(1.0, 2.5)),
                             emission=emission))
    if not any(m.is_emissive for m in mats):
        mats[0].emission = (1.0, 1.0, 1.0)
    n_mat = len(mats)
    spheres = [Sphere(f"S{i}", tuple(place(rng.uniform(-1, 1, 3))), float(scale * 10 ** rng.uniform(-2, 0)),
                      int(rng.integers(0, n_mat))) for i in range(rng.integers(0, 4))]
    quads = []
    for i in range(rng.integers(0, 4)):
        a, b = rng.uniform(0.01, 1, 2)
        c = np.array([(-a, -b, 0), (a, -b, 0), (a, b, 0), (-a, b, 0)])
        local = c @ random_rotation(rng).T + rng.uniform(-1, 1, 3)
        quads.append(Quad(f"Q{i}", place(local), int(rng.integers(0, n_mat))))
    meshes = []
    if rng.random() < 0.7:
        t = torus("Torus", rng.uniform(-1, 1, 3), 0.5, 0.2, int(rng.integers(3, 12)), int(rng.integers(3, 8)),
                  int(rng.integers(0, n_mat)))
        t.vertices = place(t.vertices)
        meshes.append(t)
    if rng.random() < 0.3:   # a mesh with degenerate and tiny triangles
        v = place(rng.uniform(-1, 1, (6, 3)))
        v[5] = v[4]
        meshes.append(TriangleMesh("Junk", v, np.array([[0, 1, 2], [3, 4, 5], [0, 0, 1]]),
                                   rng.integers(0, n_mat, 3)))
    cam_pos = place(rng.uniform(-3, 3, 3))
    target = place(rng.uniform(-0.5, 0.5, 3))
    if np.linalg.norm(cam_pos - target) < 1e-9 * scale:
        target = cam_pos + scale
    up = (0, 0, 1) if rng.random() < 0.5 else tuple(rng.normal(size=3))
    try:
        cam = Camera.look_at(cam_pos, target, up=up, lens=float(rng.uniform(10, 100)))
    except FloatingPointError:
        cam = Camera.look_at(cam_pos, target, up=(1, 0, 0))
    if not np.isfinite(cam.matrix).all():
        cam = Camera.look_at(cam_pos, target, up=(0.3, 0.5, 0.8))
    bg = tuple(rng.uniform(0, 1, 3)) if rng.random() < 0.5 else (0.0, 0.0, 0.0)
    return Scene(cam, mats, meshes, spheres, quads, background=bg, resolution=(4, 3), name=f"fuzz{seed}")


def fuzz_one(seed: int) -> None:
    scene = random_scene(seed)
    rng = np.random.default_rng(seed + 1)
    settings = RenderSettings(samples=2, threads=1, max_depth=int(rng.integers(0, 10)),
                              shadow_rays=int(rng.integers(0, 3)), fresnel=("schlick", "exact")[seed % 2],
                              seed=seed)
    try:
        with np.errstate(all="ignore"):
            result = render(scene, settings, log=lambda *a: None)
    except SceneError as exc:
        # Invalid random input (e.g. an emitter made only of degenerate triangles) must be
        # reported by name, never crash.
        assert "Object '" in str(exc), f"seed {seed}: unnamed error {exc}"
        return
    img = result.image
    assert result.stats["nonfinite_samples"] == 0, f"seed {seed}: non-finite samples"
    assert np.isfinite(img).all() and (img >= 0).all(), f"seed {seed}: bad pixel values"
    # Random rays straight at the geometry, including zero and NaN directions.
    geo = SceneGeometry(scene)
    n = 64
    o = rng.normal(size=(n, 3)) * np.abs(scene.camera.matrix[:3, 3]).max() + scene.camera.matrix[:3, 3]
    d = rng.normal(size=(n, 3))
    d[0] = 0.0
    d[1] = np.nan
    with np.errstate(all="ignore"):
        d = d / np.linalg.norm(d, axis=1)[:, None]
        t, kind, prim, u, v = geo.intersect(o.T.copy(), d.T.copy(), Counters())
    assert len(t) == n
    assert not np.isnan(t).any(), f"seed {seed}: NaN distance"
    assert (t[kind > 0] > 0).all(), f"seed {seed}: hit at t <= 0"


@pytest.mark.parametrize("block", range(10))
def test_fuzz_random_scenes(block):
    per_block = SCENES_PER_RUN // 10
    for seed in range(block * per_block, (block + 1) * per_block):
        try:
            fuzz_one(seed)
        except AssertionError:
            raise
        except Exception as exc:  # any exception is a failure that names its seed
            raise AssertionError(f"seed {seed}: {type(exc).__name__}: {exc}") from exc
