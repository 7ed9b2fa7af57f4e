"""The effect plan: which kernels and which parts of the estimator a scene needs, and why.

Decided once from the scene and the settings before tracing; it is the one place that
switches work on.  The geometry builds only the intersection kernels the plan enables
(a scene without spheres never runs the sphere test), the integrator runs only the stages
it enables (a diffuse-only scene never evaluates Fresnel or refraction; no MIS weights where
only one strategy can reach a light), and the light set builds the light tree only for
more than one light.  `describe()` prints every decision with its reason.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..scene.model import (DIFFUSE, GLASS, GLOSSY, MIRROR, MIX, PRINCIPLED, REFRACTION, TRANSLUCENT,
                           TRANSPARENT, Principled, PrincipledV1)
from ..geometry.shading_normals import has_smooth
from ..materials.oren_nayar import ENERGY_PRESERVING_SINCE
from ..materials.principled import DIFFUSE_ROUGHNESS_CUTOFF, WEIGHT_CUTOFF, specular_eta_f0
from ..materials.principled_v1 import SINGLE_SCATTER_ROUGHNESS
from ..materials.principled_v1_glass import SINGLE_SCATTER_ROUGHNESS as GLASS_SINGLE_SCATTER_ROUGHNESS
from ..materials.table import (BLURRED_ROWS, NON_DELTA_KINDS, PRINCIPLED_V1, ROUGH_DIFFUSE, ROUGH_GLASS,
                               ROUGH_REFRACTION, scatter_kind)
from ..materials.textures import textured_materials

EFFECTS = ("triangles", "smooth_normals", "spheres", "quads", "area_lights", "diffuse", "mirror", "glass",
           "glossy", "principled", "rough_diffuse", "mix", "rough_glass", "refraction", "transparent", "translucent",
           "emission", "seen_lamps", "world_light", "direct_light", "solid_angle",
           "light_tree", "mis", "deferred_roulette", "passes",
           "textures",
           "bounce_limits", "clamp", "filter_glossy", "caustics",     # Light Paths (engine/integrators/light_paths.py)
           "photon_caustics")                                         # engine/integrators/photons/
ACCELERATOR_KERNEL = {"embree": "Embree kernel", "octree": "octree kernel (Python)",
                      "brute": "brute-force kernel (every triangle)"}


@dataclass
class EffectPlan:
    enabled: dict = field(default_factory=dict)
    reason: dict = field(default_factory=dict)
    cycles_version: tuple = (5, 0)      # the scene's: the models that follow Cycles' versions use it
    backend: str = "numpy"              # the hot kernels' backend and why (engine/core/backend.py)
    backend_reason: str = "NumPy (the reference)"
    backends: dict = field(default_factory=dict)   # kernel with a compiled twin -> the backend that runs it

    def use_backend(self, backend: str, reason: str, kernels) -> None:
        """Record the render's backend: each of its kernels (`kernels`: names) that has a compiled
        twin runs on it."""
        from ..core.backend import KERNELS
        self.backend, self.backend_reason = backend, reason
        self.backends = {k: backend for k in KERNELS if k in kernels}

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
            lines.append(f"  {mark} {name:12s} {self.reason[name]}"
                         + (f" [{self.backends[name]}]" if name in self.backends else ""))
        lines.append(f"  backend: {self.backend} ({self.backend_reason})")
        return "\n".join(lines)

    def describe_light_kinds(self, lights) -> None:
        """Add to the solid-angle reason how each kind of light in `lights` is sampled."""
        if not self.enabled["solid_angle"]:
            return
        how = {"parallelogram": "spherical rectangles (area where grazing or not rectangular)",
               "triangle": "spherical triangles (area where grazing or tiny)",
               "sphere": "cones from outside, area from inside", "polygon": "area (disks, ellipses)",
               "point": "the cone of the disk they show (a delta light without a radius; spot lights "
                         "weight it by their cone's falloff)"}
        counts = {}
        for kind in lights.local.kinds:
            counts[kind.name] = counts.get(kind.name, 0) + kind.count
        self.reason["solid_angle"] += ": " + "; ".join(f"{n} {k} light(s) by {how[k]}" for k, n in counts.items())


def _names(objects, limit=3) -> str:
    names = [f"'{o.name}'" for o in objects[:limit]]
    more = f" and {len(objects) - limit} more" if len(objects) > limit else ""
    return ", ".join(names) + more


def plan_effects(scene, settings, accelerator: str = "embree") -> EffectPlan:
    plan = EffectPlan()
    mats = scene.materials

    def set_effect(name, on, why):
        plan.enabled[name] = bool(on)
        plan.reason[name] = why

    meshes = [m for m in scene.meshes if len(m.triangles)]
    n_tri = sum(len(m.triangles) for m in meshes)
    set_effect("triangles", n_tri > 0,
               f"{n_tri} triangles in {_names(meshes)}: {ACCELERATOR_KERNEL.get(accelerator, accelerator)}"
               if n_tri else "no triangle meshes: triangle kernel skipped")
    smooth = [m for m in meshes if has_smooth([m])]
    n_smooth = has_smooth(smooth)
    set_effect("smooth_normals", n_smooth > 0,
               f"{n_smooth} smooth-shaded triangles in {_names(smooth)}: corner normals interpolated at "
               "hits for shading, geometric normal for offsets and side tests"
               if n_smooth else "no smooth-shaded faces: flat (geometric) normals, nothing interpolated")
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
    mixes = [m for m in used_mats if m.kind == MIX and m.mix is not None]
    used_mats += [leaf.material for m in mixes for leaf in m.mix.leaves]     # a mix scatters by its leaves' rows

    def users(predicate):
        return [m for m in used_mats if predicate(m)]

    report = settings.estimator == "report"
    lamps = [light for light in scene.lights if max(light.radiance) > 0]
    seen_lamps = [light for light in lamps if any(
        getattr(light, f"visible_{k}") for k in ("camera", "diffuse", "glossy", "transmission"))]
    set_effect("area_lights", lamps and not report and seen_lamps,
               f"Area light(s) {_names(seen_lamps)} reached by rays (Cycles' ray visibility), light kernel"
               if lamps and not report and seen_lamps else
               "no Area lights: light kernel skipped" if not lamps else
               "report estimator: Area lights are reached by shadow rays only (eq. 2.11)" if report else
               "Area lights invisible to every ray kind: reached by shadow rays only")

    diffuse = users(lambda m: m.kind == DIFFUSE and (max(m.color) > 0 or m.color_texture is not None))
    mirror = users(lambda m: m.kind == MIRROR and (max(m.color) > 0 or m.color_texture is not None))
    glass = users(lambda m: scatter_kind(m) == GLASS)
    glossy = users(lambda m: m.kind == GLOSSY and (max(m.color) > 0 or m.color_texture is not None))
    principled = users(lambda m: m.kind == PRINCIPLED)         # its specular layer reflects on a black base
    lit = users(lambda m: scatter_kind(m) in NON_DELTA_KINDS and (max(m.color) > 0 or m.color_texture is not None
                                                         or m.kind == PRINCIPLED))
    surface_emitters = users(lambda m: m.is_emissive)
    bulbs = [p for p in scene.points if max(p.intensity) > 0]
    suns = [s for s in scene.suns if max(s.irradiance) > 0]
    emitters = surface_emitters + lamps + bulbs + suns
    set_effect("diffuse", diffuse,
               f"diffuse materials {_names(diffuse)}: cosine bounces (eq. 2.13-2.14)"
               if diffuse else "no diffuse material: no diffuse bounces")
    set_effect("mirror", mirror,
               f"mirror materials {_names(mirror)}: perfect reflection (eq. 2.20)"
               if mirror else "no mirror material: reflection path skipped")
    set_effect("glass", glass,
               f"glass materials {_names(glass)}: {settings.fresnel} Fresnel and refraction (eq. 2.17, 2.24)"
               + ("; nested media tracked" if settings.nested_dielectrics else "")
               if glass else "no glass material: Fresnel and refraction never evaluated")
    set_effect("glossy", glossy,
               f"glossy materials {_names(glossy)}: microfacet reflection sampled by visible normals, "
               "light samples and MIS weighed by its eval and pdf (engine/materials/glossy.py)"
               if glossy else "no glossy material: no microfacet lobe evaluated")
    set_effect("principled", principled,
               f"Principled BSDF materials {_principled_lobes(principled)}: lobes picked by their albedo "
               "estimates, eval and pdf summed over lobes (engine/materials/principled.py, principled_v1.py)"
               if principled else "no Principled material: no Principled lobes evaluated")
    rough = users(lambda m: scatter_kind(m) == ROUGH_DIFFUSE and (max(m.color) > 0 or m.color_texture is not None))
    _dielectric_effects(set_effect, users)
    plan.cycles_version = tuple(getattr(scene, "cycles_version", (5, 0)))
    version = ".".join(map(str, plan.cycles_version))
    set_effect("rough_diffuse", rough,
               (f"rough diffuse materials {_names(rough)}: energy-preserving Oren-Nayar (Cycles {version} is 4.3+)"
                if plan.cycles_version >= ENERGY_PRESERVING_SINCE else
                f"rough diffuse materials {_names(rough)}: Cycles 3.x's Oren-Nayar, single scattering "
                f"(Cycles {version} is before 4.3)") + ", eval and pdf per light sample (engine/materials/oren_nayar.py)"
               if rough else "no diffuse material with a roughness: every diffuse hit is Lambertian")
    set_effect("mix", mixes,
               f"mixed materials {_mix_lobes(mixes)}: a leaf picked by weight x albedo, eval and pdf "
               "summed over the leaves (engine/materials/mix.py)"
               if mixes else "no Mix or Add Shader of different BSDFs: no closure lists")
    set_effect("emission", emitters,
               f"emitters {_names(emitters)}" if emitters else "no emissive surfaces: no light sampling"
               + (" (background light only)" if max(scene.background) > 0 or getattr(scene, "environment", None)
                  else ""))

    round_lamps = [light for light in [p for p in bulbs if p.radius > 0] + [s for s in suns if s.angle > 0]
                   if light.visible_glossy or light.visible_transmission]
    passing = [m for m in principled if (m.principled or Principled()).alpha < 1.0]   # alpha: delta pass-through
    specular = mirror or glass or passing or users(lambda m: m.kind in (GLASS, REFRACTION, TRANSPARENT))
    # After a glossy bounce the shadow rays own these lamps (a BSDF sample cannot reach them in
    # their MIS, engine/lights/seen.py): glossy rays see them only when no shadow rays run.
    glossy_sees = bool(glossy or users(lambda m: m.kind == TRANSLUCENT)) and settings.shadow_rays == 0
    seen = round_lamps and (specular or glossy_sees) and not report
    set_effect("seen_lamps", seen,
               f"lamps {_names(round_lamps)} seen in mirrors and through glass (Cycles' light visibility)"
               + (" and, without shadow rays, in glossy reflections" if glossy_sees else "")
               if seen else
               "no point/spot light with a radius and no sun with an angle seen by glossy or transmission rays"
               if not round_lamps else
               "no mirror or glass: point, spot and sun lights are reached by shadow rays only" if not specular else
               "report estimator: point, spot and sun lights are reached by shadow rays only")

    env = getattr(scene, "environment", None)
    image = env is not None and env.lighting
    sky = max(scene.background) > 0 or image
    # Under mis a constant colour beside other emitters is found by bounce rays alone, as Cycles disables
    # the light of a background without spatial variation: a light sample spent on it (cosine
    # directions, what a diffuse BSDF sample draws anyway) is one the sun or lamps miss, and that
    # pick's variance is 4-5x Cycles' on sample_blends/normal_map.blend (docs/accuracy.md).
    beside = bool(emitters) and not image and settings.estimator == "mis"     # (solid-angle: no final rays)
    world = bool(sky and lit and settings.shadow_rays > 0 and not report and not beside)
    set_effect("world_light", world,
               ("the environment image is sampled as a light (by its luminance, engine/lights/environment.py)"
                if image else "the background is sampled as a light (cosine directions, shadow rays to infinity)")
               if world else
               "black background" if not sky else "report estimator: the background is found by bounce rays"
               if report else "no diffuse surface or no shadow rays: the background is found by bounce rays"
               if not beside else "a constant background beside other emitters: found by bounce rays (as Cycles)")
    nee = bool(lit and (emitters or world) and settings.shadow_rays > 0)     # hits with a non-delta BSDF
    set_effect("direct_light", nee,
               f"{settings.shadow_rays} shadow ray(s) per {'diffuse or glossy' if glossy or principled else 'diffuse'} hit (eq. 2.11)"
               if nee else
               "no diffuse surface to light" if not lit else "no emitters" if not emitters else
               "0 shadow rays: emitters found by BSDF sampling alone")
    set_effect("solid_angle", nee and not report,
               "lights sampled by solid angle where stable" if nee and not report else
               "report estimator: lights sampled by area (pdf 1/A, eq. 2.11)" if nee else "no direct light")
    n_lights = n_emissive_primitives(scene) + len(lamps) + len(bulbs)
    set_effect("light_tree", nee and not report and n_lights > 1,
               f"{n_lights} lights: picked by a light tree (importance at the shading point)"
               if nee and not report and n_lights > 1 else
               "report estimator: lights picked by power" if nee and report and n_lights > 1 else
               "one light: no light selection" if nee else "no direct light")
    # The background found by bounce rays alone is reached too: the depth limit's final BSDF rays
    # (engine/integrators/path_tracer.py final_rays) must still find it, as when it is a light.
    reachable = bool(surface_emitters) or plan.enabled["area_lights"] or world or (sky and beside)
    mis = nee and settings.estimator == "mis" and reachable
    set_effect("mis", mis,
               "light and cosine BSDF samples weighted by the power heuristic (Veach & Guibas 1995)" if mis else
               f"{settings.estimator} estimator: emission after a diffuse bounce is left to the shadow rays"
               if nee and settings.estimator != "mis" else
               "no emitter that bounce rays can reach" if nee else
               "no direct light: BSDF sampling alone (weight 1)")
    _plan_roulette(plan, settings, set_effect)
    from ..film.passes import TRACED
    features = [n for n in TRACED if n in tuple(getattr(settings, "passes", ()) or ())]
    set_effect("passes", features,
               f"first-hit {', '.join(features)} recorded per sample (engine/film/passes.py)" if features else
               "no albedo, normal or depth pass: no feature tracking")
    colored, glowing = textured_materials(scene)
    set_effect("textures", colored or glowing,
               "; ".join(part for part in (
                   f"image textures (colour, float inputs), node programs or mesh tangents read by {_names(colored)}"
                   if colored else "",
                   f"on the emission of {_names(glowing)} (light samples read the texture)" if glowing else "")
                   if part) + ": texture lookups at triangle hits (UVs interpolated)"
               if colored or glowing else "no image textures: no UVs, no texture lookups")
    _plan_photons(settings, set_effect, users, lit, emitters + (["the world"] if world else []))
    _plan_light_paths(settings, set_effect, users, plan.enabled["photon_caustics"])
    return plan


def _plan_photons(settings, set_effect, users, receivers, emitters) -> None:
    """The caustic photon pass (engine/integrators/photons/): on where `caustics_method` asks for it
    and the scene has specular surfaces (a BSDF with a delta lobe), non-specular receivers and lights."""
    from ..materials.protocol import BSDFFlags
    from ..materials.table import SCATTERING
    delta_kinds = {kind for kind, bsdf in SCATTERING if bsdf.flags & BSDFFlags.DELTA}
    specular = users(lambda m: scatter_kind(m) in delta_kinds)
    method = settings.caustics_method
    toggled = not (settings.caustics_reflective and settings.caustics_refractive)
    report = method == "auto" and settings.estimator == "report"     # the report's estimator, kept as it is
    # Cycles' clamp cuts the caustic paths' rare large samples, which a photon map would keep: auto
    # leaves clamped renders to the path tracer, whose clamp is Cycles' (docs/photons.md).
    clamped = method == "auto" and (settings.clamp_direct > 0 or settings.clamp_indirect > 0)
    on = (method != "path" and not report and not clamped and bool(specular) and bool(receivers) and bool(emitters)
          and not toggled)
    set_effect("photon_caustics", on,
               f"caustics_method {method}: {settings.photons_per_pass or 'auto'} photons per pass aimed at the specular "
               f"{_names(specular)}, gathered on the non-specular {_names(receivers)} (radius "
               f"{'auto' if settings.photon_radius <= 0 else format(settings.photon_radius, 'g')}, alpha "
               f"{settings.photon_alpha:.3g}); the path tracer leaves L S+ D paths to them" if on else
               "caustics_method path: caustics by path tracing alone" if method == "path" else
               "caustics_method auto, report estimator: caustics by path tracing, as the report computes them"
               if report else
               "caustics_method auto, clamping on: caustics by path tracing, clamped as Cycles clamps them"
               if clamped else
               f"caustics_method {method}, but Cycles' caustics options leave caustics out" if toggled else
               f"caustics_method {method}, but no specular surface (mirror, smooth glass, pass-through)"
               if not specular else
               f"caustics_method {method}, but no non-specular surface to receive caustics" if not receivers else
               f"caustics_method {method}, but no lights")


def _plan_light_paths(settings, set_effect, users, photons=False) -> None:
    """Cycles' Light Paths options (engine/integrators/light_paths.py): on where they change the image.
    photons: whether the caustic photon pass runs (Filter Glossy then leaves delta lobes sharp)."""
    kind_of = scatter_kind
    mirror = users(lambda m: m.kind == MIRROR)
    glass = users(lambda m: m.kind in (GLASS, REFRACTION))
    glossy = users(lambda m: m.kind == GLOSSY)
    principled = users(lambda m: kind_of(m) == PRINCIPLED)         # v2 (the v1 closures keep theirs)
    principled_v1 = users(lambda m: kind_of(m) == PRINCIPLED_V1)   # Filter Glossy only: Cycles 3.4's bsdf_blur
    passing = users(lambda m: m.kind == TRANSPARENT or (kind_of(m) == PRINCIPLED
                                                          and getattr(m.principled, "alpha", 1.0) < 1.0))
    depth = settings.max_depth
    limits = {"diffuse": settings.diffuse_bounces, "glossy": settings.glossy_bounces,
              "transmission": settings.transmission_bounces}
    below = {kind: n for kind, n in limits.items() if n < depth}
    if passing and settings.transparent_bounces <= depth:   # its last pass-through only finds emission
        below[f"transparent (through {_names(passing)})"] = settings.transparent_bounces
    set_effect("bounce_limits", below,
               "bounces counted per type: " + ", ".join(f"{k} at most {n}" for k, n in below.items())
               + f" (of {depth} in all); a bounce past its type's limit only finds emission"
               if below else f"no bounce type limited below the total of {depth}")
    direct, indirect = settings.clamp_direct, settings.clamp_indirect
    set_effect("clamp", direct > 0 or indirect > 0,
               "each contribution's mean over R, G, B clamped: " + ", ".join(
                   part for part in (f"direct to {direct:g}" if direct > 0 else "",
                                     f"indirect to {indirect:g}" if indirect > 0 else "") if part)
               if direct > 0 or indirect > 0 else "no clamping (Clamp Direct and Indirect 0)")
    lobes = glossy + principled + principled_v1 + users(lambda m: kind_of(m) in (ROUGH_GLASS, ROUGH_REFRACTION))
    # Delta lobes Cycles blurs (engine/integrators/delta_blur.py): mirrors, smooth glass and refraction
    # but Blender 3.x's Sharp closures, which its bsdf_blur leaves alone.  The caustic photons carry
    # the light of sharp specular chains (L S+ D): with them the path tracer keeps its delta lobes sharp,
    # else light through a blurred lobe would count twice.
    blurrable = users(lambda m: kind_of(m) in BLURRED_ROWS and not m.sharp_closure)
    blurred = [] if photons else blurrable
    blur = settings.filter_glossy > 0 and bool(lobes or blurred)
    delta = [m for m in mirror + glass if m not in lobes + blurred]
    sharp = (f" (the caustic photons' specular {_names(blurrable)} stay sharp)" if photons and blurrable else "") + (
        f" ({_names([m for m in delta if m not in blurrable])}: Blender 3.x's Sharp closures, left sharp as"
        " Cycles 3.4)" if [m for m in delta if m not in blurrable] else "")
    set_effect("filter_glossy", blur,
               f"Filter Glossy {settings.filter_glossy:g}: microfacet lobes of {_names(lobes + blurred)} widened after "
               "blurry bounces (alpha >= sqrt(1 - min pdf / filter) / 2"
               + (f"; {_names(blurred)} as GGX lobes of that alpha" if blurred else "") + ")" + sharp if blur else
               "Filter Glossy 0: no roughness widened" if settings.filter_glossy <= 0 else
               "no microfacet material: Filter Glossy widens nothing" + sharp)
    reflective = [] if settings.caustics_reflective else mirror + glass + glossy + principled
    refractive = [] if settings.caustics_refractive else glass       # the Glass and Refraction BSDFs
    left_out = reflective + [m for m in refractive if m not in reflective]
    off = [name for name, on in (("reflective", settings.caustics_reflective),
                                 ("refractive", settings.caustics_refractive)) if not on]
    set_effect("caustics", left_out,
               f"{' and '.join(off)} caustics off: after a diffuse bounce the "
               f"{' and '.join(('glossy and mirror reflection',) * bool(reflective) + ('refraction',) * bool(refractive))}"
               f" of {_names(left_out)} left out" if left_out else
               "caustics on (reflective and refractive)" if not off else
               f"{' and '.join(off)} caustics off, but no material has such a lobe")


# The material models after Cycles' closures: scenes that use any of them take Cycles' order of
# Russian roulette (deferred_roulette); scenes of the report's materials keep the report's.
CYCLES_MODELS = ("glossy", "principled", "rough_diffuse", "mix", "rough_glass", "refraction", "transparent",
                 "translucent")


def _plan_roulette(plan, settings, set_effect) -> None:
    """Russian roulette as Cycles orders it (kernel/integrator/intersect_closest.h and shade_surface.h):
    the ray is traced whatever the roulette says, the emission and background it reaches count with
    the throughput before the roulette, and only what follows (the next vertex's light samples and
    bounces) is ended or divided by the survival probability (engine/integrators/path_tracer.py
    `deferred_roulette`)."""
    models = [name for name in CYCLES_MODELS if plan.enabled.get(name)]
    on = bool(models and settings.russian_roulette and settings.estimator != "report")
    set_effect("deferred_roulette", on,
               f"{', '.join(models)} materials: Russian roulette as Cycles', after the emission its ray "
               "reaches (never rouletted), survival min(1, sqrt(max throughput))" if on else
               "Russian roulette off" if not settings.russian_roulette else
               "report estimator: Russian roulette before the ray (report 2.4)" if settings.estimator == "report"
               else "only diffuse, mirror and glass materials: Russian roulette before the ray (report 2.4)")


def _dielectric_effects(set_effect, users) -> None:
    """The rough glass and refraction rows and the Refraction, Transparent and Translucent BSDFs
    (engine/materials/dielectric.py, transparent.py, translucent.py)."""
    rough = users(lambda m: scatter_kind(m) == ROUGH_GLASS)
    set_effect("rough_glass", rough,
               f"rough glass materials {_names(rough)}: microfacet reflection and refraction (Walter et al. "
               "2007) sampled by visible normals, Fresnel picks the lobe; light samples from both sides"
               + ("; multiscatter GGX compensated by glass albedo tables" if any(m.distribution == "multi_ggx"
                                                                                 for m in rough) else "")
               if rough else "no glass with a roughness: every glass surface is smooth (delta)")
    refraction = users(lambda m: m.kind == REFRACTION)
    rough_refraction = [m for m in refraction if scatter_kind(m) == ROUGH_REFRACTION]
    set_effect("refraction", refraction,
               f"Refraction BSDF materials {_names(refraction)}: the refracted lobe alone (no Fresnel), "
               + (f"rough in {_names(rough_refraction)} (light samples from the far side)" if rough_refraction
                  else "smooth (delta)")
               if refraction else "no Refraction BSDF")
    transparent = users(lambda m: m.kind == TRANSPARENT and max(m.color) > 0)
    set_effect("transparent", transparent,
               f"Transparent BSDF materials {_names(transparent)}: rays pass straight through with the "
               "colour as weight; they block shadow rays (light behind them found by the passing paths)"
               if transparent else "no Transparent BSDF")
    translucent = users(lambda m: m.kind == TRANSLUCENT and (max(m.color) > 0 or m.color_texture is not None))
    set_effect("translucent", translucent,
               f"Translucent BSDF materials {_names(translucent)}: diffuse transmission, cosine-sampled on "
               "the far side, light samples from the far side"
               if translucent else "no Translucent BSDF")


def _principled_lobes(materials) -> str:
    """Each Principled material's name and the lobes it runs (engine/materials/principled.py)."""
    parts = []
    for m in materials[:3]:
        p = m.principled or Principled()
        if isinstance(p, PrincipledV1):
            parts.append(f"'{m.name}' {_principled_v1_lobes(m, p)}")
            continue
        lobes = ["metallic (GGX, F82 tint)"] if p.metallic > WEIGHT_CUTOFF else []
        if p.transmission_weight > WEIGHT_CUTOFF and 1.0 - p.metallic > WEIGHT_CUTOFF:
            lobes.append("transmission (GGX glass" + (", multiscatter" if m.multiscatter else "")
                         + "; light samples from both sides)")
        if (1.0 - p.metallic) * (1.0 - p.transmission_weight) > WEIGHT_CUTOFF:
            if specular_eta_f0(max(m.ior, 1e-5), max(p.specular_ior_level, 0.0))[0] != 1.0:
                lobes.append("specular (GGX)")
            rough = getattr(m, "diffuse_roughness", 0.0) >= DIFFUSE_ROUGHNESS_CUTOFF
            lobes.append("diffuse (Oren-Nayar)" if rough else "diffuse (Lambert)")
        over = [name for name, on in (("alpha pass-through", p.alpha < 1.0), ("sheen (microfiber)", p.sheen_weight > WEIGHT_CUTOFF),
                                      ("coat (GGX)", p.coat_weight > WEIGHT_CUTOFF)) if on]
        lobes = over + lobes
        parts.append(f"'{m.name}' {' + '.join(lobes)}")
    more = f" and {len(materials) - 3} more" if len(materials) > 3 else ""
    return ", ".join(parts) + more


