"""Image Texture nodes -> tracer textures (engine/materials/textures.py).

An image is exported once per render however many materials use it (`ImageTable`):
* a file on disk: its absolute path; the render worker reads it with OpenImageIO;
* packed into the .blend, or generated in Blender: its pixels, read with ``foreach_get``
  (no Python loop; Blender keeps byte images as stored values / 255 and float images linear).
A missing file, an empty image or an unsupported source (movie, sequence, UDIM tiles) is a
warning naming the material and image, and the input keeps its unlinked value (as no texture).

The node's Interpolation (Closest; Linear, Cubic and Smart as Linear) and Extension (Repeat,
Extend, Clip, Mirror) are kept per use.  Its UV input: unlinked or a Texture Coordinate node's
UV output -> the mesh's active render UV map; a UV Map node -> that map; anything else (Mapping,
Object coordinates, ...) is not modelled (warning; the default UV map is used).
"""
import os

import numpy as np

from .util import linked_from, socket

LINEAR_SPACES = ("Non-Color", "Linear", "Linear Rec.709", "Raw", "Linear CIE-XYZ E", "scene_linear")


class ImageTable:
    def __init__(self, module, warnings):
        self.ImageTexture, self.TextureSlot = module.ImageTexture, module.TextureSlot
        self.textures = []
        self.warnings = warnings
        self._index = {}

    def warn(self, mat, node, text):
        self.warnings.append(f"Material '{mat.name}', node '{node.name}': {text}")

    def slot(self, mat, node, scale=(1.0, 1.0, 1.0)):
        """TextureSlot for an Image Texture node feeding a colour input, or None (with a warning)
        when it cannot be used."""
        image = node.image
        if image is None:
            self.warn(mat, node, "has no image; the input's unlinked value is used")
            return None
        index = self.texture_index(mat, node, image)
        if index is None:
            return None
        interpolation = "Closest" if node.interpolation == "Closest" else "Linear"
        if node.interpolation in ("Cubic", "Smart"):
            self.warn(mat, node, f"{node.interpolation} interpolation is rendered as Linear")
        extension = node.extension if node.extension in ("REPEAT", "EXTEND", "CLIP", "MIRROR") else "REPEAT"
        if getattr(node, "projection", "FLAT") != "FLAT":
            self.warn(mat, node, f"{node.projection.lower()} projection is not modelled (flat UV lookup)")
        return self.TextureSlot(texture=index, interpolation=interpolation, extension=extension,
                                scale=tuple(float(c) for c in scale), node=node.name,
                                uv_map=self.uv_map(mat, node))

    def uv_map(self, mat, node):
        source = linked_from(socket(node, "Vector"))
        if source is None:
            return ""
        if source.bl_idname == "ShaderNodeUVMap":
            return source.uv_map
        if source.bl_idname == "ShaderNodeTexCoord":
            link = socket(node, "Vector").links[0]
            if link.from_socket.name == "UV":
                return ""
        self.warn(mat, node, f"texture coordinates from '{source.name}' ({source.bl_idname}) are not "
                             "modelled; the active render UV map is used")
        return ""

    def texture_index(self, mat, node, image):
        key = image.name_full
        if key in self._index:
            if self._index[key] is None:
                self.warn(mat, node, f"image '{image.name}' cannot be used (see above); "
                                     "the input's unlinked value is used")
            return self._index[key]
        texture = self.convert(mat, node, image)
        self._index[key] = None if texture is None else len(self.textures)
        if texture is not None:
            self.textures.append(texture)
        return self._index[key]

    def convert(self, mat, node, image):
        where = f"image '{image.name}'"
        if image.source not in ("FILE", "GENERATED"):
            self.warn(mat, node, f"{where}: {image.source.lower()} images are not supported; "
                                 "the input's unlinked value is used")
            return None
        space = image.colorspace_settings.name
        if image.packed_file is None and image.source == "FILE":
            import bpy
            path = os.path.normpath(bpy.path.abspath(image.filepath_raw or image.filepath, library=image.library))
            if not os.path.isfile(path):
                self.warn(mat, node, f"{where}: file '{path}' not found; the input's unlinked value is used")
                return None
            return self.ImageTexture(name=image.name, path=path, colorspace=self._space(mat, node, image, space))
        width, height = (int(s) for s in image.size)
        channels = int(image.channels)
        if width <= 0 or height <= 0 or channels <= 0:
            self.warn(mat, node, f"{where} has no pixels; the input's unlinked value is used")
            return None
        pixels = np.empty(width * height * channels, np.float32)
        image.pixels.foreach_get(pixels)                     # bottom row first, as the tracer keeps them
        is_float = bool(image.is_float)
        pixels = pixels.reshape(height, width, channels)
        if not is_float:                       # bytes / 255: sent as bytes again (a quarter of the size)
            pixels = np.rint(pixels * 255.0).astype(np.uint8)
        # Blender holds float buffers in linear space already; byte buffers as stored.
        return self.ImageTexture(name=image.name, pixels=pixels,
                                 colorspace="Linear" if is_float else self._space(mat, node, image, space),
                                 is_float=is_float)

    def _space(self, mat, node, image, space):
        if space == "sRGB" or space in LINEAR_SPACES:
            return space
        self.warn(mat, node, f"image '{image.name}': colour space '{space}' is treated as sRGB")
        return "sRGB"


