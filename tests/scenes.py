"""Small analytic test scenes shared by the engine tests."""
import numpy as np

from engine.scene.model import DIFFUSE, Camera, Material, Quad, Scene, Sphere, TriangleMesh


def camera_inside_sphere_scene(albedo=0.8, emission=1.0, resolution=(8, 8)):
    """Camera at the centre of a closed sphere that is both diffuse and emitting (docs/hard-cases.md T1)."""
    mats = [Material("Furnace", DIFFUSE, (albedo,) * 3, emission=(emission,) * 3)]
    cam = Camera.look_at((0, 0, 0), (0, 1, 0), lens=20.0)
    return Scene(cam, mats, spheres=[Sphere("Shell", (0, 0, 0), 1.0, 0)], resolution=resolution)


def object_in_uniform_background(kind, color=1.0, resolution=(24, 24), ior=1.5):
    """A sphere of one material filling most of the view, background radiance 1 (docs/hard-cases.md T3, S7)."""
    mats = [Material("Object", kind, (color,) * 3, ior=ior)]
    cam = Camera.look_at((0, -3, 0), (0, 0, 0), lens=50.0)
    return Scene(cam, mats, spheres=[Sphere("Ball", (0, 0, 0), 0.6, 0)], background=(1, 1, 1),
                 resolution=resolution)


def floor_under_square_light(albedo=0.8, height=1.0, size=1.0, radiance=1.0):
    """A diffuse floor quad and a size x size light quad `height` above its centre.

    The camera looks straight down at the floor point below the light's centre with a
    very long lens, so every pixel sees (almost) that point: L = albedo * Le * F.
    """
    mats = [Material("Floor", DIFFUSE, (albedo,) * 3),
            Material("Light", DIFFUSE, (0, 0, 0), emission=(radiance,) * 3)]
    s = size / 2
    big = 50.0
    floor = Quad("Floor", np.array([(-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0)]), 0)
    light = Quad("Light", np.array([(-s, -s, height), (-s, s, height), (s, s, height), (s, -s, height)]), 1)
    cam = Camera.look_at((0, 0, 0.5 * height), (0, 0, 0), up=(0, 1, 0), lens=20000.0)
    return Scene(cam, mats, quads=[floor, light], resolution=(4, 4))


def form_factor_square(size, height):
    """Point-to-parallel-rectangle form factor, light centred above the point."""
    def corner(a, b, c):
        x, y = a / c, b / c
        return (x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
                + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))) / (2 * np.pi)
    return 4 * corner(size / 2, size / 2, height)


def diffuse_box_scene(resolution=(16, 16)):
    """A closed diffuse box with a ceiling light: a small Cornell room for estimator tests."""
    mats = [Material("White", DIFFUSE, (0.7, 0.7, 0.7)), Material("Red", DIFFUSE, (0.7, 0.1, 0.1)),
            Material("Light", DIFFUSE, (0, 0, 0), emission=(8, 8, 8))]
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                  [-1, -1, 2], [1, -1, 2], [1, 1, 2], [-1, 1, 2]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [3, 0, 4], [3, 4, 7]])
    ids = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1])
    h = 0.3
    light = Quad("Light", np.array([(-h, -h, 1.99), (-h, h, 1.99), (h, h, 1.99), (h, -h, 1.99)]), 2)
    cam = Camera.look_at((0, -0.95, 1.0), (0, 1, 1.0), lens=14.0)
    return Scene(cam, mats, meshes=[TriangleMesh("Box", v, faces, ids)], quads=[light],
                 resolution=resolution)


def near_lamp_box(resolution=(16, 16), gap=0.02, lamp_size=0.5, radiance=10.0, albedo=0.7):
    """A closed diffuse box (2 x 2 x 2) whose two-sided lamp quad hangs `gap` under the ceiling:
    the ceiling above it is lit from `gap` away (the near-field case, docs/hard-cases.md S9).  The camera
    looks up at the lamp's edge and the ceiling."""
    mats = [Material("White", DIFFUSE, (albedo,) * 3), Material("Lamp", DIFFUSE, (0, 0, 0), emission=(radiance,) * 3)]
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                  [-1, -1, 2], [1, -1, 2], [1, 1, 2], [-1, 1, 2]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                      [2, 3, 7], [2, 7, 6], [1, 2, 6], [1, 6, 5], [3, 0, 4], [3, 4, 7]])
    s, z = lamp_size / 2, 2.0 - gap
    lamp = Quad("Lamp", np.array([(-s, -s, z), (s, -s, z), (s, s, z), (-s, s, z)]), 1)
    cam = Camera.look_at((0.0, -0.9, 0.6), (0.25, 0.3, 2.0), lens=18.0)
    return Scene(cam, mats, meshes=[TriangleMesh("Box", v, faces, np.zeros(12, int))], quads=[lamp],
                 resolution=resolution)


def emitting_box(albedo=0.5, emission=1.0, resolution=(8, 8)):
    """A closed box of six quads, each diffuse and emitting: L = Le / (1 - albedo) everywhere."""
    mats = [Material("Wall", DIFFUSE, (albedo,) * 3, emission=(emission,) * 3)]
    c = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                  [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (3, 0, 4, 7)]
    quads = [Quad(f"Wall {i}", c[list(f)], 0) for i, f in enumerate(faces)]
    cam = Camera.look_at((0.1, -0.2, 0.05), (0.3, 1, 0.2), lens=15.0)
    return Scene(cam, mats, quads=quads, resolution=resolution)