def _mix_lobes(materials) -> str:
    """Each mixed material's name and its leaves: kind (scatter row) x weight factors."""
    def weight(leaf):
        parts = [f"{f.constant():g}" if f.is_constant else
                 ("1 - " if f.invert else "") + (f"{f.kind}({f.output})" if f.kind == "layer_weight" else f.kind)
                 for f in leaf.factors]
        return " x ".join(parts) or "1"
    parts = [f"'{m.name}' " + " + ".join(f"{scatter_kind(leaf.material)} [{weight(leaf)}]" for leaf in m.mix.leaves)
             for m in materials[:3]]
    more = f" and {len(materials) - 3} more" if len(materials) > 3 else ""
    return ", ".join(parts) + more


def _principled_v1_lobes(m, p) -> str:
    """The closures Blender 3.4's Principled BSDF runs (engine/materials/principled_v1.py)."""
    lobes = []
    glass = p.transmission * (1.0 - p.metallic)
    if (1.0 - p.metallic) * (1.0 - p.transmission) > WEIGHT_CUTOFF:
        lobes.append("diffuse (Burley, v1)")
        if p.sheen > WEIGHT_CUTOFF:
            lobes.append("sheen")
    if p.specular > WEIGHT_CUTOFF or p.metallic > WEIGHT_CUTOFF:
        multi = m.multiscatter and m.roughness > SINGLE_SCATTER_ROUGHNESS
        lobes.append("specular (GGX, multiscatter by energy compensation)" if multi else "specular (GGX)")
    if p.clearcoat > WEIGHT_CUTOFF:
        lobes.append("clearcoat (GTR1)")
    if glass > WEIGHT_CUTOFF:
        multi = m.multiscatter and m.roughness > GLASS_SINGLE_SCATTER_ROUGHNESS
        lobes.append("glass (multiscatter GGX glass, approximated; light samples from both sides)" if multi else
                     "glass (GGX reflection + GGX refraction; light samples from both sides)")
    return " + ".join(lobes)


def n_emissive_primitives(scene) -> int:
    emissive = np.array([m.is_emissive for m in scene.materials])
    n = sum(int(emissive[np.asarray(m.material_ids, dtype=np.int64)].sum()) for m in scene.meshes
            if len(m.triangles))
    return n + sum(bool(emissive[q.material_id]) for q in scene.quads) + \
        sum(bool(emissive[s.material_id]) for s in scene.spheres)
