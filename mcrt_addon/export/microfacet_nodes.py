"""Microfacet shader nodes -> the glossy and principled material kinds (engine/scene/model.py).

The node vocabulary of the running Blender (bpy.app.version; node ids and sockets as that Blender
names them):

* 3.4: Glossy BSDF (ShaderNodeBsdfGlossy: Color, Roughness; distribution SHARP / BECKMANN / GGX /
  ASHIKHMIN_SHIRLEY / MULTI_GGX) and Anisotropic BSDF (ShaderNodeBsdfAnisotropic: also Anisotropy,
  default 0.5, Rotation and Tangent); Principled BSDF v1 (materials.py keeps it Lambertian).
* 4.0+ (also 5.0): one Glossy BSDF, ShaderNodeBsdfAnisotropic (ShaderNodeBsdfGlossy creates it):
  Color, Roughness, Anisotropy (default 0), Rotation, Tangent; distribution BECKMANN / GGX /
  ASHIKHMIN_SHIRLEY / MULTI_GGX; Principled BSDF v2 (Base Color, Metallic, Roughness, IOR,
  Specular IOR Level, Specular Tint (a colour), Anisotropic, Anisotropic Rotation, Tangent, Coat
  Weight / Roughness / IOR / Tint, Sheen Weight / Roughness / Tint, Alpha, Emission Color x
  Emission Strength (times Alpha, as Cycles), ...; Coat Normal, Thin Film and Subsurface (rendered
  as diffuse) are warned by socket).
* 4.3+: Metallic BSDF (ShaderNodeBsdfMetallic): Base Color and Edge Tint (fresnel_type F82) or IOR
  and Extinction (PHYSICAL_CONDUCTOR), Roughness, Anisotropy, Rotation, Tangent, Thin Film;
  distribution BECKMANN / GGX / MULTI_GGX; the Principled BSDF's Diffuse Roughness.

Distributions: GGX and BECKMANN as named, MULTI_GGX is GGX with `multiscatter` (energy compensation),
ASHIKHMIN_SHIRLEY is exported as GGX with a warning.  The Glossy BSDF at roughness 0 (or SHARP) is the
perfect mirror it always was (unless an image texture drives the roughness).

Image textures (straight or through Separate RGB / Color, images.py float_image) on Roughness,
Metallic and the Principled BSDF's Diffuse Roughness are the material's input textures; other
links to float inputs are warned about (the unlinked value is used).

Tangent of an anisotropic material (Cycles' svm closure.h takes the Tangent input; unlinked, the
Geometry node's Tangent, primitive_tangent: radial about the object's Z axis in its generated
coordinates): unlinked -> tangent_source "radial"; a Tangent node -> "radial" (axis Z) or "uv" (its
UV map's MikkTSpace tangent); the mesh exporter computes the corner tangents (mesh.py
corner_tangents).  Material.tangent, the object's local X axis, is the fallback where a hit has none.
"""
import numpy as np

from .util import linked_from, socket

DISTRIBUTIONS = {"GGX": ("ggx", False), "MULTI_GGX": ("ggx", True), "BECKMANN": ("beckmann", False)}
PRINCIPLED_V2 = (4, 0)
# Principled v2 inputs not modelled: warned (naming the socket) when above their "off" value.
PRINCIPLED_UNMODELLED = ("Thin Film Thickness",)


def _clamp(value, low, high):
    return min(max(float(value), low), high)


def _clamp01(rgb):
    return tuple(_clamp(c, 0.0, 1.0) for c in rgb)


def distribution(table, mat, node):
    """(distribution, multiscatter) of the node's distribution menu."""
    name = getattr(node, "distribution", "GGX")
    if name in DISTRIBUTIONS:
        return DISTRIBUTIONS[name]
    table.warn(mat, node, f"distribution {name} is not modelled; rendered as GGX")
    return "ggx", False


def tangent_source(table, mat, node):
    """(tangent_source, tangent_uv_map) of an anisotropic node's Tangent input (see the module)."""
    sock = socket(node, "Tangent")
    source = linked_from(sock) if sock is not None else None
    if source is None:
        return "radial", ""
    if source.bl_idname == "ShaderNodeTangent":
        if source.direction_type == "UV_MAP":
            return "uv", source.uv_map
        if source.axis != "Z":
            table.warn(mat, node, f"Tangent node '{source.name}': radial about the {source.axis} axis is not "
                                  "modelled; radial about Z is used")
        return "radial", ""
    table.warn(mat, node, f"input 'Tangent' is linked to '{source.name}' ({source.bl_idname}), which is not "
                          "modelled; Cycles' default tangent (radial about the object's Z axis) is used")
    return "radial", ""


