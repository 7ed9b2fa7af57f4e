"""Add Shader and Mix Shader nodes -> one tracer material, as Cycles' closure list.

Cycles sums a material's closures, each times a weight: an Add Shader passes weight 1 to both
inputs, a Mix Shader 1 - fac and fac (fac clamped to [0, 1]); nested nodes multiply the weights.
A tracer material (engine/scene/model.py) holds one BSDF and an emission, so the graph is folded:

* Emission adds: each side's emission times its weight.  An Emission beside a BSDF is that BSDF's
  material, emitting (the "Diffuse + Emission" emitters of scenes converted from other renderers).
* A side without a BSDF (an Emission, an unconnected socket) leaves the other side's BSDF; that
  BSDF's weight scales its colour.
* Two BSDFs of one kind with the same non-colour parameters add their weighted colours.
* A Mix Shader's factor 0 or 1 is that side alone (the other side is not read).

Both rest on a closure being linear in its colour, which holds for diffuse (Lambert, and the
Oren-Nayar of Cycles 3.x), mirror, glass (not multiscatter GGX rough glass), refraction, transparent,
translucent and glossy with fresnel 'none' (the Glossy BSDF's tint);
not for Cycles 4.3+'s energy-preserving Oren-Nayar (its multiple-scatter term is quadratic in the
colour), the Metallic BSDF (colour = F0) or the Principled BSDF.  Other combinations are warned
(naming material and node) and the side of larger weight is kept.
"""
import dataclasses

from .util import linked_from, socket

# The Oren-Nayar closure is linear in its colour below this Cycles version (3.x's single-scatter lobe).
ENERGY_PRESERVING_OREN_NAYAR = (4, 3)
# Fields that are a closure's weight, not its parameters.
WEIGHT_FIELDS = ("name", "color", "emission", "color_texture", "emission_texture")


def shader_inputs(node):
    """The node's two shader sockets (by type: Blender names both 'Shader')."""
    return [s for s in node.inputs if s.bl_idname == "NodeSocketShader"][:2]


def mix_factor(table, mat, node):
    """The Mix Shader's factor clamped to [0, 1] as Cycles does (a linked factor: warned, unlinked value)."""
    if socket(node, "Factor", "Fac") is None:
        return 0.5
    return min(max(table.read_float(mat, node, "Factor", "Fac", default=0.5), 0.0), 1.0)


def add_shader(table, mat, node):
    return combine(table, mat, node, [(1.0, *table.side(mat, linked_from(s))) for s in shader_inputs(node)])


def mix_shader(table, mat, node):
    fac = mix_factor(table, mat, node)
    first, second = shader_inputs(node)
    if fac <= 0.0 or fac >= 1.0:
        return table.shader(mat, linked_from(second if fac >= 1.0 else first))
    return combine(table, mat, node, [(1.0 - fac, *table.side(mat, linked_from(first))),
                                      (fac, *table.side(mat, linked_from(second)))])


def has_bsdf(table, material, slots):
    return not (material.kind == table.DIFFUSE and max(material.color) == 0.0 and "color" not in slots)


def colour_is_weight(table, material):
    """Whether the closure is linear in `material.color` (module docstring)."""
    if material.kind in (table.MIRROR, table.GLASS, table.REFRACTION, table.TRANSPARENT, table.TRANSLUCENT):
        return not (material.roughness and material.distribution == "multi_ggx")   # its compensation: not linear
    if material.kind == table.DIFFUSE:
        return material.diffuse_roughness == 0.0 or table.version < ENERGY_PRESERVING_OREN_NAYAR
    return material.kind == table.GLOSSY and material.fresnel == "none"


def parameters(material):
    return {f.name: getattr(material, f.name) for f in dataclasses.fields(material)
            if f.name not in WEIGHT_FIELDS}


def scaled(rgb, w):
    return tuple(w * c for c in rgb)


def scaled_slot(slot, w):
    return dataclasses.replace(slot, scale=scaled(slot.scale, w))


def combine(table, mat, node, sides):
    """One material for the weighted sum of ``sides`` [(weight, material, slots)]; the textures go
    to ``table._slots``."""
    emission = emission_of(table, mat, node, sides)
    bsdfs = [(w, m, slots) for w, m, slots in sides if w > 0.0 and has_bsdf(table, m, slots)]
    if not bsdfs:
        return table.Material(name=mat.name, kind=table.DIFFUSE, color=(0.0, 0.0, 0.0), emission=emission)
    if len(bsdfs) == 2 and same_closure(table, bsdfs[0][1], bsdfs[1][1]) and "color" not in bsdfs[0][2] \
            and "color" not in bsdfs[1][2]:
        color = tuple(bsdfs[0][0] * a + bsdfs[1][0] * b for a, b in zip(bsdfs[0][1].color, bsdfs[1][1].color))
        return dataclasses.replace(bsdfs[0][1], name=mat.name, color=color, emission=emission)
    if len(bsdfs) == 2:
        table.warn(mat, node, f"a mix of {describe(bsdfs[0][1])} and {describe(bsdfs[1][1])} is not "
                              f"modelled; the side of larger weight is rendered")
        bsdfs = [max(bsdfs, key=lambda side: side[0])]
        w, material, slots = bsdfs[0]
        w = 1.0          # the kept side stands for both
    else:
        w, material, slots = bsdfs[0]
    if "color" in slots:
        table._slots["color"] = scaled_slot(slots["color"], w) if w != 1.0 else slots["color"]
    if w != 1.0 and not colour_is_weight(table, material):
        table.warn(mat, node, f"the weight {w:g} of {describe(material)} is not modelled (rendered at weight 1)")
        w = 1.0
    return dataclasses.replace(material, name=mat.name, color=scaled(material.color, w), emission=emission)


def same_closure(table, a, b):
    return a.kind == b.kind and colour_is_weight(table, a) and parameters(a) == parameters(b)


def describe(material):
    return f"{material.kind}" + (f" (fresnel {material.fresnel})" if material.kind == "glossy" else "")


def emission_of(table, mat, node, sides):
    """The weighted sum of the sides' emission; one textured emission is kept as the slot."""
    textured = [(w, slots["emission"]) for w, m, slots in sides if w > 0.0 and "emission" in slots]
    if len(textured) > 1 or (textured and any(w > 0.0 and max(m.emission) > 0 and "emission" not in slots
                                              for w, m, slots in sides)):
        table.warn(mat, node, "more than one emission beside a textured one is not modelled; "
                              "only the textured emission is rendered")
        sides = [side for side in sides if "emission" in side[2]][:1]
        textured = textured[:1]
    if textured:
        w, slot = textured[0]
        table._slots["emission"] = scaled_slot(slot, w) if w != 1.0 else slot
    total = [0.0, 0.0, 0.0]
    for w, m, _ in sides:
        for c in range(3):
            total[c] += w * m.emission[c]
    return tuple(total)
