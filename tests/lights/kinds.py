"""One instance of every light kind (engine/lights/protocol.py), each with a few lights that
differ (one- and two-sided, delta and not, spot and not), for the tests of this package.

A new kind is added to EVERY_KIND: the conformance test then checks it against the protocol.
"""
from __future__ import annotations

import numpy as np

from engine.lights.distant import SunLights, WorldLight
from engine.lights.parallelograms import Parallelograms
from engine.lights.points import PointLights
from engine.lights.polygons import Polygons
from engine.lights.spheres import Spheres
from engine.lights.triangles import Triangles
from engine.scene.model import PointLight, SunLight


def disk(center, radius, sides=16, normal_sign=1.0):
    """Corners of a regular polygon in a plane z = const, counter-clockwise seen from +z (normal
    +z) or, with normal_sign -1, clockwise (normal -z)."""
    t = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False) * normal_sign
    return np.stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t), np.full(sides, center[2])], axis=1)


PENTAGON = np.array([[0.0, 0.0, 1.5], [1.2, 0.1, 1.5], [1.5, 0.9, 1.5], [0.6, 1.6, 1.5], [-0.3, 0.7, 1.5]])


def parallelograms():
    return Parallelograms([[-0.5, -0.25, 2.0], [1.0, -1.0, 1.0]], [[1.0, 0.0, 0.0], [0.8, 0.0, 0.2]],
                          [[0.0, 0.5, 0.0], [0.3, 0.6, 0.0]], radiance=[[3.0, 2.0, 1.0], [0.5, 0.7, 2.0]],
                          one_sided=[True, False])


def triangles():
    return Triangles([[0.0, 0.0, 2.0], [-2.0, 0.0, 0.5]], [[1.0, 0.0, 2.0], [-1.0, 0.0, 0.6]],
                     [[0.2, 0.8, 2.0], [-1.5, 1.0, 1.5]], radiance=(1.0, 2.0, 3.0), one_sided=[False, True])


def spheres():
    return Spheres([[0.5, -1.0, 0.5], [-1.0, 1.0, 1.0]], [0.2, 0.5], radiance=[[4.0, 4.0, 4.0], [1.0, 0.5, 0.2]])


POLYGONS = [disk((0.0, -2.0, 1.8), 0.3, normal_sign=-1.0), PENTAGON]


def polygons():
    return Polygons(POLYGONS, radiance=[[4.0, 4.0, 4.0], [1.0, 2.0, 1.0]], one_sided=[True, False])


def point_lights():
    return PointLights([
        PointLight("Point", (0.1, 0.2, 2.5), (5.0, 4.0, 3.0)),
        PointLight("Bulb", (1.1, -0.2, 2.2), (2.0, 4.0, 3.0), radius=0.1),
        PointLight("Spot", (-1.1, 0.2, 2.4), (7.0, 4.0, 3.0), radius=0.05, spot_size=1.0, spot_blend=0.3,
                   spot_direction=(0.1, 0.2, -1.0)),
        PointLight("Old spot", (-0.1, 1.2, 2.4), (7.0, 4.0, 9.0), radius=0.2, spot_size=2.0, spot_blend=1.0,
                   spot_falloff="cosine-smoothstep", spot_direction=(0.0, 1.0, -1.0))])


SUNS = [SunLight("Sharp sun", (0.3, 0.2, -1.0), (2.0, 2.0, 1.5)),
        SunLight("Soft sun", (-0.3, 0.2, -1.0), (1.0, 2.0, 1.5), angle=0.2)]


def suns():
    return SunLights(SUNS, 3.0)


def world():
    return WorldLight((0.2, 0.3, 0.4), 3.0)


def environment():
    """The image world under the sample sky of scripts/make_sample_hdr.py, turned by a rotation."""
    from engine.lights.environment import EnvironmentLight, EnvironmentMap
    from engine.scene.model import Environment
    from scripts.make_sample_hdr import sky_pixels
    env = Environment(0, strength=0.5, matrix=((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    return EnvironmentLight(EnvironmentMap(env, sky_pixels(32, 16), False), 3.0)


EVERY_KIND = {"parallelograms": parallelograms, "triangles": triangles, "spheres": spheres,
              "polygons": polygons, "point lights": point_lights, "suns": suns, "world": world,
              "environment": environment}
