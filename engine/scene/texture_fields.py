"""Scene-file fields of image textures (format version 4; engine/scene/files.py):

    "textures": [{"name": "Checker", "path": "checker.png", "colorspace": "sRGB"},
                 {"name": "Packed", "pixels": "@texture1_pixels", "colorspace": "sRGB", "is_float": false}],
    "materials": [{..., "color_texture": {"texture": "Checker" or 0, "interpolation": "Linear",
                                          "extension": "REPEAT", "scale": [1, 1, 1], "uv_map": ""},
                   "emission_texture": {...},
                   "input_textures": {"roughness": {..., "channel": "luminance" | "r" | "g" | "b"}}}],
    "meshes": [{..., "uvs": "@mesh0_uvs"}]          # (3 T, 2) corner UVs, 3 rows per triangle

A relative "path" is relative to the scene file's directory.  "pixels" (height, width, channels)
have row 0 at the bottom (v = 0), as Blender's; uint8 arrays are bytes (value / 255).
"input_textures" maps float inputs (engine/scene/model.py TEXTURED_INPUTS) to slots; a slot's
"channel" is the float it gives (default "luminance").
"""
from __future__ import annotations

import os

import numpy as np

from ..core.errors import SceneError
from .fields import Fields, is_integer
from .textures import ImageTexture, TextureSlot


def read_textures(top: Fields, arrays: dict, base_dir: str) -> list:
    textures = []
    for i, entry in enumerate(top.objects("textures")):
        f = Fields(entry, f"Image #{i}")
        name = f.text("name", f"texture{i}")
        f.owner = f"Image '{name}'"
        colorspace = f.text("colorspace", "sRGB")
        is_float = f.get("is_float", False)
        if not isinstance(is_float, bool):
            f.fail("is_float", "true or false", is_float)
        if "pixels" in f:
            value = f.get("pixels")
            if isinstance(value, str) and value.startswith("@"):
                if value[1:] not in arrays:
                    raise SceneError(f"{f.owner}: pixels: array '{value[1:]}' not found in the NPZ file")
                value = arrays[value[1:]]
            try:
                pixels = np.asarray(value)
                pixels = pixels if pixels.dtype == np.uint8 else pixels.astype(np.float32)
            except (TypeError, ValueError):
                f.fail("pixels", "a (height, width, channels) array of numbers", value)
            if pixels.ndim == 2:
                pixels = pixels[:, :, None]
            if pixels.ndim != 3:
                f.fail("pixels", "a (height, width, channels) array of numbers", value)
            textures.append(ImageTexture(name, pixels=pixels, colorspace=colorspace, is_float=is_float))
        else:
            path = f.text("path")
            if not os.path.isabs(path):
                path = os.path.normpath(os.path.join(base_dir, path))
            textures.append(ImageTexture(name, path=path, colorspace=colorspace, is_float=is_float))
    return textures


def read_slot(fields: Fields, key: str, textures: list):
    if key not in fields:
        return None
    f = Fields(fields.get(key), f"{fields.owner}: {key}")
    ref = f.get("texture")
    names = [t.name for t in textures]
    if is_integer(ref):
        if not 0 <= ref < len(textures):
            raise SceneError(f"{f.owner}: texture index {ref} out of range")
        index = int(ref)
    elif isinstance(ref, str) and ref in names:
        index = names.index(ref)
    else:
        raise SceneError(f"{f.owner}: unknown texture {ref!r}")
    return TextureSlot(index, interpolation=f.text("interpolation", "Linear"),
                       extension=f.text("extension", "REPEAT"), scale=f.numbers("scale", 3, (1.0, 1.0, 1.0)),
                       node=f.text("node", ""), uv_map=f.text("uv_map", ""), channel=f.text("channel", "luminance"))


def read_input_slots(fields: Fields, textures: list) -> dict:
    """A material entry's "input_textures" ({input name: slot}), {} when absent."""
    if "input_textures" not in fields:
        return {}
    entry = fields.get("input_textures")
    if not isinstance(entry, dict):
        fields.fail("input_textures", "an object of input name: texture slot", entry)
    inputs = Fields(entry, f"{fields.owner}: input_textures")
    return {name: read_slot(inputs, name, textures) for name in entry}


def slot_json(slot):
    if slot is None:
        return None
    out = {"texture": int(slot.texture), "interpolation": slot.interpolation, "extension": slot.extension,
           "scale": [float(c) for c in slot.scale], "node": slot.node, "uv_map": slot.uv_map}
    if slot.channel != "luminance":
        out["channel"] = slot.channel
    return out


def input_slots_json(material) -> dict:
    """{"input_textures": ...} of a material with textured inputs, else {} (files stay as they were)."""
    slots = {name: slot_json(slot) for name, slot in sorted((material.input_textures or {}).items())
             if slot is not None}
    return {"input_textures": slots} if slots else {}


def textures_json(scene, arrays: dict) -> list:
    out = []
    for i, t in enumerate(scene.textures):
        entry = {"name": t.name, "colorspace": t.colorspace, "is_float": bool(t.is_float)}
        if t.pixels is not None:
            px = np.asarray(t.pixels)
            arrays[f"texture{i}_pixels"] = px if px.dtype == np.uint8 else px.astype(np.float32)
            entry["pixels"] = f"@texture{i}_pixels"
        else:
            entry["path"] = t.path
        out.append(entry)
    return out
