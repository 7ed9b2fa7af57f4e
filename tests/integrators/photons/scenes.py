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


def spot_over_mirror(size, blend, axis=(0.0, 0.0, -1.0), radius=0.0, resolution=(8, 8)) -> Scene:
    """mirror_under_ceiling with a spot light (cone of full angle `size`, `blend`, aimed along `axis`,
    Cycles 4.0's smoothstep falloff) in place of the point light: its cone falls on the mirror."""
    scene = mirror_under_ceiling(resolution)
    scene.points = [PointLight("Spot", (0.0, 0.0, LAMP_Z), (INTENSITY,) * 3, radius=radius, spot_size=size,
                               spot_blend=blend, spot_direction=tuple(axis))]
    return scene


def spot_falloff(w, size, blend, axis):
    """a(theta) of engine/scene/model.py PointLight for unit directions w (rows) from the light, written
    out here from Blender's definition: smoothstep(0, 1, (cos theta - c0) / ((1 - c0) blend)) inside
    the cone (c0 = cos(size / 2)), 0 outside."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    c, c0 = axis @ w, np.cos(0.5 * size)
    t = np.clip((c - c0) / ((1.0 - c0) * blend), 0.0, 1.0) if blend > 0 else np.ones_like(c)
    return np.where(c > c0, t * t * (3.0 - 2.0 * t), 0.0)


def ceiling_points_of(w):
    """Where the spot's rays of unit directions w (rows, downwards) meet the ceiling after the mirror."""
    mirrored = w * np.array([[1.0], [1.0], [-1.0]])
    return np.array([[0.0], [0.0], [-LAMP_Z]]) + mirrored * ((CEILING_Z + LAMP_Z) / mirrored[2])


def mirrored_spot_irradiance(points, size, blend, axis) -> np.ndarray:
    """R I a(theta) cos / d^2 at ceiling points from the spot's image at -LAMP_Z, theta the angle to
    the spot's axis of the direction the light left in (the mirror image of the one from the image)."""
    rel = points - np.array([[0.0], [0.0], [-LAMP_Z]])
    w = rel / np.sqrt((rel ** 2).sum(axis=0))
    return mirrored_irradiance(points) * spot_falloff(w * np.array([[1.0], [1.0], [-1.0]]), size, blend, axis)


BALL_R, BALL_LAMP_Z, BALL_CEILING_Z = 0.25, 0.6, 1.2     # mirror ball at the origin, spot above it, ceiling


def spot_over_mirror_ball(size, blend, axis, resolution=(8, 8)) -> Scene:
    """A spot light (radius 0) BALL_LAMP_Z above the centre of a mirror ball of radius BALL_R and
    reflectance MIRROR_R, under a large diffuse ceiling at BALL_CEILING_Z: its cone falls on the ball."""
    mats = [Material("Mirror", MIRROR, (MIRROR_R,) * 3), Material("Ceiling", DIFFUSE, (RHO,) * 3)]
    cam = Camera.look_at((0.0, -0.3, 0.2), (0.0, 0.0, BALL_CEILING_Z), lens=50.0)
    return Scene(cam, mats, quads=[plane("Ceiling", BALL_CEILING_Z, 6.0, 1, down=True)],
                 spheres=[Sphere("Ball", (0.0, 0.0, 0.0), BALL_R, 0)],
                 points=[PointLight("Spot", (0.0, 0.0, BALL_LAMP_Z), (INTENSITY,) * 3, spot_size=size,
                                    spot_blend=blend, spot_direction=tuple(axis))], resolution=resolution)


def off_the_ball(theta, phi):
    """(the directions (rows) leaving the lamp at angle theta to -z and azimuth phi, where they meet
    the ceiling after reflecting off the ball)."""
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
    o = np.array([[0.0], [0.0], [BALL_LAMP_Z]])
    b, c = (o * d).sum(axis=0), (o * o).sum(axis=0) - BALL_R ** 2
    p = o + (-b - np.sqrt(b * b - c)) * d
    n = p / BALL_R
    r = d - 2.0 * (d * n).sum(axis=0) * n
    return d, p + ((BALL_CEILING_Z - p[2]) / r[2]) * r


def ball_spot_irradiance(theta, phi, size, blend, axis, h=1e-5):
    """(ceiling points, their irradiance R I a(theta) dw / dA) for the lamp's directions (theta, phi):
    the rays of the ring theta..theta + dtheta (dw = 2 pi sin theta dtheta) land on the ring
    rho..rho + drho (dA = 2 pi rho drho; the ball is centred under the lamp), drho / dtheta by a
    central difference."""
    d, x = off_the_ball(theta, phi)
    rho = np.hypot(x[0], x[1])
    drho = (np.hypot(*off_the_ball(theta + h, phi)[1][:2]) - np.hypot(*off_the_ball(theta - h, phi)[1][:2])) / (2 * h)
    return x, MIRROR_R * INTENSITY * spot_falloff(d, size, blend, axis) * np.sin(theta) / (rho * np.abs(drho))


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


__all__ = ["GLASS", "mirror_under_ceiling", "mirrored_irradiance", "spot_over_mirror", "spot_falloff",
           "ceiling_points_of", "mirrored_spot_irradiance",
           "spot_over_mirror_ball", "off_the_ball", "ball_spot_irradiance", "glass_ball_room", "diffuse_only"]
