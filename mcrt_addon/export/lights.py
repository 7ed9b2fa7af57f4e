"""Light export: Blender Area lights -> the tracer's light-only AreaLight emitters.

Radiance of an area light with power P [W], colour c and exposure e:
  Blender >= 4.0 (Cycles commit a21af93e6):  L = c * P * 2^e / (pi * A)
  Blender 3.x:                                L = c * P / (4 * A)
(A = area including the object's scale; with ``normalize`` off the 1/A is dropped.)
As in Cycles, the exported light emits from its front (-Z) side only, is invisible to camera
rays and casts no shadow.  Unlike Cycles, it is not seen in mirror or glass reflections (the
tracer reaches it by shadow rays only); a warning says so when the scene has such materials.
Point, spot and sun lights are ignored with a warning.
"""
import math

import numpy as np

from .mesh import transform_points

DISK_SEGMENTS = 64


def area_light_radiance(light, area, version):
    power = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    color = tuple(float(c) for c in light.color)
    if not getattr(light, "normalize", True):
        area = 1.0
    if area <= 0:
        return None
    factor = power / (math.pi * area) if version >= (4, 0, 0) else power / (4.0 * area)
    return tuple(c * factor for c in color)


def area_light_polygon(light):
    """Local corners (N,3) in the z=0 plane, counter-clockwise seen from -Z (the emitting side),
    and the exact area of the shape."""
    sx = float(light.size)
    sy = float(light.size_y) if light.shape in ("RECTANGLE", "ELLIPSE") else sx
    if light.shape in ("SQUARE", "RECTANGLE"):
        pts = np.array([[-0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.5, -0.5]]) * [sx, sy]
        area = sx * sy
    else:
        t = np.linspace(0.0, -2.0 * math.pi, DISK_SEGMENTS, endpoint=False)
        pts = np.stack([0.5 * sx * np.cos(t), 0.5 * sy * np.sin(t)], axis=1)
        area = math.pi * 0.25 * sx * sy
    return np.column_stack([pts, np.zeros(len(pts))]), area


def export_area_light(ob, matrix, version, *, AreaLight, warnings):
    light = ob.data
    local, area = area_light_polygon(light)
    world = transform_points(local, matrix)
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    # area scales with the object's x and y scale (Cycles: size * |axisu|, size_y * |axisv|)
    area *= float(np.linalg.norm(m[:, 0]) * np.linalg.norm(m[:, 1]))
    radiance = area_light_radiance(light, area, version)
    if radiance is None:
        raise ValueError(f"Light '{ob.name}': area light has zero area")
    if getattr(light, "spread", math.pi) < math.pi - 1e-6:
        warnings.append(f"Light '{ob.name}': spread {math.degrees(light.spread):.0f} deg is ignored "
                        "(full hemisphere)")
    # Corners run counter-clockwise seen from -Z: the polygon's normal is the emitting side.
    return AreaLight(name=ob.name, vertices=world, radiance=radiance, two_sided=False)
