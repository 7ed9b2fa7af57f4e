"""Scene-file fields of mixed materials (engine/scene/model.py Mix; engine/scene/files.py):

    {"name": "Varnish", "kind": "mix",
     "mix": [{"material": {... a material entry of any kind but mix ...},
              "factors": [{"kind": "constant", "value": 0.5, "invert": false},
                          {"kind": "fresnel", "ior": 1.45},
                          {"kind": "layer_weight", "blend": 0.5, "output": "facing"},
                          {"kind": "texture", "value": 0.5, "texture": {... a texture slot ...}}]}]}

Each factor key except "kind" is optional (the MixFactor defaults); "node" names the Blender node.
"""
from __future__ import annotations

from .fields import Fields
from .model import CONSTANT, PROGRAM, TEXTURE, Mix, MixFactor, MixLeaf
from .programs import program_json, read_program
from .texture_fields import read_slot, slot_json


def read_mix(m: Fields, textures: list, read_material):
    """The Mix of material entry m, or None; read_material(fields, name) reads a leaf's entry."""
    if "mix" not in m:
        return None
    value = m.get("mix")
    if not isinstance(value, list):
        m.fail("mix", "a list of leaves", value)
    leaves = []
    for i, entry in enumerate(value):
        f = Fields(entry, f"{m.owner}: mix leaf #{i}")
        leaf = Fields(f.get("material"), f"{f.owner}: material")
        material = read_material(leaf, leaf.text("name", f"{m.get('name', 'mix')} #{i}"))
        factors = []
        for j, fac in enumerate(f.get("factors", [])):
            g = Fields(fac, f"{f.owner}: factor #{j}")
            invert = g.get("invert", False)
            if not isinstance(invert, bool):
                g.fail("invert", "true or false", invert)
            default = MixFactor()
            factors.append(MixFactor(kind=g.text("kind", CONSTANT), value=g.number("value", default.value),
                                     invert=invert, ior=g.number("ior", default.ior),
                                     blend=g.number("blend", default.blend), output=g.text("output", default.output),
                                     texture=read_slot(g, "texture", textures), node=g.text("node", ""),
                                     program=(read_program(g.get("program"), f"{g.owner}: program")
                                              if "program" in g else None)))
        leaves.append(MixLeaf(material, factors))
    return Mix(leaves)


def mix_json(material, material_json) -> dict:
    """The "mix" key of a mixed material's entry; material_json(leaf material) writes a leaf's entry."""
    if material.mix is None:
        return {}
    return {"mix": [{"material": material_json(leaf.material),
                     "factors": [dict({"kind": f.kind, "value": float(f.value), "invert": bool(f.invert),
                                       "ior": float(f.ior), "blend": float(f.blend), "output": f.output,
                                       "node": f.node}, **({"texture": slot_json(f.texture)}
                                                           if f.kind == TEXTURE and f.texture is not None else {}),
                                       **({"program": program_json(f.program)} if f.kind == PROGRAM else {}))
                                 for f in leaf.factors]}
                    for leaf in material.mix.leaves]}