def anisotropy_fields(table, mat, node, anisotropy_name, rotation_name):
    """anisotropy, rotation and tangent of a node: the mesh's tangents (tangent_source), the object's
    local X axis where a hit has none."""
    anisotropy = _clamp(table.read_float(mat, node, anisotropy_name, default=0.0), -1.0, 1.0)
    rotation = table.read_float(mat, node, rotation_name, default=0.0)
    fields = dict(anisotropy=anisotropy, rotation=rotation, tangent=table.object_x)
    if anisotropy != 0.0:
        table.used_object_tangent = True
        fields["tangent_source"], fields["tangent_uv_map"] = tangent_source(table, mat, node)
    return fields


def glossy(table, mat, node):
    """Glossy BSDF (3.4's Glossy and Anisotropic, 4.0+'s Glossy): fresnel 'none', the colour a tint."""
    color = _clamp01(table.read_color(mat, node, "Color"))
    roughness = table.read_float(mat, node, "Roughness", default=0.5, role="roughness")
    sharp = getattr(node, "distribution", "GGX") == "SHARP"
    if sharp or (roughness <= 0.0 and "roughness" not in table._slots):
        table._slots.pop("roughness", None)
        # the distribution Filter Glossy blurs a GGX / Beckmann mirror with; Sharp stays sharp (3.x)
        return table.Material(name=mat.name, kind=table.MIRROR, color=color, sharp_closure=sharp,
                              distribution=DISTRIBUTIONS.get(getattr(node, "distribution", "GGX"), ("ggx",))[0])
    dist, multiscatter = distribution(table, mat, node)
    return table.Material(name=mat.name, kind=table.GLOSSY, color=color, roughness=min(roughness, 1.0),
                          distribution=dist, multiscatter=multiscatter, fresnel="none",
                          **anisotropy_fields(table, mat, node, "Anisotropy", "Rotation"))


def metallic(table, mat, node):
    """Metallic BSDF (4.3+): fresnel 'f82' (Base Color = F0, Edge Tint) or 'conductor' (IOR, Extinction)."""
    roughness = _clamp(table.read_float(mat, node, "Roughness", default=0.5, role="roughness"), 0.0, 1.0)
    dist, multiscatter = distribution(table, mat, node)
    fields = dict(name=mat.name, kind=table.GLOSSY, roughness=roughness, distribution=dist,
                  multiscatter=multiscatter, **anisotropy_fields(table, mat, node, "Anisotropy", "Rotation"))
    thin_film = table.read_float(mat, node, "Thin Film Thickness", default=0.0)
    if thin_film > 0.0:
        table.warn(mat, node, f"input 'Thin Film Thickness' {thin_film:g} is not modelled")
    if getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
        n = tuple(max(c, 0.0) for c in table.read_color(mat, node, "IOR", role=None))
        k = tuple(max(c, 0.0) for c in table.read_color(mat, node, "Extinction", role=None))
        # the colour is not used by conductors (engine/materials/glossy.py); white keeps it scattering
        return table.Material(color=(1.0, 1.0, 1.0), fresnel="conductor", conductor_ior=n, conductor_k=k,
                              **fields)
    color = _clamp01(table.read_color(mat, node, "Base Color"))
    edge_tint = _clamp01(table.read_color(mat, node, "Edge Tint", role=None))
    return table.Material(color=color, fresnel="f82", edge_tint=edge_tint, **fields)


