"""Add Shader and Mix Shader nodes -> one tracer material, as Cycles' closure list.

Cycles sums a material's closures, each times a weight: an Add Shader passes weight 1 to both
inputs (the sum may reflect more than it receives: Cycles does not renormalise, nor do we), a Mix
Shader 1 - fac and fac (fac clamped to [0, 1]); nested nodes multiply the weights.  The result:

* Emission adds: each side's emission times its weight, into the material's own emission.  An
  Emission beside a BSDF is that BSDF's material, emitting (the "Diffuse + Emission" emitters of
  scenes converted from other renderers).  An emission weighted by a Fresnel, Layer Weight or
  texture factor is view- or position-dependent in Cycles; it is weighted here by the factor at
  normal incidence (Fresnel: F0, Layer Weight Facing: 0) or, for a texture, by the Mix node's
  unlinked factor (warned).
* With constant weights, today's folds are kept, bit for bit: one BSDF (its weight scales its
  colour), two BSDFs of one kind with the same non-colour parameters (their weighted colours add),
  a factor 0 or 1 (that side alone).  Both rest on a closure being linear in its colour, which holds
  for diffuse (Lambert, and the Oren-Nayar of Cycles 3.x), mirror, glass (not multiscatter GGX rough glass),
  refraction, transparent, translucent and glossy with fresnel 'none' (the Glossy BSDF's tint); not for Cycles 4.3+'s energy-preserving Oren-Nayar, the Metallic
  BSDF (colour = F0) or the Principled BSDF.
* Anything else is a material of kind "mix" (engine/scene/model.py Mix): the BSDF leaves, nested
  mixes flattened, each with its weight as a product of factors: constants, a Fresnel node, a
  Layer Weight node (Fresnel or Facing output), an Image Texture (its Color, UV-mapped).  Another
  factor source is warned (naming material and node) and its unlinked value is used.
"""
import dataclasses

from .images import image_node
from .util import linked_from, socket

# The Oren-Nayar closure is linear in its colour below this Cycles version (3.x's single-scatter lobe).
ENERGY_PRESERVING_OREN_NAYAR = (4, 3)
# Fields that are a closure's weight, not its parameters.
WEIGHT_FIELDS = ("name", "color", "emission", "color_texture", "emission_texture")


def shader_inputs(node):
    """The node's two shader sockets (by type: Blender names both 'Shader')."""
    return [s for s in node.inputs if s.bl_idname == "NodeSocketShader"][:2]


def constant(table, value):
    return table.MixFactor(value=float(value))


def mix_factor(table, mat, node):
    """The Mix Shader's factor: a constant clamped to [0, 1] as Cycles does, or a MixFactor read
    from the node feeding it (Fresnel, Layer Weight, Image Texture)."""
    sock = socket(node, "Factor", "Fac")
    if sock is None:
        return 0.5
    unlinked = min(max(float(sock.default_value), 0.0), 1.0)
    source = linked_from(sock) if sock.is_linked else None
    if source is None:
        return min(max(table.read_float(mat, node, "Factor", "Fac", default=0.5), 0.0), 1.0)
    factor = factor_node(table, mat, node, sock, source, unlinked)
    if factor is not None and factor.is_constant and source.bl_idname == "NodeGroupInput":
        return factor.constant()              # a group input's value: as an unlinked factor
    return unlinked if factor is None else factor