# Separate RGB (3.x) / Separate Color (4.x, 5.0; mode RGB) outputs -> a float input's texture channel.
CHANNEL_OUTPUTS = {"R": "r", "G": "g", "B": "b", "Red": "r", "Green": "g", "Blue": "b"}


def float_image(sock):
    """(Image Texture node, channel) feeding the float input ``sock``: its Color output straight in
    (Cycles' colour-to-float: the luminance) or through a Separate RGB / Color node's R, G or B
    (engine/scene/textures.py CHANNELS); None for anything else."""
    node = linked_from(sock)
    if node is None:
        return None
    if node.bl_idname == "ShaderNodeTexImage":
        image = image_node(sock)
        return None if image is None else (image, "luminance")
    if node.bl_idname not in ("ShaderNodeSeparateRGB", "ShaderNodeSeparateColor"):
        return None
    if getattr(node, "mode", "RGB") != "RGB":
        return None
    link = sock.links[0]
    while link.from_node.bl_idname == "NodeReroute":
        link = link.from_node.inputs[0].links[0]
    channel = CHANNEL_OUTPUTS.get(link.from_socket.name)
    source = node.inputs.get("Color") or node.inputs.get("Image")
    image = image_node(source) if (channel is not None and source is not None) else None
    return None if image is None else (image, channel)


def image_node(sock):
    """The Image Texture node whose Color output feeds ``sock`` and that reads a UV map (its Vector
    unlinked, or from a UV Map node or a Texture Coordinate's UV), else None (other coordinates: a
    node program, mcrt_addon/export/node_graph.py)."""
    node = linked_from(sock)
    if node is None or node.bl_idname != "ShaderNodeTexImage":
        return None
    link = sock.links[0]
    while link.from_node.bl_idname == "NodeReroute":
        link = link.from_node.inputs[0].links[0]
    return node if link.from_socket.name == "Color" and reads_uv(node) else None


def reads_uv(node):
    """Whether an Image Texture node's Vector is a UV map (unlinked, UV Map node, Texture Coordinate UV)."""
    vector = socket(node, "Vector")
    if vector is None or not vector.is_linked:
        return True
    link = vector.links[0]
    while link.from_node.bl_idname == "NodeReroute" and link.from_node.inputs[0].is_linked:
        link = link.from_node.inputs[0].links[0]
    source = link.from_node
    return source.bl_idname == "ShaderNodeUVMap" or (source.bl_idname == "ShaderNodeTexCoord"
                                                    and link.from_socket.name == "UV")
