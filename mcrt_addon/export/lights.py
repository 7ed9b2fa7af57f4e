"""Light export: Blender Area lights -> emissive triangles (the tracer's only light source).

Radiance of an area light with power P [W], colour c and exposure e:
  Blender >= 4.0 (Cycles commit a21af93e6):  L = c * P * 2^e / (pi * A)
  Blender 3.x:                                L = c * P / (4 * A)
(A = area including the object's scale; with ``normalize`` off the 1/A is dropped.)
Cycles' area lights emit from their front (-Z) side only; the tracer's emitters are two-sided,
so light leaving the back of the lamp is an acknowledged model difference (a warning says so).
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


def export_area_light(ob, matrix, version, *, Material, TriangleMesh, material_table, warnings):
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
    warnings.append(f"Light '{ob.name}': area light exported as a two-sided emissive "
                    "polygon (Cycles' area lights emit from the front only)")
    n = len(world)
    tris = np.array([[0, i, i + 1] for i in range(1, n - 1)], dtype=np.int64)
    mat_id = material_table.add(Material(name=f"{ob.name} (area light)", kind=material_table.DIFFUSE,
                                         color=(0.0, 0.0, 0.0), emission=radiance))
    return TriangleMesh(name=ob.name, vertices=world, triangles=tris,
                        material_ids=np.full(len(tris), mat_id, dtype=np.int64))