def factor_node(table, mat, mix, sock, source, unlinked):
    """A MixFactor for the node `source` feeding the Mix Shader's factor socket, or None (warned)."""
    kind = source.bl_idname
    if kind in ("ShaderNodeFresnel", "ShaderNodeLayerWeight"):
        normal = socket(source, "Normal")
        if normal is not None and normal.is_linked:
            table.warn(mat, source, "a linked Normal is not modelled; the shading normal is used")
        if kind == "ShaderNodeFresnel":
            return table.MixFactor(kind="fresnel", ior=max(table.read_float(mat, source, "IOR", default=1.45), 0.0),
                                   value=unlinked, node=source.name)
        link = sock.links[0]
        while link.from_node.bl_idname == "NodeReroute":
            link = link.from_node.inputs[0].links[0]
        blend = min(max(table.read_float(mat, source, "Blend", default=0.5), 0.0), 1.0)
        return table.MixFactor(kind="layer_weight", blend=blend, output=link.from_socket.name.lower(),
                               value=unlinked, node=source.name)
    if kind == "ShaderNodeTexImage" and table.images is not None and image_node(sock) is not None:
        image = image_node(sock)
        if image is None:
            table.warn(mat, mix, f"a factor from the '{source.name}' node's Alpha is not modelled; "
                                 f"the unlinked factor {unlinked:g} is used")
            return None
        slot = table.images.slot(mat, image)
        if slot is None:
            return None                         # warned by the image table
        return table.MixFactor(kind="texture", texture=slot, value=unlinked, node=source.name)
    program, value = table.program(mat, mix, sock, "VALUE")
    if value is not None:
        return table.MixFactor(value=min(max(float(value), 0.0), 1.0), node=source.name)
    if program is not None:
        return table.MixFactor(kind="program", program=program, value=unlinked, node=source.name)
    if table.graph_warned():
        return None
    table.warn(mat, mix, f"input '{sock.name}' is linked to '{source.name}' ({kind}), which is not modelled "
                         f"as a mix factor; its unlinked value {unlinked:g} is used")
    return None


def add_shader(table, mat, node):
    one = constant(table, 1.0)
    return combine(table, mat, node, [(one, *side(table, mat, s)) for s in shader_inputs(node)])


def mix_shader(table, mat, node):
    fac = mix_factor(table, mat, node)
    first, second = shader_inputs(node)
    if not isinstance(fac, float):
        inverted = dataclasses.replace(fac, invert=True)
        return combine(table, mat, node, [(inverted, *side(table, mat, first)), (fac, *side(table, mat, second))])
    if fac <= 0.0 or fac >= 1.0:
        return table.shader(mat, *table.shader_source(mat, second if fac >= 1.0 else first))
    return combine(table, mat, node, [(constant(table, 1.0 - fac), *side(table, mat, first)),
                                      (constant(table, fac), *side(table, mat, second))])


def side(table, mat, sock):
    """(material, slots) of the shader feeding `sock`; a BSDF is named after its node (a mix leaf)."""
    source, path = table.shader_source(mat, sock)
    material, slots = table.side(mat, source, path)
    if source is not None and material.kind != table.MIX:
        material = dataclasses.replace(material, name=f"{mat.name}: {source.name}")
    return material, slots


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
    """One material for the weighted sum of ``sides`` [(MixFactor, material, slots)]; the textures
    go to ``table._slots`` (a mix keeps its leaves' colour textures on the leaves)."""
    emission = emission_of(table, mat, node, sides)
    bsdfs = [(f, m, slots) for f, m, slots in sides
             if (not f.is_constant or f.constant() > 0.0) and has_bsdf(table, m, slots)]
    if not bsdfs:
        return table.Material(name=mat.name, kind=table.DIFFUSE, color=(0.0, 0.0, 0.0), emission=emission)
    folds = all(f.is_constant for f, _, _ in bsdfs) and all(m.kind != table.MIX for _, m, _ in bsdfs)
    if folds and len(bsdfs) == 2:
        (f0, m0, s0), (f1, m1, s1) = bsdfs
        if same_closure(table, m0, m1) and "color" not in s0 and "color" not in s1:
            color = tuple(f0.constant() * a + f1.constant() * b for a, b in zip(m0.color, m1.color))
            return dataclasses.replace(m0, name=mat.name, color=color, emission=emission)
    elif folds:
        w, material, slots = bsdfs[0][0].constant(), bsdfs[0][1], bsdfs[0][2]
        if w == 1.0 or colour_is_weight(table, material):
            if "color" in slots:
                table._slots["color"] = scaled_slot(slots["color"], w) if w != 1.0 else slots["color"]
            return dataclasses.replace(material, name=mat.name, color=scaled(material.color, w), emission=emission)
    return table.Material(name=mat.name, kind=table.MIX, emission=emission,
                          mix=table.Mix([leaf for f, m, slots in bsdfs for leaf in leaves(table, f, m, slots)]))


