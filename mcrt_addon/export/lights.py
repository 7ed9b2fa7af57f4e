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
Point lights (measured the same in Cycles 3.4 and 5.0): intensity I = P * colour * 2^exposure
/ (4 pi) from the object's location; with a radius (shadow_soft_size) a disk of that radius facing
the receiver.  Sun lights: irradiance E = strength * colour * 2^exposure on a surface facing the
sun, from directions within `angle` about the object's local +Z (the light travels along -Z);
Cycles 3.x gives a sun of angular diameter theta only (1 + cos(theta/2)) / 2 of that (measured:
0.984 at 0.5 rad), 4.0 and later the full E.  Both reach diffuse surfaces by shadow rays only:
unlike Cycles they are not seen in mirrors or glass.  Spot lights are ignored with a warning.
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


def lamp_visibility(ob):
    """Cycles' ray visibility of a point, spot or sun light object -> the light's flags (camera
    and diffuse rays never meet these lamps in the tracer: see engine/lights/seen.py)."""
    flags = area_light_visibility(ob)
    return {key: flags[key] for key in ("lights_diffuse", "visible_glossy", "visible_transmission")}


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


def _power(light):
    return float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def export_point_light(ob, matrix, version, *, PointLight):
    """A point or spot light (the spot's cone about the object's -Z axis, its falloff as the
    Cycles of this Blender version has it: see engine/scene/model.py PointLight)."""
    light = ob.data
    intensity = tuple(float(c) * _power(light) / (4.0 * math.pi) for c in light.color)
    radius = float(getattr(light, "shadow_soft_size", 0.0))
    if not math.isfinite(radius) or radius < 0:
        raise ValueError(f"Light '{ob.name}': radius must be 0 or more, got {radius!r}")
    m = np.asarray(matrix, dtype=np.float64)
    spot = {}
    if light.type == "SPOT":
        axis = -m[:3, 2]
        if not np.linalg.norm(axis) > 0:
            raise ValueError(f"Light '{ob.name}': spot has a zero scale, so no direction")
        spot = dict(spot_size=min(float(light.spot_size), math.pi), spot_blend=float(light.spot_blend),
                    spot_direction=tuple(float(v) for v in axis / np.linalg.norm(axis)),
                    spot_falloff="smoothstep" if version >= (4, 0, 0) else "cosine-smoothstep")
    # Cycles takes the radius as it is, whatever the object's scale.
    return PointLight(name=ob.name, position=tuple(float(v) for v in m[:3, 3]),
                      intensity=intensity, radius=radius, **spot, **lamp_visibility(ob))


def export_sun_light(ob, matrix, version, *, SunLight):
    light = ob.data
    angle = float(getattr(light, "angle", 0.0))
    factor = 1.0 if version >= (4, 0, 0) else 0.5 * (1.0 + math.cos(0.5 * angle))
    irradiance = tuple(float(c) * _power(light) * factor for c in light.color)
    down = -np.asarray(matrix, dtype=np.float64)[:3, 2]
    if not np.linalg.norm(down) > 0:
        raise ValueError(f"Light '{ob.name}': sun has a zero scale, so no direction")
    return SunLight(name=ob.name, direction=tuple(float(v) for v in down / np.linalg.norm(down)),
                    irradiance=irradiance, angle=angle, **lamp_visibility(ob))
