"""Scenes for the caustic photon tests (engine/integrators/photons/)."""
from __future__ import annotations

import numpy as np

from engine.scene.model import DIFFUSE, GLASS, MIRROR, Camera, Material, PointLight, Quad, Scene, Sphere

MIRROR_R, RHO, INTENSITY = 0.9, 0.5, 10.0
LAMP_Z, CEILING_Z, HALF = 0.5, 1.0, 4.0            # point lamp, ceiling height, half size of both planes


def plane(name, z, half, material, down=False):
    c = [(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)]
    return Quad(name, np.array(c[::-1] if down else c, dtype=np.float64), material)


def mirror_under_ceiling(resolution=(8, 8)) -> Scene:
    """A point light (radius 0) LAMP_Z above a large horizontal mirror of reflectance MIRROR_R, under a
    diffuse ceiling of albedo RHO at CEILING_Z; the camera looks up at the ceiling above the lamp."""
    mats = [Material("Mirror", MIRROR, (MIRROR_R,) * 3), Material("Ceiling", DIFFUSE, (RHO,) * 3)]
    cam = Camera.look_at((0.0, -0.3, 0.2), (0.0, 0.0, CEILING_Z), lens=50.0)
    return Scene(cam, mats, quads=[plane("Mirror", 0.0, HALF, 0), plane("Ceiling", CEILING_Z, HALF, 1, down=True)],
                 points=[PointLight("Lamp", (0.0, 0.0, LAMP_Z), (INTENSITY,) * 3)], resolution=resolution)


def mirrored_irradiance(points) -> np.ndarray:
    """R I cos(theta) / d^2 at ceiling points (rows) from the lamp's image in the mirror, at -LAMP_Z."""
    rel = points - np.array([[0.0], [0.0], [-LAMP_Z]])
    d2 = (rel ** 2).sum(axis=0)
    return MIRROR_R * INTENSITY * (rel[2] / np.sqrt(d2)) / d2


def glass_ball_room(resolution=(24, 24), light=12.0, lamp_half=0.3) -> Scene:
    """The built-in Cornell room with a glass ball under its lamp (engine/scene/builtin.py)."""
    from engine.scene.builtin import GLASS_MAT, LIGHT, lamp, room, room_walls, Z1
    scene = room("Glass ball room", room_walls(ceiling_hole=lamp_half), [lamp("Lamp", 0, 0, lamp_half, Z1)],
                 [Sphere("Glass ball", (0.0, 0.0, 0.4), 0.4, GLASS_MAT)], resolution)
    scene.materials[LIGHT].emission = (light,) * 3
    return scene


def diffuse_only(resolution=(8, 8)) -> Scene:
    mats = [Material("Floor", DIFFUSE, (0.5,) * 3), Material("Ball", DIFFUSE, (0.8,) * 3)]
    cam = Camera.look_at((0.0, -3.0, 1.0), (0.0, 0.0, 0.0))
    return Scene(cam, mats, quads=[plane("Floor", 0.0, 2.0, 0)], spheres=[Sphere("Ball", (0, 0, 0.5), 0.5, 1)],
                 points=[PointLight("Lamp", (0.0, 0.0, 2.0), (10.0,) * 3)], resolution=resolution)


__all__ = ["GLASS", "mirror_under_ceiling", "mirrored_irradiance", "glass_ball_room", "diffuse_only"]
