"""The built-in scenes: the report's Figure 3.5 and three rooms that stress light sampling.

`cornell_scene`: a Cornell room (red left wall, green right wall, white floor, ceiling and
back; open towards the camera), a square ceiling light, a mirror sphere, a glass sphere and
a procedural diffuse torus of 5,000 triangles.  The same room with
* `near_lamp_scene`: a closed ceiling and the lamp hung 2 cm under it (two-sided: it lights
  the ceiling from 2 cm, the near-field case of the light-sampling study);
* `caustic_scene`: a glass ball resting on the floor under a small lamp;
* `many_lights_scene`: a 6 x 6 grid of small lamps 1 cm under the ceiling.
Z is up, as in Blender.  `BUILTIN_SCENES` names them for the command line and the study.
"""
from __future__ import annotations

import copy

import numpy as np

from .model import DIFFUSE, GLASS, MIRROR, Camera, Material, Quad, Scene, Sphere, TriangleMesh


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


ROOM_MATERIALS = [
    Material("White", DIFFUSE, (0.75, 0.75, 0.75)),
    Material("Red", DIFFUSE, (0.63, 0.065, 0.05)),
    Material("Green", DIFFUSE, (0.14, 0.45, 0.091)),
    Material("Light", DIFFUSE, (0.0, 0.0, 0.0), emission=(12.0, 12.0, 12.0)),
    Material("Mirror", MIRROR, (0.95, 0.95, 0.95)),
    Material("Glass", GLASS, (1.0, 1.0, 1.0), ior=1.5),
    Material("Blue", DIFFUSE, (0.2, 0.35, 0.7)),
]
WHITE, RED, GREEN, LIGHT, MIRROR_MAT, GLASS_MAT, BLUE = range(len(ROOM_MATERIALS))
X0, X1, Y0, Y1, Z0, Z1 = -1.0, 1.0, -1.0, 1.0, 0.0, 2.0


def room_walls(ceiling_hole: float | None = None) -> list:
    """Floor, back, left (red) and right (green) walls and the ceiling, with a square hole of
    half-size `ceiling_hole` in its middle (filled flush by a lamp) or closed."""
    h = ceiling_hole
    if h is None:
        ceiling = [box_wall("Ceiling", [(X0, Y0, Z1), (X0, Y1, Z1), (X1, Y1, Z1), (X1, Y0, Z1)], WHITE)]
    else:
        ceiling = [
            box_wall("Ceiling (back)", [(X0, h, Z1), (X0, Y1, Z1), (X1, Y1, Z1), (X1, h, Z1)], WHITE),
            box_wall("Ceiling (front)", [(X0, Y0, Z1), (X0, -h, Z1), (X1, -h, Z1), (X1, Y0, Z1)], WHITE),
            box_wall("Ceiling (left)", [(X0, -h, Z1), (X0, h, Z1), (-h, h, Z1), (-h, -h, Z1)], WHITE),
            box_wall("Ceiling (right)", [(h, -h, Z1), (h, h, Z1), (X1, h, Z1), (X1, -h, Z1)], WHITE),
        ]
    return [
        box_wall("Floor", [(X0, Y0, Z0), (X1, Y0, Z0), (X1, Y1, Z0), (X0, Y1, Z0)], WHITE),
        *ceiling,
        box_wall("Back wall", [(X0, Y1, Z0), (X1, Y1, Z0), (X1, Y1, Z1), (X0, Y1, Z1)], WHITE),
        box_wall("Left wall", [(X0, Y0, Z0), (X0, Y1, Z0), (X0, Y1, Z1), (X0, Y0, Z1)], RED),
        box_wall("Right wall", [(X1, Y0, Z0), (X1, Y0, Z1), (X1, Y1, Z1), (X1, Y1, Z0)], GREEN),
    ]


