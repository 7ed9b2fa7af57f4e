"""Light export: Blender Area lights -> the tracer's light-only AreaLight emitters.

Radiance of an area light with power P [W], colour c and exposure e:
  Blender >= 4.0 (Cycles commit a21af93e6):  L = c * P * 2^e / (pi * A)
  Blender 3.x:                                L = c * P / (4 * A)
(A = area including the object's scale; with ``normalize`` off the 1/A is dropped.)
As in Cycles, the exported light emits from its front (-Z) side only and casts no shadow.

Ray visibility, as Cycles has it (measured in Blender 5.0.1 and 3.4.1, the same in both; 32x32,
16 spp, camera facing the lamp / a roughness-0 mirror / a glass box, black world):
  * camera rays see the lamp only when the *object's* ``visible_camera`` is on.  It is off by
    default for lights (``bpy.data.objects.new`` and ``bpy.ops.object.light_add`` alike); when on,
    the front face shows its radiance and the back face stays black (one-sided);
  * mirror reflections (``visible_glossy``, on by default) and glass refraction
    (``visible_transmission``, on by default) see the lamp;
  * ``visible_diffuse`` off removes the lamp's light from diffuse surfaces altogether (shadow rays
    too): exported as ``lights_diffuse=False``, which the tracer's light sampler leaves out;
  * ``light.cycles.use_multiple_importance_sampling`` off makes the lamp unreachable by every ray
    kind (camera, mirror, glass), while shadow rays still light diffuse surfaces;
  * ``light.cycles.is_portal`` makes it a world portal, not an emitter: exported with zero
    radiance and a warning;
  * the Light's diffuse/specular/transmission factors are EEVEE-only (Cycles ignores them).
The flags live on the Object in Blender >= 3.0 (``Object.visible_*``) and in
``Object.cycles_visibility`` before it; both are read.
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


def _object_flag(ob, name, default=True):
    if hasattr(ob, "visible_" + name):                      # Blender >= 3.0
        return bool(getattr(ob, "visible_" + name))
    old = getattr(ob, "cycles_visibility", None)            # Blender 2.8x / 2.9x
    return bool(getattr(old, name, default)) if old is not None else default


def area_light_visibility(ob):
    """Cycles' ray visibility of an area light object -> the AreaLight's visible_* flags."""
    cycles = getattr(ob.data, "cycles", None)
    mis = bool(getattr(cycles, "use_multiple_importance_sampling", True))
    return dict(lights_diffuse=_object_flag(ob, "diffuse"),
                visible_camera=mis and _object_flag(ob, "camera", False),
                visible_diffuse=mis and _object_flag(ob, "diffuse"),
                visible_glossy=mis and _object_flag(ob, "glossy"),
                visible_transmission=mis and _object_flag(ob, "transmission"))


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
    flags = area_light_visibility(ob)
    if bool(getattr(getattr(light, "cycles", None), "is_portal", False)):
        warnings.append(f"Light '{ob.name}': a portal emits no light (as in Cycles); ignored")
        radiance = (0.0, 0.0, 0.0)
        flags = dict.fromkeys(flags, False)
    # Corners run counter-clockwise seen from -Z: the polygon's normal is the emitting side.
    return AreaLight(name=ob.name, vertices=world, radiance=radiance, two_sided=False, **flags)