def leaves(table, factor, material, slots):
    """The MixLeaves of one side: a BSDF (its colour texture kept on the leaf, its emission gone to
    the mix), or a mix's leaves with the side's factor in front (nested mixes flattened)."""
    outer = [] if factor.is_constant and factor.constant() == 1.0 else [factor]
    if material.kind == table.MIX:
        return [table.MixLeaf(leaf.material, outer + list(leaf.factors)) for leaf in material.mix.leaves]
    programs = {role: p for role, p in (getattr(material, "programs", None) or {}).items() if role != "emission"}
    if len(programs) != len(getattr(material, "programs", None) or {}):
        table.warnings.append(f"Material '{material.name}': an emission driven by nodes inside a Mix or Add "
                              "Shader is not modelled; that side's emission is ignored")
    leaf = dataclasses.replace(material, emission=(0.0, 0.0, 0.0), emission_texture=None,
                               color_texture=slots.get("color"), **({"programs": programs} if hasattr(material, "programs") else {}))
    return [table.MixLeaf(leaf, outer)]


def same_closure(table, a, b):
    return a.kind == b.kind and colour_is_weight(table, a) and parameters(a) == parameters(b)


def describe(material):
    return f"{material.kind}" + (f" (fresnel {material.fresnel})" if material.kind == "glossy" else "")


def emission_weight(table, mat, node, factor):
    """A side's weight for its emission: constant, or (warned) the factor at normal incidence /
    the Mix node's unlinked value for a texture."""
    if factor.is_constant:
        return factor.constant()
    if factor.kind == "fresnel":
        ior = max(factor.ior, 1e-5)
        f = ((ior - 1.0) / (ior + 1.0)) ** 2
    elif factor.kind == "layer_weight" and factor.output == "fresnel":
        ior = 1.0 / max(1.0 - factor.blend, 1e-5)
        f = ((ior - 1.0) / (ior + 1.0)) ** 2
    elif factor.kind == "layer_weight":
        f = 0.0
    else:
        f = factor.value
    f = 1.0 - f if factor.invert else f
    table.warn(mat, node, f"an emission weighted by '{factor.node}' ({factor.kind}) is not modelled per hit; "
                          f"it is weighted by {f:g} (its value "
                          + ("of the unlinked factor)" if factor.kind == "texture" else "at normal incidence)"))
    return f


def emission_of(table, mat, node, sides):
    """The weighted sum of the sides' emission; one textured emission is kept as the slot."""
    emitting = [(f, m, slots) for f, m, slots in sides if max(m.emission) > 0 or "emission" in slots]
    weighted = [(emission_weight(table, mat, node, f), m, slots) for f, m, slots in emitting]
    textured = [(w, slots["emission"]) for w, m, slots in weighted if w > 0.0 and "emission" in slots]
    if len(textured) > 1 or (textured and any(w > 0.0 and max(m.emission) > 0 and "emission" not in slots
                                              for w, m, slots in weighted)):
        table.warn(mat, node, "more than one emission beside a textured one is not modelled; "
                              "only the textured emission is rendered")
        weighted = [side for side in weighted if "emission" in side[2]][:1]
        textured = textured[:1]
    if textured:
        w, slot = textured[0]
        table._slots["emission"] = scaled_slot(slot, w) if w != 1.0 else slot
    total = [0.0, 0.0, 0.0]
    for w, m, _ in weighted:
        for c in range(3):
            total[c] += w * m.emission[c]
    return tuple(total)


def program_uv_maps(material):
    """The UV maps the node programs of a material (its own, its leaves', its factors') read."""
    programs = list((getattr(material, "programs", None) or {}).values())
    if getattr(material, "mix", None) is not None:
        for leaf in material.mix.leaves:
            programs += list((getattr(leaf.material, "programs", None) or {}).values())
            programs += [f.program for f in leaf.factors if f.kind == "program"]
    return [name for p in programs for name in p.uv_maps]


def texture_slots(material):
    """Every texture slot a material reads: its own (colour, emission, float inputs), its mix leaves'
    and texture factors."""
    slots = [material.color_texture, material.emission_texture, *(getattr(material, "input_textures", None) or {}).values()]
    if getattr(material, "mix", None) is not None:
        for leaf in material.mix.leaves:
            slots.append(leaf.material.color_texture)
            slots += list((getattr(leaf.material, "input_textures", None) or {}).values())
            slots += [f.texture for f in leaf.factors if f.kind == "texture"]
    return [slot for slot in slots if slot is not None]
