"""The compiled Area-light polygon test (engine/geometry/shapes/light_polygons_jit.py) against the
NumPy one (engine/geometry/shapes/light_polygons.py): triangles to octagons, one light for all rays
and one light per ray, with the ray kinds each light is visible to, and rays through corners and
along edges; and a whole render of Area lights on both backends."""
import numpy as np

from engine import api
from engine.core.settings import RenderSettings
from engine.geometry.shapes.light_polygons import LightPolygons
from engine.scene.builtin import cornell_scene
from engine.scene.model import AreaLight
from tests.backend_capture import require_compiled
from tests.geometry.test_light_polygons import convex_polygon

TWIN = "engine.geometry.shapes.light_polygons_jit"   # imported by LightPolygons(backend="numba")


def lights(rng):
    polygons = [convex_polygon(rng, n) for n in (3, 4, 5, 8, 4)]
    flags = [dict(), dict(visible_camera=True), dict(visible_glossy=True, visible_camera=True), dict(), dict()]
    return [AreaLight(f"Lamp{i}", v, (1, 1, 1), **f) for i, (v, f) in enumerate(zip(polygons, flags))], polygons


def test_one_light_and_pairs_bit_identical():
    require_compiled()
    rng = np.random.default_rng(4)
    objects, polygons = lights(rng)
    numpy_lights, compiled = LightPolygons(objects), LightPolygons(objects, backend="numba")
    m = 6000
    o = rng.uniform(-6, 6, (3, m))
    targets = np.concatenate([p[rng.integers(0, len(p), 200)].T for p in polygons], axis=1)   # corners
    aim = rng.uniform(-3, 3, (3, m))
    aim[:, :targets.shape[1]] = targets
    d = aim - o
    d /= np.linalg.norm(d, axis=0)
    bound = np.where(rng.random(m) < 0.3, 2.0, np.inf)
    hits = 0
    for k in range(len(objects)):
        a = numpy_lights.intersect_one(k, o, d, bound)
        assert np.array_equal(a, compiled.intersect_one(k, o, d, bound))
        hits += np.isfinite(a).sum()
    assert hits > 500
    prim = rng.integers(0, len(objects), m)
    ray_kind = rng.integers(0, 4, m).astype(np.int8)
    for kinds in (None, ray_kind):
        assert np.array_equal(numpy_lights.intersect_pairs(prim, o, d, bound, kinds),
                              compiled.intersect_pairs(prim, o, d, bound, kinds))
    # Control: the comparison sees a light grown by 1 %.
    grown = [AreaLight(x.name, x.vertices * 1.01, (1, 1, 1)) for x in objects]
    assert not np.array_equal(numpy_lights.intersect_one(3, o, d, bound),
                              LightPolygons(grown, backend="numba").intersect_one(3, o, d, bound))


def test_render_with_area_lights_on_both_backends():
    require_compiled()
    scene = cornell_scene((16, 16))
    square = np.array([[-0.3, -0.3, 0.98], [-0.3, 0.3, 0.98], [0.3, 0.3, 0.98], [0.3, -0.3, 0.98]])
    scene.lights = [AreaLight("Area", square, (8.0, 8.0, 8.0), visible_camera=True, visible_glossy=True)]
    images = {}
    for b in ("numpy", "numba"):
        result = api.render(scene, RenderSettings(samples=4, threads=1, backend=b), log=lambda m: None)
        images[b] = result.image
        assert result.stats["kernel_backends"].get("area_lights") == b
    assert np.array_equal(images["numpy"], images["numba"])
