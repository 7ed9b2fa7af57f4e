"""Dielectric shader nodes -> the glass, refraction, transparent and translucent material kinds
(engine/scene/model.py; the BSDFs in engine/materials/dielectric.py, transparent.py, translucent.py).

The node vocabulary of the running Blender (bpy.app.version):

* Glass BSDF (ShaderNodeBsdfGlass): Color, Roughness, IOR, Normal; 3.4: distribution SHARP /
  BECKMANN (the default) / GGX / MULTI_GGX, IOR default 1.45; 4.0+ (also 5.0): BECKMANN / GGX /
  MULTI_GGX (the default), IOR 1.5, and in 5.0 Thin Film Thickness / Thin Film IOR.
* Refraction BSDF (ShaderNodeBsdfRefraction): Color, Roughness, IOR (1.45), Normal; distribution
  BECKMANN (the default) / GGX, and SHARP in 3.4.
* Transparent BSDF (ShaderNodeBsdfTransparent): Color.  Translucent BSDF (ShaderNodeBsdfTranslucent):
  Color, Normal.

An Image Texture on Roughness (straight or through Separate RGB / Color) is the material's roughness
texture (rough glass per hit).  Roughness 0 (or SHARP) is the smooth (delta) glass or refraction it always was; the roughness is set
explicitly on every material, since the scene model's default for these kinds is 0.  MULTI_GGX is
Cycles 4.x's energy compensation by albedo scaling; Blender 3.x's MULTI_GGX glass (Heitz's random
walk) is approximated by it (warned).  Linked Normal inputs and thin films are warned about.
"""
from .util import socket

GLASS_DISTRIBUTIONS = {"GGX": "ggx", "MULTI_GGX": "multi_ggx", "BECKMANN": "beckmann", "SHARP": "ggx"}
RANDOM_WALK_BEFORE = (4, 0)      # Blender 3.x's Multiscatter GGX glass


def _clamp01(rgb):
    return tuple(min(max(float(c), 0.0), 1.0) for c in rgb)


def _normal_warning(table, mat, node):
    sock = socket(node, "Normal")
    if sock is not None and sock.is_linked:
        table.warn(mat, node, "input 'Normal' is linked (normal inputs are not modelled); the surface normal is used")


def _dielectric(table, mat, node, kind, ior_default):
    color = _clamp01(table.read_color(mat, node, "Color", default=(1.0, 1.0, 1.0)))
    roughness = min(max(table.read_float(mat, node, "Roughness", default=0.0, role="roughness"), 0.0), 1.0)
    ior = max(table.read_float(mat, node, "IOR", default=ior_default), 1e-3)
    name = getattr(node, "distribution", "BECKMANN")
    if name == "SHARP":
        roughness = 0.0
        table._slots.pop("roughness", None)
    distribution = GLASS_DISTRIBUTIONS.get(name)
    if distribution is None:
        table.warn(mat, node, f"distribution {name} is not modelled; rendered as GGX")
        distribution = "ggx"
    if distribution == "multi_ggx" and roughness > 0 and table.version < RANDOM_WALK_BEFORE:
        table.warn(mat, node, "Multiscatter GGX of Blender 3.x (a random walk) is approximated by 4.x's "
                              "energy compensation (albedo scaling)")
    thin_film = table.read_float(mat, node, "Thin Film Thickness", default=0.0)
    if thin_film > 0.0:
        table.warn(mat, node, f"input 'Thin Film Thickness' {thin_film:g} is not modelled")
    _normal_warning(table, mat, node)
    return table.Material(name=mat.name, kind=kind, color=color, ior=ior, roughness=roughness,
                          distribution=distribution, sharp_closure=name == "SHARP")


def glass(table, mat, node):
    """Glass BSDF: smooth (roughness 0) or rough glass with the node's distribution."""
    return _dielectric(table, mat, node, table.GLASS, 1.45 if table.version < (4, 0) else 1.5)


def refraction(table, mat, node):
    """Refraction BSDF: the refracted lobe alone (no Fresnel), smooth or rough."""
    return _dielectric(table, mat, node, table.REFRACTION, 1.45)


def transparent(table, mat, node):
    """Transparent BSDF: straight through with the colour (shadow rays are blocked: docs/materials.md)."""
    color = _clamp01(table.read_color(mat, node, "Color", default=(1.0, 1.0, 1.0), role=None))
    table.warn(mat, node, "transparent shadows are not modelled: shadow rays stop at it, light behind it "
                          "comes from the paths through it (point lights without a radius are not seen)")
    return table.Material(name=mat.name, kind=table.TRANSPARENT, color=color)


def translucent(table, mat, node):
    """Translucent BSDF: diffuse transmission with the colour."""
    color = _clamp01(table.read_color(mat, node, "Color"))
    _normal_warning(table, mat, node)
    return table.Material(name=mat.name, kind=table.TRANSLUCENT, color=color)
