"""The effect plan: which kernels and scattering effects a scene needs, and why.

Decided once from the scene before tracing.  The integrator consults it so that a
diffuse-only scene never evaluates Fresnel or refraction and a scene without spheres
never runs the sphere test.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .scene import DIFFUSE, GLASS, MIRROR

EFFECTS = ("spheres", "quads", "triangles", "diffuse", "mirror", "glass", "emission")


@dataclass
class EffectPlan:
    enabled: dict = field(default_factory=dict)
    reason: dict = field(default_factory=dict)

    def __getattr__(self, name):
        try:
            return self.__dict__["enabled"][name]
        except KeyError:
            raise AttributeError(name) from None

    def summary(self) -> str:
        on = [name for name in EFFECTS if self.enabled[name]]
        return ", ".join(on) if on else "nothing"

    def describe(self) -> str:
        lines = []
        for name in EFFECTS:
            mark = "on " if self.enabled[name] else "off"
            lines.append(f"  {mark} {name:9s} {self.reason[name]}")
        return "\n".join(lines)


def _names(objects, limit=3) -> str:
    names = [f"'{o.name}'" for o in objects[:limit]]
    more = f" and {len(objects) - limit} more" if len(objects) > limit else ""
    return ", ".join(names) + more


def plan_effects(scene, settings) -> EffectPlan:
    plan = EffectPlan()
    mats = scene.materials

    def set_effect(name, on, why):
        plan.enabled[name] = bool(on)
        plan.reason[name] = why

    meshes = [m for m in scene.meshes if len(m.triangles)]
    n_tri = sum(len(m.triangles) for m in meshes)
    set_effect("triangles", n_tri > 0,
               f"{n_tri} triangles in {_names(meshes)}: Embree kernel" if n_tri
               else "no triangle meshes: triangle kernel skipped")
    set_effect("spheres", bool(scene.spheres),
               f"{len(scene.spheres)} implicit sphere(s) {_names(scene.spheres)}: sphere kernel"
               if scene.spheres else "no implicit spheres: sphere kernel skipped")
    set_effect("quads", bool(scene.quads),
               f"{len(scene.quads)} quad(s) {_names(scene.quads)}: quad kernel"
               if scene.quads else "no quads: quad kernel skipped")

    # Materials actually used by some primitive.
    used = set()
    for mesh in meshes:
        used.update(np.unique(mesh.material_ids).tolist())
    used.update(s.material_id for s in scene.spheres)
    used.update(q.material_id for q in scene.quads)
    used_mats = [mats[i] for i in sorted(used)]

    def users(predicate):
        return [m for m in used_mats if predicate(m)]

    diffuse = users(lambda m: m.kind == DIFFUSE and max(m.color) > 0)
    mirror = users(lambda m: m.kind == MIRROR and max(m.color) > 0)
    glass = users(lambda m: m.kind == GLASS)
    emitters = users(lambda m: m.is_emissive) + [l for l in scene.lights if max(l.radiance) > 0]
    set_effect("diffuse", diffuse,
               f"diffuse materials {_names(diffuse)}: shadow rays (eq. 2.11) and cosine bounces (eq. 2.14)"
               if diffuse else "no diffuse material: no shadow rays or diffuse bounces")
    set_effect("mirror", mirror,
               f"mirror materials {_names(mirror)}: perfect reflection (eq. 2.20)"
               if mirror else "no mirror material: reflection path skipped")
    set_effect("glass", glass,
               f"glass materials {_names(glass)}: {settings.fresnel} Fresnel and refraction (eq. 2.17, 2.24)"
               + ("; nested media tracked" if settings.nested_dielectrics else "")
               if glass else "no glass material: Fresnel and refraction never evaluated")
    set_effect("emission", emitters,
               f"emitters {_names(emitters)}: area lights sampled by area (pdf 1/A)"
               if emitters else "no emissive surfaces: no light sampling"
               + (" (background light only)" if max(scene.background) > 0 else ""))
    return plan
