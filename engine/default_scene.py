"""The built-in scene, in the spirit of the report's Figure 3.5.

A Cornell room (red left wall, green right wall, white floor, ceiling and back; open
towards the camera), a square ceiling light, a mirror sphere, a glass sphere and a
procedural diffuse torus of 5,000 triangles.  Z is up, as in Blender.
"""
from __future__ import annotations

import numpy as np

from .scene import DIFFUSE, GLASS, MIRROR, Camera, Material, Quad, Scene, Sphere, TriangleMesh


def box_wall(name: str, corners, material_id: int) -> TriangleMesh:
    """Two triangles for the rectangle corners[0..3] (counter-clockwise seen from inside)."""
    v = np.asarray(corners, dtype=np.float64)
    return TriangleMesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), np.array([material_id, material_id]))


def torus(name: str, center, major: float, minor: float, rings: int, sides: int,
          material_id: int) -> TriangleMesh:
    """A torus lying in the XY plane: rings x sides x 2 triangles, outward winding."""
    i, j = np.meshgrid(np.arange(rings), np.arange(sides), indexing="ij")
    theta = 2 * np.pi * i / rings
    phi = 2 * np.pi * j / sides
    r = major + minor * np.cos(phi)
    verts = np.stack([r * np.cos(theta), r * np.sin(theta), minor * np.sin(phi)], axis=-1).reshape(-1, 3)
    verts += np.asarray(center, dtype=np.float64)
    a = (i * sides + j).ravel()
    b = (((i + 1) % rings) * sides + j).ravel()
    c = (((i + 1) % rings) * sides + (j + 1) % sides).ravel()
    d = (i * sides + (j + 1) % sides).ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return TriangleMesh(name, verts, tris, np.full(len(tris), material_id))


def cornell_scene(resolution=(256, 256), light_radiance: float = 12.0) -> Scene:
    materials = [
        Material("White", DIFFUSE, (0.75, 0.75, 0.75)),
        Material("Red", DIFFUSE, (0.63, 0.065, 0.05)),
        Material("Green", DIFFUSE, (0.14, 0.45, 0.091)),
        Material("Light", DIFFUSE, (0.0, 0.0, 0.0), emission=(light_radiance,) * 3),
        Material("Mirror", MIRROR, (0.95, 0.95, 0.95)),
        Material("Glass", GLASS, (1.0, 1.0, 1.0), ior=1.5),
        Material("Blue", DIFFUSE, (0.2, 0.35, 0.7)),
    ]
    white, red, green, light, mirror, glass, blue = range(len(materials))
    x0, x1, y0, y1, z0, z1 = -1.0, 1.0, -1.0, 1.0, 0.0, 2.0
    h = 0.3                                     # half size of the square ceiling light
    # The ceiling has a hole that the light fills, flush: a two-sided emitter just under a
    # ceiling would light it from millimetres away (heavy-tailed 1/r^2 samples, hard case S9).
    ceiling = [
        box_wall("Ceiling (back)", [(x0, h, z1), (x0, y1, z1), (x1, y1, z1), (x1, h, z1)], white),
        box_wall("Ceiling (front)", [(x0, y0, z1), (x0, -h, z1), (x1, -h, z1), (x1, y0, z1)], white),
        box_wall("Ceiling (left)", [(x0, -h, z1), (x0, h, z1), (-h, h, z1), (-h, -h, z1)], white),
        box_wall("Ceiling (right)", [(h, -h, z1), (h, h, z1), (x1, h, z1), (x1, -h, z1)], white),
    ]
    meshes = [
        box_wall("Floor", [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], white),
        *ceiling,
        box_wall("Back wall", [(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], white),
        box_wall("Left wall", [(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], red),
        box_wall("Right wall", [(x1, y0, z0), (x1, y0, z1), (x1, y1, z1), (x1, y1, z0)], green),
        torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, 50, 50, blue),
    ]
    quads = [Quad("Ceiling light", np.array([(-h, -h, z1), (-h, h, z1), (h, h, z1), (h, -h, z1)]), light)]
    spheres = [
        Sphere("Mirror ball", (-0.45, 0.25, 0.35), 0.35, mirror),
        Sphere("Glass ball", (0.4, -0.35, 0.3), 0.3, glass),
    ]
    camera = Camera.look_at((0.0, -3.4, 1.0), (0.0, 0.0, 1.0), lens=38.0, name="Camera")
    return Scene(camera, materials, meshes, spheres, quads, background=(0.0, 0.0, 0.0),
                 resolution=tuple(resolution), name="Cornell (report Fig. 3.5)")