def lamp(name: str, cx: float, cy: float, half: float, z: float) -> Quad:
    return Quad(name, np.array([(cx - half, cy - half, z), (cx - half, cy + half, z), (cx + half, cy + half, z),
                                (cx + half, cy - half, z)]), LIGHT)


def room(name, meshes, quads, spheres, resolution, materials=None) -> Scene:
    camera = Camera.look_at((0.0, -3.4, 1.0), (0.0, 0.0, 1.0), lens=38.0, name="Camera")
    return Scene(camera, [copy.copy(m) for m in (materials or ROOM_MATERIALS)], meshes, spheres, quads,
                 background=(0.0, 0.0, 0.0), resolution=tuple(resolution), name=name)


def cornell_scene(resolution=(256, 256), light_radiance: float = 12.0) -> Scene:
    h = 0.3                                     # half size of the square ceiling light
    # The ceiling has a hole that the light fills, flush: a two-sided emitter just under a
    # ceiling would light it from millimetres away (heavy-tailed 1/r^2 samples, docs/hard-cases.md S9).
    meshes = room_walls(ceiling_hole=h) + [torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, 50, 50, BLUE)]
    spheres = [Sphere("Mirror ball", (-0.45, 0.25, 0.35), 0.35, MIRROR_MAT),
               Sphere("Glass ball", (0.4, -0.35, 0.3), 0.3, GLASS_MAT)]
    scene = room("Cornell (report Fig. 3.5)", meshes, [lamp("Ceiling light", 0, 0, h, Z1)], spheres, resolution)
    scene.materials[LIGHT].emission = (light_radiance,) * 3
    return scene


def near_lamp_scene(resolution=(256, 256)) -> Scene:
    """The lamp hangs 2 cm under a closed ceiling and lights it from there (two-sided)."""
    meshes = room_walls() + [torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, 50, 50, BLUE)]
    return room("Near-field lamp", meshes, [lamp("Lamp 2 cm under the ceiling", 0, 0, 0.25, Z1 - 0.02)], [],
                resolution)


def caustic_scene(resolution=(256, 256)) -> Scene:
    """A glass ball resting on the floor under a small lamp: the floor under it is lit by caustics."""
    scene = room("Caustic", room_walls(ceiling_hole=0.1), [lamp("Small lamp", 0, 0, 0.1, Z1)],
                 [Sphere("Glass ball", (0.0, 0.0, 0.35), 0.35, GLASS_MAT)], resolution)
    scene.materials[LIGHT].emission = (60.0, 60.0, 60.0)
    return scene


def many_lights_scene(resolution=(256, 256)) -> Scene:
    """36 lamps of 8 cm in a 6 x 6 grid, 1 cm under the ceiling, with the power of the Cornell lamp."""
    grid = (np.arange(6) - 2.5) * 0.3
    # One mesh of 36 quads (72 triangles), as a Blender file has it: Embree traces it, and the
    # light sampler pairs its triangles back into 36 rectangle lights.
    corners = np.concatenate([lamp("", x, y, 0.04, Z1 - 0.01).corners for x in grid for y in grid])
    quads = np.arange(len(corners)).reshape(-1, 4)
    lamps = TriangleMesh("Lamps", corners, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1
                                                          ).reshape(-1, 3), np.full(2 * len(quads), LIGHT))
    meshes = room_walls() + [torus("Torus", (0.25, 0.45, 0.12), 0.3, 0.12, 50, 50, BLUE), lamps]
    scene = room("Many lights", meshes, [], [Sphere("Ball", (-0.4, -0.2, 0.3), 0.3, WHITE)], resolution)
    # 0.36 m^2 at radiance 12, spread over 36 x 0.0064 m^2 (both emit from two sides).
    scene.materials[LIGHT].emission = (12.0 * 0.36 / (36 * 0.0064),) * 3
    return scene


BUILTIN_SCENES = {"cornell": cornell_scene, "near_lamp": near_lamp_scene, "caustic": caustic_scene,
                  "many_lights": many_lights_scene}
