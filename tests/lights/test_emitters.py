"""engine/lights/emitters.py (what the light set gathers from a scene) and
engine/lights/emitting_surface.py (the base of the surface kinds): a quad triangulated as Blender
does is one parallelogram light, a kite is two triangles; the scene's bounding radius; every
surface kind of the conformance list derives from the base."""
import numpy as np

from engine.lights.emitters import is_parallelogram, parallelogram_pairs, scene_radius
from engine.lights.emitting_surface import EmittingSurface
from engine.lights.points import PointLights
from engine.scene.model import Camera, Material, Scene, Sphere, TriangleMesh
from tests.lights.kinds import EVERY_KIND


def test_a_triangulated_rectangle_is_one_parallelogram_and_a_kite_is_not():
    square = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    first, corner, e1, e2 = parallelogram_pairs(square, tris, np.array([0, 0]))
    assert first.tolist() == [0]
    assert np.isclose(abs(np.cross(e1[0], e2[0])[2]), 2.0)              # the area of the rectangle
    normal = np.cross(square[1] - square[0], square[2] - square[0])
    assert np.dot(np.cross(e1[0], e2[0]), normal) > 0                    # oriented like the triangle
    kite = square.copy()
    kite[2] = [2.5, 1.5, 0]
    assert len(parallelogram_pairs(kite, tris, np.array([0, 0]))[0]) == 0
    assert len(parallelogram_pairs(square, tris, np.array([0, 1]))[0]) == 0   # two materials: no pair
    assert is_parallelogram(square) and not is_parallelogram(kite)


def test_no_triangle_belongs_to_two_pairs():
    strip = np.array([[x, y, 0] for x in range(4) for y in (0, 1)], float)   # 3 squares side by side
    tris = np.array([[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3], [4, 6, 7], [4, 7, 5]])
    first = parallelogram_pairs(strip, tris, np.zeros(6, int))[0]
    assert np.all(np.diff(first) >= 2)
    assert len(first) == 3


def test_scene_radius_holds_every_primitive():
    mesh = TriangleMesh("M", np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0]], float), np.array([[0, 1, 2]]), [0])
    scene = Scene(Camera(np.eye(4)), [Material("m")], meshes=[mesh], spheres=[Sphere("S", (0, 0, -5), 1.0, 0)])
    r = scene_radius(scene)
    assert r >= 6.0                                  # the sphere reaches z = -6
    assert r <= 6.0 * np.sqrt(3.0) + 1e-12           # and no more than the box's diagonal


def test_every_surface_kind_is_an_emitting_surface():
    kinds = {type(make()) for make in EVERY_KIND.values()}
    surfaces = [k for k in kinds if issubclass(k, EmittingSurface)]
    assert {k.__name__ for k in surfaces} >= {"Parallelograms", "Triangles", "Polygons", "Spheres"}
    assert not issubclass(PointLights, EmittingSurface)
