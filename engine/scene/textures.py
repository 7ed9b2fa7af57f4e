"""Image textures in the scene model: the images (`ImageTexture`) and their uses by material
inputs (`TextureSlot`), and their validation.  How they are loaded and looked up at hits is
engine/materials/textures.py."""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..core.errors import SceneError
from .checks import check_magnitude

INTERPOLATIONS = ("Linear", "Closest")
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")
# How a float input reads a texture's colour (TextureSlot.channel): Cycles' colour-to-float (the
# luminance of linear Rec.709, engine/materials/mix.py LUMINANCE), or one channel (a Separate RGB /
# Separate Color node's output).
CHANNELS = ("luminance", "r", "g", "b")
LINEAR_SPACES = ("Non-Color", "Linear", "Linear Rec.709", "Raw", "Linear CIE-XYZ E", "scene_linear")


@dataclass
class ImageTexture:
    """One image.  `path`: a file for OpenImageIO; or `pixels` (H, W, C), row 0 = bottom, values as
    stored: uint8 bytes (8-bit images, 4x smaller to send to the workers) or float32 (`is_float`)."""
    name: str
    path: str = ""
    pixels: np.ndarray | None = None
    colorspace: str = "sRGB"
    is_float: bool = False

    @property
    def is_srgb(self) -> bool:
        return self.colorspace not in LINEAR_SPACES


@dataclass
class TextureSlot:
    """A material input fed by an Image Texture node."""
    texture: int                       # index into Scene.textures
    interpolation: str = "Linear"
    extension: str = "REPEAT"
    scale: tuple = (1.0, 1.0, 1.0)     # multiplies the colour (emission strength)
    node: str = ""                     # the node's name, for messages
    uv_map: str = ""                   # the UV map the exporter read ("": the active render one)
    channel: str = "luminance"         # a float input's value: CHANNELS (colour inputs ignore it)


def material_slots(material) -> list:
    """(label, slot) of every texture a material reads: its colour, emission and float inputs (labelled
    by the input's name), and in a mix its leaves' colours and inputs and its texture factors
    (engine/scene/model.py Mix)."""
    slots = [("colour", material.color_texture), ("emission", material.emission_texture)]
    slots += [(name, slot) for name, slot in sorted((getattr(material, "input_textures", None) or {}).items())]
    mix = getattr(material, "mix", None)
    if mix is not None:
        for leaf in mix.leaves:
            slots.append((f"mix leaf '{leaf.material.name}' colour", leaf.material.color_texture))
            slots += [(f"mix leaf '{leaf.material.name}' {name}", slot)
                      for name, slot in sorted((leaf.material.input_textures or {}).items())]
            slots += [(f"mix factor '{f.node}'", f.texture) for f in leaf.factors if f.kind == "texture"]
    return [(label, slot) for label, slot in slots if slot is not None]


def missing_message(scene, tex: ImageTexture, why: str) -> str:
    users = [m.name for m in scene.materials
             if any(scene.textures[s.texture] is tex for _, s in material_slots(m)
                    if isinstance(s.texture, (int, np.integer)) and 0 <= s.texture < len(scene.textures))]
    env = getattr(scene, "environment", None)
    world = ([f"World '{env.name}'"] if env is not None and 0 <= env.texture < len(scene.textures)
             and scene.textures[env.texture] is tex else [])
    who = ", ".join([f"Material '{n}'" for n in users] + world) or "no material"
    where = f" ('{tex.path}')" if tex.path else ""
    return (f"{who}: image '{tex.name}'{where} cannot be read: {why}; "
            "rendered with the unlinked colour")


def validate_textures(scene) -> list[str]:
    """SceneError on bad texture data (named by material / image / object); warnings for images
    that will not be found (their materials render with the unlinked colour)."""
    warnings = []
    n = len(scene.textures)
    for tex in scene.textures:
        if tex.pixels is not None:
            px = np.asarray(tex.pixels)
            numeric = px.dtype.kind in "uif"
            if (not numeric or px.ndim not in (2, 3) or px.shape[0] == 0 or px.shape[1] == 0
                    or not np.isfinite(px).all()):
                raise SceneError(f"Image '{tex.name}': pixels must be a finite (height, width, channels) array")
            check_magnitude(f"Image '{tex.name}'", "pixel value", px)
        elif not tex.path or not os.path.isfile(tex.path):
            warnings.append(missing_message(scene, tex, "file not found"))
    for m in scene.materials:
        for label, slot in material_slots(m):
            owner = f"Material '{m.name}'"
            if not isinstance(slot, TextureSlot):
                raise SceneError(f"{owner}: {label} texture must be a texture slot, got {slot!r}")
            if not (isinstance(slot.texture, (int, np.integer)) and 0 <= slot.texture < n):
                raise SceneError(f"{owner}: {label} texture index {slot.texture!r} out of range")
            if slot.interpolation not in INTERPOLATIONS:
                raise SceneError(f"{owner}: unknown texture interpolation '{slot.interpolation}' "
                                 f"(expected one of {', '.join(INTERPOLATIONS)})")
            if slot.extension not in EXTENSIONS:
                raise SceneError(f"{owner}: unknown texture extension '{slot.extension}' "
                                 f"(expected one of {', '.join(EXTENSIONS)})")
            if slot.channel not in CHANNELS:
                raise SceneError(f"{owner}: {label} texture channel '{slot.channel}' is not one of "
                                 f"{', '.join(CHANNELS)}")
            scale = np.asarray(slot.scale, dtype=np.float64)
            if scale.shape != (3,) or not np.isfinite(scale).all() or (scale < 0).any():
                raise SceneError(f"{owner}: {label} texture scale must be 3 finite non-negative numbers")
    return warnings