def principled(table, mat, node):
    """Principled BSDF v2 (4.0+) -> the principled kind; 'Transmission Weight' is its rough glass closure
    (engine/materials/principled_glass.py)."""
    base = _clamp01(table.read_color(mat, node, "Base Color"))
    emission = table.principled_emission(mat, node)
    roughness = _clamp(table.read_float(mat, node, "Roughness", default=0.5, role="roughness"), 0.0, 1.0)
    ior = max(table.read_float(mat, node, "IOR", default=1.5), 1e-3)
    for name in PRINCIPLED_UNMODELLED:
        value = table.read_float(mat, node, name, default=0.0)
        if value > 0:
            table.warn(mat, node, f"input '{name}' {value:g} is not modelled")
    subsurface = table.read_float(mat, node, "Subsurface Weight", default=0.0)
    if subsurface > 0:
        table.warn(mat, node, f"input 'Subsurface Weight' {subsurface:g} is rendered as diffuse "
                              "(subsurface scattering is not modelled)")
    transmission = table.read_float(mat, node, "Transmission Weight", default=0.0)
    dist, multiscatter = distribution(table, mat, node)
    layers = principled_layers(table, mat, node, transmission, emission)
    emission = tuple(c * layers["alpha"] for c in emission)       # Cycles: the emission closure's weight is alpha
    slot = table._slots.get("emission")
    if slot is not None and layers["alpha"] < 1:
        slot.scale = tuple(c * layers["alpha"] for c in slot.scale)
    settings = table.Principled(
        metallic=_clamp(table.read_float(mat, node, "Metallic", default=0.0, role="metallic"), 0.0, 1.0),
        specular_ior_level=max(table.read_float(mat, node, "Specular IOR Level", default=0.5), 0.0),
        specular_tint=tuple(max(c, 0.0) for c in table.read_color(mat, node, "Specular Tint",
                                                                   default=(1.0, 1.0, 1.0), role=None)),
        **layers)
    diffuse_roughness = _clamp(table.read_float(mat, node, "Diffuse Roughness", default=0.0, role="diffuse_roughness"),
                               0.0, 1.0)
    return table.Material(name=mat.name, kind=table.PRINCIPLED, color=base, emission=emission, ior=ior,
                          roughness=roughness, distribution=dist, multiscatter=multiscatter,
                          diffuse_roughness=diffuse_roughness, principled=settings,
                          **anisotropy_fields(table, mat, node, "Anisotropic", "Anisotropic Rotation"))


def principled_layers(table, mat, node, transmission, emission):
    """The layers over the Principled base (engine/scene/model.py Principled: coat, sheen, alpha,
    transmission_weight), clamped as Cycles' closure.h; warnings for what is not modelled of them."""
    def colour(name):
        return tuple(max(c, 0.0) for c in table.read_color(mat, node, name, default=(1.0, 1.0, 1.0), role=None))
    def number(name, default):      # sockets hold float32: their shortest decimal (0.03, not 0.029999999)
        return float(str(np.float32(table.read_float(mat, node, name, default=default))))
    layers = dict(
        coat_weight=max(number("Coat Weight", 0.0), 0.0),
        coat_roughness=_clamp(number("Coat Roughness", 0.03), 0.0, 1.0),
        coat_ior=max(number("Coat IOR", 1.5), 1.0),
        coat_tint=colour("Coat Tint"),
        sheen_weight=max(number("Sheen Weight", 0.0), 0.0),
        sheen_roughness=_clamp(number("Sheen Roughness", 0.5), 0.0, 1.0),
        sheen_tint=colour("Sheen Tint"),
        alpha=_clamp(number("Alpha", 1.0), 0.0, 1.0),
        transmission_weight=_clamp(transmission, 0.0, 1.0))
    coat_normal = socket(node, "Coat Normal")
    if layers["coat_weight"] > 0 and coat_normal is not None and coat_normal.is_linked:
        table.warn(mat, node, "input 'Coat Normal' is linked (not modelled): the coat uses the surface's normal")
    if layers["alpha"] < 1:
        table.warn(mat, node, f"input 'Alpha' {layers['alpha']:g}: rays pass straight through with probability "
                              "1 - alpha, but shadow rays stop at the surface: point and spot lamps without a radius "
                              "and suns without an angle cast its full shadow (Cycles lets 1 - alpha of their "
                              "light through), and the light behind it is noisier")
    covered = [name for name, key in (("coat", "coat_weight"), ("sheen", "sheen_weight")) if layers[key] > 0]
    if covered and (max(emission) > 0 or "emission" in table._slots):
        f0 = ((layers["coat_ior"] - 1) / (layers["coat_ior"] + 1)) ** 2 * min(layers["coat_weight"], 1.0)
        table.warn(mat, node, f"the emission is not darkened by the {' and '.join(covered)} (Cycles darkens it by "
                              f"their albedo at each view angle{f', the coat by {f0:.3f} at normal incidence' if f0 else ''})")
    return layers
