"""Image textures: Blender's Image Texture node on a colour input (Base Colour / Color / Emission
Colour), looked up through per-corner UVs as Cycles does.

* `ImageTexture` is one Blender image (loaded once per worker, shared by every material that uses
  it): a file read with OpenImageIO, or pixels sent by the exporter (packed or generated images).
  Pixels are kept as Blender holds them: row 0 is the BOTTOM row (v = 0), OpenImageIO's top-first
  rows are flipped on load.
* `TextureSlot` is one use of an image by a material input: interpolation (Closest / Linear),
  extension (REPEAT / EXTEND / CLIP / MIRROR) and a scale (the emission strength).
* Float inputs (engine/scene/model.py TEXTURED_INPUTS: roughness, diffuse roughness, metallic) read
  a slot's `channel` of the texture: its luminance (Cycles' colour-to-float) or one channel (a
  Separate RGB / Color node).  The BSDFs take the per-hit value with `per_hit` (the material's own
  value at hits without a texture: no other hit changes); anisotropic BSDFs take the mesh's
  interpolated corner tangents with `hit_tangent`.
* Colour space: sRGB images are decoded to linear with the sRGB transfer function
  (IEC 61966-2-1): c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055)^2.4.  As in Cycles, 8-bit
  sRGB images are interpolated in sRGB and decoded afterwards (Cycles' "compress as sRGB"); float
  images are decoded on load.  Non-Color / Linear images are used as they are.
* Lookup (Cycles' kernel image interpolation, CPU): Closest reads texel floor(u W); Linear reads
  the 4 texels around u W - 0.5 and blends them bilinearly.  REPEAT wraps texel indices, EXTEND
  clamps them, CLIP reads 0 for texels beyond the border (Closest: 0 outside [0, 1)^2; Linear fades
  to 0 over the half texel outside, as Cycles 3.4-5.0 do), MIRROR reflects them.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..scene.model import PROGRAM, TEXTURED_INPUTS, with_mix_leaves
from ..scene.textures import ImageTexture, TextureSlot, material_slots, missing_message

from .mix import LUMINANCE

# A float input's weights of the linear colour, per TextureSlot.channel.
CHANNEL_WEIGHTS = {"luminance": LUMINANCE, "r": np.array([1.0, 0.0, 0.0]), "g": np.array([0.0, 1.0, 0.0]),
                   "b": np.array([0.0, 0.0, 1.0])}


def as_float(pixels) -> np.ndarray:
    """Pixels as float32: uint8 bytes / 255, anything else as it is."""
    pixels = np.asarray(pixels)
    if pixels.dtype == np.uint8:
        return pixels.astype(np.float32) * np.float32(1.0 / 255.0)
    return pixels.astype(np.float32)


def srgb_to_linear(c):
    """The sRGB electro-optical transfer function (IEC 61966-2-1), as Cycles' color_srgb_to_linear."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c * (1.0 / 12.92), np.power(np.maximum(c + 0.055, 0.0) / 1.055, 2.4))


# -- lookup --------------------------------------------------------------------------------------
def _wrap(i, n, extension):
    """Texel indices wrapped by the extension mode; CLIP: -1 marks texels outside (read as 0)."""
    if extension == "REPEAT":
        return np.mod(i, n)
    if extension == "MIRROR":
        period = np.mod(i, 2 * n)
        return np.where(period < n, period, 2 * n - 1 - period)
    if extension == "CLIP":
        return np.where((i >= 0) & (i < n), i, -1)
    return np.clip(i, 0, n - 1)                     # EXTEND


def _read(pixels, ix, iy):
    """Texels (N, C) at wrapped indices; index -1 (CLIP outside) reads 0."""
    h, w = pixels.shape[:2]
    out = pixels[np.clip(iy, 0, h - 1), np.clip(ix, 0, w - 1)].astype(np.float64)
    outside = (ix < 0) | (iy < 0)
    if outside.any():
        out[outside] = 0.0
    return out


def lookup(pixels, u, v, interpolation="Linear", extension="REPEAT"):
    """Texture values (N, C) at texture coordinates (u, v) (N,), as stored (no colour decoding)."""
    h, w = pixels.shape[:2]
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    if interpolation == "Closest":
        ix, iy = np.floor(u * w).astype(np.int64), np.floor(v * h).astype(np.int64)
        out = _read(pixels, _wrap(ix, w, extension), _wrap(iy, h, extension))
    else:
        x, y = u * w - 0.5, v * h - 0.5
        fx, fy = np.floor(x), np.floor(y)
        tx, ty = (x - fx)[:, None], (y - fy)[:, None]
        ix, iy = fx.astype(np.int64), fy.astype(np.int64)
        x0, x1 = _wrap(ix, w, extension), _wrap(ix + 1, w, extension)
        y0, y1 = _wrap(iy, h, extension), _wrap(iy + 1, h, extension)
        out = ((1 - ty) * ((1 - tx) * _read(pixels, x0, y0) + tx * _read(pixels, x1, y0))
               + ty * ((1 - tx) * _read(pixels, x0, y1) + tx * _read(pixels, x1, y1)))
    return out


def rgb(values):
    """(N, C) texel values -> (N, 3) colour: grey for 1-2 channels, alpha dropped."""
    if values.shape[1] >= 3:
        return values[:, :3]
    return np.repeat(values[:, :1], 3, axis=1)


# -- loading -------------------------------------------------------------------------------------
def read_image(path: str):
    """(pixels (H, W, C) float32 with row 0 at the bottom, is_float: not 8-bit) via OpenImageIO;
    raises OSError."""
    try:
        import OpenImageIO as oiio
    except ImportError as exc:
        raise OSError(f"OpenImageIO is not available ({exc})") from None
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(oiio.geterror() or "cannot open")
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if data is None:
            raise OSError(inp.geterror() or "cannot read")
        # Cycles keeps only 8-bit images as stored bytes (decoded after interpolation); 16-bit and
        # float images become floats, decoded on load.
        is_float = spec.format.basetype not in (oiio.UINT8, oiio.INT8)
    finally:
        inp.close()
    pixels = np.asarray(data, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    return np.ascontiguousarray(pixels[::-1]), is_float


@dataclass
class LoadedTexture:
    pixels: np.ndarray             # (H, W, C) float32, bottom row first
    decode_after: bool             # 8-bit sRGB: decode after interpolation
    mean: np.ndarray               # (3,) mean linear colour
    decoded: np.ndarray | None = None   # 8-bit sRGB: the texels decoded (Closest reads these)


class TextureSet:
    """Every texture of a scene, loaded once, and the materials' slots as lookups.

    A texture that cannot be read gives one warning naming the image and the materials that use
    it; those materials render with their unlinked colour."""

    def __init__(self, scene, backend: str = "numpy"):
        self.warnings: list[str] = []
        # The image lookups' kernel: `lookup` here, or its numba twin (engine/materials/textures_jit.py).
        self.compiled = None
        if backend == "numba":
            from . import textures_jit
            self.compiled = textures_jit
        self.loaded: list[LoadedTexture | None] = [self._load(t, scene) for t in scene.textures]
        mats, _ = with_mix_leaves(scene.materials)        # mix leaves: material ids after the scene's
        self.color = [self._usable(m.color_texture) for m in mats]
        self.emission = [self._usable(m.emission_texture) for m in mats]
        self.has_color = np.array([s is not None for s in self.color], dtype=bool)
        self.has_emission = np.array([s is not None for s in self.emission], dtype=bool)
        # Mix factors read from images (engine/materials/mix.py).
        self.has_factor = any(slot.texture is not None and self.loaded[slot.texture] is not None
                              for m in scene.materials for label, slot in material_slots(m)
                              if label.startswith("mix factor"))
        # Float inputs read from images (per_hit): per input name, the slot of each material.
        self.inputs = {name: [self._usable((m.input_textures or {}).get(name)) for m in mats]
                       for name in TEXTURED_INPUTS}
        self.has_input = {name: np.array([s is not None for s in slots], dtype=bool)
                          for name, slots in self.inputs.items()}
        # Anisotropic materials that read the mesh's tangents (hit_tangent).
        self.mesh_tangent = np.array([getattr(m, "tangent_source", "fixed") != "fixed" for m in mats], dtype=bool)
        # Shader-node programs (engine/scene/programs.py, run by engine/nodes/evaluator.py): per role
        # ("color", "emission", the TEXTURED_INPUTS), the program of each material or None.
        self.programs = {role: [(m.programs or {}).get(role) for m in mats]
                         for role in ("color", "emission", "normal") + TEXTURED_INPUTS}
        self.has_program = {role: np.array([p is not None for p in progs], dtype=bool)
                            for role, progs in self.programs.items()}
        self.has_program_factor = any(f.kind == PROGRAM for m in scene.materials if m.mix is not None
                                      for leaf in m.mix.leaves for f in leaf.factors)
        self.cycles_version = tuple(getattr(scene, "cycles_version", (5, 0)))[:2]
        for name in TEXTURED_INPUTS:                  # per_hit and textured_mask see both kinds of input
            if self.has_program[name].any():
                self.has_input[name] = self.has_input[name] | self.has_program[name]

    @property
    def needed(self) -> bool:
        """Whether any hit reads anything here (else the scene renders without lookups)."""
        return bool(self.has_color.any() or self.has_emission.any() or self.has_factor or self.mesh_tangent.any()
                    or any(h.any() for h in self.has_input.values()) or self.has_programs)

    @property
    def has_programs(self) -> bool:
        return self.has_program_factor or any(h.any() for h in self.has_program.values())

    def sample(self, texture, u, v, interpolation="Linear", extension="REPEAT", alpha=True):
        """(linear colour rows (3, N), alpha (N,)) of image `texture` at (u, v): an Image Texture node
        inside a node program (engine/nodes/image.py), read as `evaluate` reads a slot."""
        tex = self.loaded[texture] if 0 <= texture < len(self.loaded) else None
        if tex is None:
            return np.repeat(np.array([[1.0], [0.0], [1.0]]), len(u), axis=1), np.ones(len(u))
        color = self.evaluate(TextureSlot(texture, interpolation, extension), u, v)
        if not alpha or tex.pixels.shape[2] < 4:
            return color, np.ones(len(u))
        return color, self.lookup(tex.pixels, u, v, interpolation, extension, (3, 1))[:, 0]

    def lookup(self, pixels, u, v, interpolation, extension, channels=None) -> np.ndarray:
        """`lookup` of loaded pixels (H, W, C), on this set's backend; `channels`: (first, count) of
        the channels to read (default all)."""
        if self.compiled is not None:
            return self.compiled.lookup(pixels, u, v, interpolation, extension, channels)
        if channels is not None:
            pixels = pixels[:, :, channels[0]:channels[0] + channels[1]]
        return lookup(pixels, u, v, interpolation, extension)

    def _usable(self, slot):
        return slot if slot is not None and self.loaded[slot.texture] is not None else None

    def _load(self, tex: ImageTexture, scene):
        if tex.pixels is not None:
            pixels, is_float = as_float(tex.pixels), tex.is_float
        else:
            if not tex.path or not os.path.isfile(tex.path):
                return None                     # Scene.validate warned already (validate_textures)
            try:
                pixels, is_float = read_image(tex.path)
            except (OSError, RuntimeError, ValueError) as exc:
                self.warnings.append(missing_message(scene, tex, str(exc)))
                return None
        if pixels.ndim == 2:
            pixels = pixels[:, :, None]
        decode_after = tex.is_srgb and not is_float
        if tex.is_srgb and is_float:
            pixels = srgb_to_linear(pixels).astype(np.float32)
        col = rgb(pixels.reshape(-1, pixels.shape[2]).astype(np.float64))
        mean = (srgb_to_linear(col) if decode_after else col).mean(axis=0)
        decoded = srgb_to_linear(pixels).astype(np.float32) if decode_after else None
        return LoadedTexture(np.ascontiguousarray(pixels), decode_after, mean, decoded)

    def evaluate(self, slot: TextureSlot, u, v) -> np.ndarray:
        """Linear colour rows (3, N) of `slot` at texture coordinates (u, v), times its scale."""
        tex = self.loaded[slot.texture]
        colour = (0, 3 if tex.pixels.shape[2] >= 3 else 1)          # the channels rgb keeps (no alpha)
        if tex.decode_after and slot.interpolation == "Closest":      # decode(texel): decoded once
            return rgb(self.lookup(tex.decoded, u, v, "Closest", slot.extension, colour)).T * \
                np.asarray(slot.scale, dtype=np.float64)[:, None]
        value = rgb(self.lookup(tex.pixels, u, v, slot.interpolation, slot.extension, colour))
        if tex.decode_after:
            value = srgb_to_linear(value)
        return value.T * np.asarray(slot.scale, dtype=np.float64)[:, None]

    def mean(self, slot: TextureSlot) -> np.ndarray:
        return self.loaded[slot.texture].mean * np.asarray(slot.scale, dtype=np.float64)

    def value(self, slot: TextureSlot, u, v) -> np.ndarray:
        """The float (N,) of `slot` at (u, v): its channel of the linear colour (times the scale)."""
        return CHANNEL_WEIGHTS[slot.channel] @ self.evaluate(slot, u, v)


# -- UVs at hits ---------------------------------------------------------------------------------
def triangle_uvs(scene) -> np.ndarray:
    """Corner UVs (T, 3, 2) of every triangle in SceneGeometry's order (zeros for meshes without)."""
    parts = [np.asarray(m.uvs, dtype=np.float64).reshape(-1, 3, 2) if m.uvs is not None
             else np.zeros((len(m.triangles), 3, 2)) for m in scene.meshes if len(m.triangles)]
    return np.concatenate(parts) if parts else np.zeros((0, 3, 2))


def triangle_tangents(scene):
    """(corner tangents as rows (9, T), has_tangent (T,)) of every triangle in SceneGeometry's
    order (engine/scene/model.py TriangleMesh.tangents; zeros and False for meshes without)."""
    parts = [np.asarray(m.tangents, dtype=np.float64).reshape(-1, 9) if m.tangents is not None
             else np.zeros((len(m.triangles), 9)) for m in scene.meshes if len(m.triangles)]
    has = [np.full(len(m.triangles), m.tangents is not None) for m in scene.meshes if len(m.triangles)]
    if not parts:
        return np.zeros((9, 0)), np.zeros(0, dtype=bool)
    return np.ascontiguousarray(np.concatenate(parts).T), np.concatenate(has)


def by_material(mat):
    """[(material id, the positions of its hits in `mat`, None when they are all of them)], ids
    ascending (np.unique's order) without sorting the hits."""
    if not len(mat):
        return []
    lowest = mat.min()
    if lowest == mat.max():
        return [(lowest, None)]
    return [(m, np.flatnonzero(mat == m)) for m in np.flatnonzero(np.bincount(mat))]


def picked(values, positions):
    """values.take(positions) on the last axis; `values` itself for None (all of them)."""
    return values if positions is None else values.take(positions, axis=-1)


def whole(values, new):
    """A float64 copy of `values` with every value written from `new`: `new` itself when it is a new
    float64 array of that shape (the same numbers), else the copy."""
    if new.dtype == np.float64 and new.shape == np.shape(values):
        return new
    out = np.array(values, dtype=np.float64)
    out[...] = new
    return out


def interpolate_uv(tri_uv, prim, b1, b2):
    """(u, v) at barycentrics (b1, b2) of vertices 1 and 2 of triangles `prim` (Embree's u, v);
    tri_uv: corner UVs (T, 3, 2), or as rows (6, T) (u0 v0 u1 v1 u2 v2, faster to gather)."""
    c = tri_uv.take(prim, axis=1) if tri_uv.ndim == 2 else tri_uv[prim].reshape(-1, 6).T
    b0 = 1.0 - b1 - b2
    return b0 * c[0] + b1 * c[2] + b2 * c[4], b0 * c[1] + b1 * c[3] + b2 * c[5]


class Barycentrics:
    """Barycentrics (b1, b2) of points in a fixed set of triangles (projected onto their plane),
    with the per-triangle terms computed once: w = p - v0, b = Gram(e1, e2)^-1 (w.e1, w.e2)."""

    def __init__(self, tri):
        tri = np.asarray(tri, dtype=np.float64).reshape(-1, 3, 3)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        inv = 1.0 / np.maximum(d11 * d22 - d12 * d12, 1e-300)
        self.v0, self.e1, self.e2 = tri[:, 0].T.copy(), e1.T.copy(), e2.T.copy()      # rows (3, K)
        self.d11, self.d12, self.d22 = d11 * inv, d12 * inv, d22 * inv

    @property
    def terms(self):
        """(v0, e1, e2, d11, d12, d22): the per-triangle terms (engine/materials/textures_jit.py light_points)."""
        return self.v0, self.e1, self.e2, self.d11, self.d12, self.d22

    def __call__(self, k, point):
        """(b1, b2) of points (rows (3, N)) in triangles k (N,) of the set."""
        w = point - self.v0.take(k, axis=1)
        w1 = (w * self.e1.take(k, axis=1)).sum(axis=0)
        w2 = (w * self.e2.take(k, axis=1)).sum(axis=0)
        d12 = self.d12.take(k)
        return self.d22.take(k) * w1 - d12 * w2, self.d11.take(k) * w2 - d12 * w1


def textured_materials(scene):
    """(materials that read textures or mesh tangents at hits: a colour, a float input, a mix leaf's
    or factor's texture, a tangent from the mesh; materials with an emission texture) used by a mesh."""
    used = set()
    for mesh in scene.meshes:
        if len(mesh.triangles):
            used.update(np.unique(np.asarray(mesh.material_ids)).tolist())
    mats = [scene.materials[i] for i in sorted(used)]
    # Node programs run on any primitive (engine/nodes/context.py): spheres' and quads' materials too.
    shapes = [scene.materials[i] for i in sorted({x.material_id for x in list(scene.spheres) + list(scene.quads)}
                                                  - used)]
    return ([m for m in mats if m.color_texture is not None or m.tangent_source != "fixed" or any(
                label != "emission" for label, _ in material_slots(m)) or _reads_programs(m)]
            + [m for m in shapes if _reads_programs(m)],
            [m for m in mats + shapes if m.emission_texture is not None or "emission" in (m.programs or {})])


def _reads_programs(material) -> bool:
    """Whether a material (or a leaf or factor of its mix) has a node program on an input but emission."""
    if any(role != "emission" for role in (material.programs or {})):
        return True
    mix = getattr(material, "mix", None)
    return mix is not None and any(leaf.material.programs or any(f.kind == PROGRAM for f in leaf.factors)
                                   for leaf in mix.leaves)


def with_texture_means(scene, textures: TextureSet):
    """The scene with every textured emitter's `emission` set to its texture's mean radiance (x
    strength): the light sampler picks lights by that power, the radiance of each light sample
    and emission hit comes from the texture itself (HitTextures), so the estimate stays unbiased
    and the pdfs, which depend on geometry only, stay those of MIS."""
    import dataclasses
    if textures.has_program["emission"].any():
        scene = _with_program_means(scene, textures)
    if not textures.has_emission.any():
        return scene
    mats = [dataclasses.replace(m, emission=tuple(float(c) for c in textures.mean(slot)))
            if slot is not None else m for m, slot in zip(scene.materials, textures.emission)]
    return dataclasses.replace(scene, materials=mats)


def _with_program_means(scene, textures: TextureSet):
    """The scene with each emitter whose emission is a node program given the program's area-weighted
    mean over its triangles' centroids (at least 1e-6: it stays a light) as `emission` (the light
    sampler's power; the radiance itself is the program's at every hit and light sample)."""
    import dataclasses
    from ..geometry.scene_geometry import TRIANGLE
    from ..nodes.context import SceneAttributes
    from ..nodes.evaluator import run
    meshes = [m for m in scene.meshes if len(m.triangles)]
    if not meshes:
        return scene
    tri = np.concatenate([np.asarray(m.vertices, dtype=np.float64)[np.asarray(m.triangles)] for m in meshes])
    mat_of = np.concatenate([np.asarray(m.material_ids) for m in meshes])
    attributes = SceneAttributes(scene, tri, np.ascontiguousarray(triangle_uvs(scene).reshape(-1, 6).T))
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    mats = list(scene.materials)
    for i, m in enumerate(mats):
        program = (m.programs or {}).get("emission")
        sel = np.flatnonzero(mat_of == i)
        if program is None or not len(sel):
            continue
        third = np.full(len(sel), 1.0 / 3.0)
        ctx = attributes.context(np.full(len(sel), TRIANGLE, np.int8), sel, third, third, None,
                                 textures.cycles_version, textures, TRIANGLE)
        value = np.maximum(run(program, ctx), 0.0)
        mean = (value * area[sel]).sum(axis=1) / max(area[sel].sum(), 1e-300)
        mats[i] = dataclasses.replace(m, emission=tuple(max(float(c), 1e-6) for c in mean))
    return dataclasses.replace(scene, materials=mats)


class HitTextures:
    """Texture lookups at triangle hits and light samples (the integrator's view of TextureSet).

    Colours and emission of hits on textured materials are replaced by the texture at the hit's
    UV, interpolated from the corner UVs with Embree's barycentrics (b1, b2) (any accelerator: the
    octree and brute force return the same barycentrics).  Spheres and quads have no UVs: they
    keep the unlinked colour."""

    def __init__(self, textures: TextureSet, scene, triangles, triangle_material, lights=None):
        self.textures = textures
        self.tri_uv = np.ascontiguousarray(triangle_uvs(scene).reshape(-1, 6).T)     # rows (6, T)
        self.triangles = triangles                    # (T, 3, 3)
        self.triangle_material = triangle_material
        self.has_color, self.has_emission = textures.has_color, textures.has_emission
        self.tri_tangent, self.has_tangent = (triangle_tangents(scene) if textures.mesh_tangent.any()
                                              else (None, None))
        self.attributes = None                        # engine/nodes/context.py SceneAttributes: programs only
        if textures.has_programs:
            from ..nodes.context import SceneAttributes
            compiled = None
            if textures.compiled is not None:         # the numba backend: the attributes' twins too
                from ..nodes import context_jit as compiled
            self.attributes = SceneAttributes(scene, triangles, self.tri_uv, compiled)
        self._reads_input = {}                        # input name -> reads_input(name)
        self.light_a = self.light_b = None
        emits = self.has_emission | textures.has_program["emission"]
        if lights is not None and emits.any() and len(lights.triangle_light):
            # Each light's triangles (a parallelogram light is a pair), for light samples: numbers k
            # into `emitting` (the textured emitters' triangles, whose barycentric terms are kept).
            total = len(lights.radiance[0])
            tl = lights.triangle_light
            self.emitting = np.flatnonzero((tl >= 0) & emits.take(triangle_material))
            k = np.arange(len(self.emitting))
            self.light_a = np.full(total, -1, np.int64)
            self.light_b = np.full(total, -1, np.int64)
            self.light_a[tl[self.emitting[::-1]]] = k[::-1]      # first triangle of each light
            self.light_b[tl[self.emitting]] = k                  # last one
            self.light_b[self.light_b == self.light_a] = -1
            self.barycentrics = Barycentrics(triangles[self.emitting])
            # The compiled light_points (engine/materials/textures_jit.py) reads int64 materials and
            # the corners (T, 3, 3) as float64.
            self.material_ids = np.ascontiguousarray(triangle_material, dtype=np.int64)
            self.corners = np.ascontiguousarray(np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3))

    def _apply(self, values, slots, which, material, kind, prim, b1, b2, uv=None):
        """`values` with the hits of materials `which` flags read from their slot; `uv`: the (u, v)
        of every hit when known (interpolate_uv's numbers)."""
        from ..geometry.scene_geometry import TRIANGLE
        sel = np.flatnonzero(which.take(material) & (kind == TRIANGLE))
        if not len(sel):
            return values
        mat = material.take(sel)
        if uv is not None:
            u, v = uv if len(sel) == len(kind) else (uv[0].take(sel), uv[1].take(sel))
        else:
            u, v = interpolate_uv(self.tri_uv, prim.take(sel), b1.take(sel), b2.take(sel))
        groups = by_material(mat)
        if len(sel) == len(kind) and len(groups) == 1:          # one slot at every hit: its values
            return whole(values, self.textures.evaluate(slots[groups[0][0]], u, v))
        values = np.array(values, dtype=np.float64)
        for m, mine in groups:
            values[:, picked(sel, mine)] = self.textures.evaluate(slots[m], picked(u, mine), picked(v, mine))
        return values

    def color(self, color, material, kind, prim, b1, b2, points=None):
        """Colour rows (3, N) with textured hits replaced by the texture (Base Colour / Color), and the
        hits of materials with a node program on it by the program's value (at least 0)."""
        color = self._apply(color, self.textures.color, self.has_color, material, kind, prim, b1, b2)
        return self._programs("color", color, material, kind, prim, b1, b2, points, low=0.0)

    def emission(self, le, material, kind, prim, b1, b2, points=None):
        """Emitted radiance rows (3, N) with textured hits replaced by texture x strength (node
        programs: their value, at least 0)."""
        le = self._apply(le, self.textures.emission, self.has_emission, material, kind, prim, b1, b2)
        return self._programs("emission", le, material, kind, prim, b1, b2, points, low=0.0)

    def at(self, hits, points=None) -> "HitLookup":
        """The lookups at a wavefront's hits (engine/geometry/scene_geometry.py nearest_hits);
        `points`: engine/nodes/context.py HitPoints of the hits, for node programs."""
        return HitLookup(self, hits.kind, hits.prim, hits.u, hits.v, points)

    # -- node programs (engine/nodes/evaluator.py) -----------------------------------------------
    def run_program(self, program, kind, prim, b1, b2, points, idx):
        """A program's value at the hits idx (ascending) of these arrays: all of them when idx has
        their length (the arrays themselves, no takes)."""
        from ..geometry.scene_geometry import TRIANGLE
        from ..nodes.evaluator import run
        if len(idx) != len(kind):
            kind, prim, b1, b2 = kind.take(idx), prim.take(idx), b1.take(idx), b2.take(idx)
            points = None if points is None else points.taken(idx)
        ctx = self.attributes.context(kind, prim, b1, b2, points, self.textures.cycles_version, self.textures, TRIANGLE)
        return run(program, ctx)

    def _programs(self, role, values, material, kind, prim, b1, b2, points, low=None):
        has = self.textures.has_program[role]
        if self.attributes is None or not has.any():
            return values
        sel = np.flatnonzero(has.take(material))
        if role == "emission":             # the light sampler knows program emitters' triangles only
            from ..geometry.scene_geometry import TRIANGLE
            sel = sel[kind.take(sel) == TRIANGLE]
        if not len(sel):
            return values
        mat = material.take(sel)
        programs = self.textures.programs[role]
        groups = by_material(mat)
        if len(sel) == len(kind) and len(groups) == 1 and low is not None:    # one program at every hit
            return whole(values, np.maximum(self.run_program(programs[groups[0][0]], kind, prim, b1, b2, points, sel),
                                            low))
        values = np.array(values, dtype=np.float64)
        for m, mine in groups:
            idx = picked(sel, mine)
            out = self.run_program(programs[m], kind, prim, b1, b2, points, idx)
            values[..., idx] = out if low is None else np.maximum(out, low)
        return values

    def factor(self, slot, fallback, kind, prim, b1, b2):
        """A texture mix factor (N,) at hits: the luminance of `slot` at triangle hits with a readable
        image, `fallback` elsewhere (engine/materials/mix.py)."""
        from ..geometry.scene_geometry import TRIANGLE
        out = np.full(len(kind), float(fallback))
        sel = np.flatnonzero(kind == TRIANGLE)
        if not len(sel) or self.textures.loaded[slot.texture] is None:
            return out
        u, v = interpolate_uv(self.tri_uv, prim.take(sel), b1.take(sel), b2.take(sel))
        out[sel] = LUMINANCE @ self.textures.evaluate(slot, u, v)
        return out

    def input(self, name, values, material, kind, prim, b1, b2, points=None):
        """`values` (N,) with the hits whose material has a texture on input `name` read from it
        (triangle hits only: spheres and quads have no UVs), or a node program (any hit); `values`
        itself when none has."""
        return apply_writes(values, self.input_writes(name, material, kind, prim, b1, b2, points))

    def reads_input(self, name) -> bool:
        """Whether any material reads float input `name` from a node program or an image texture
        (else `input_writes` writes nothing, whatever the hits: HitLookup.input then reads none of
        its arrays)."""
        if name not in self._reads_input:
            self._reads_input[name] = bool(self._image_inputs(name).any()) or (
                self.attributes is not None and bool(self.textures.has_program[name].any()))
        return self._reads_input[name]

    def _image_inputs(self, name) -> np.ndarray:
        """Which materials (M,) read float input `name` from an image texture (with node programs:
        the inputs whose program did not take the image over)."""
        has = self.textures.has_input[name]
        if self.attributes is not None:
            has = has & np.array([s is not None for s in self.textures.inputs[name]], dtype=bool)
        return has

    def input_writes(self, name, material, kind, prim, b1, b2, points=None) -> list:
        """What `input` writes over the per-material values: [(hits, values)] in order (node
        programs first, then image textures), empty when no hit reads either."""
        from ..geometry.scene_geometry import TRIANGLE
        writes = []
        if not self.reads_input(name):
            return writes
        has = self.textures.has_program[name]
        if self.attributes is not None and has.any():
            sel = np.flatnonzero(has.take(material))
            if len(sel):
                mat = material.take(sel)
                programs = self.textures.programs[name]
                for m, mine in by_material(mat):
                    idx = picked(sel, mine)
                    writes.append((idx, self.run_program(programs[m], kind, prim, b1, b2, points, idx)))
        has = self._image_inputs(name)
        if not has.any():
            return writes
        sel = np.flatnonzero(has.take(material) & (kind == TRIANGLE))
        if not len(sel):
            return writes
        mat = material.take(sel)
        u, v = interpolate_uv(self.tri_uv, prim.take(sel), b1.take(sel), b2.take(sel))
        slots = self.textures.inputs[name]
        for m, mine in by_material(mat):
            writes.append((picked(sel, mine), self.textures.value(slots[m], picked(u, mine), picked(v, mine))))
        return writes

    def normal(self, shading, material, kind, prim, b1, b2, points, ng, incoming, specular):
        """Shading normals rows (3, N) (on the viewer's side) with the hits of materials with a normal
        program (a BSDF's Normal input) replaced by the program's normal, then raised as Cycles'
        closures raise it where its mirror reflection of `incoming` would fall below the geometric
        normal `ng` (engine/nodes/normals.py ensure_valid_reflection: Blender 3.x for every BSDF,
        4.x / 5.0 for the materials `specular` (M,) bool flags, not Diffuse)."""
        has = self.textures.has_program["normal"]
        if self.attributes is None or not has.any():
            return shading
        from ..nodes.normals import ensure_valid_reflection, safe_normalize
        sel = np.flatnonzero(has.take(material))
        if not len(sel):
            return shading
        out = np.array(shading, dtype=np.float64)
        mat = material.take(sel)
        programs = self.textures.programs["normal"]
        version = self.textures.cycles_version
        for m, mine in by_material(mat):
            idx = picked(sel, mine)
            n = safe_normalize(self.run_program(programs[m], kind, prim, b1, b2, points, idx))
            n = np.where((np.abs(n) > 0).any(axis=0) & np.isfinite(n).all(axis=0), n, out[:, idx])
            if version < (4, 0) or specular[m]:
                n = ensure_valid_reflection(ng[:, idx], incoming[:, idx], n, version)
            out[:, idx] = n
        return out

    def tangent(self, tangents, material, kind, prim, b1, b2):
        """Tangent rows (3, N): `tangents` with the hits of mesh-tangent materials on triangles
        that carry tangents replaced by the corner tangents interpolated at (b1, b2) (unnormalised:
        the BSDF's frame orthonormalises them, as Cycles' make_orthonormals_tangent)."""
        from ..geometry.scene_geometry import TRIANGLE
        if self.tri_tangent is None:
            return tangents
        sel = np.flatnonzero(self.textures.mesh_tangent.take(material) & (kind == TRIANGLE))
        if len(sel):
            sel = sel[self.has_tangent.take(prim.take(sel))]
        if not len(sel):
            return tangents
        c = self.tri_tangent.take(prim.take(sel), axis=1)
        bb1, bb2 = b1.take(sel), b2.take(sel)
        b0 = 1.0 - bb1 - bb2
        out = np.array(tangents, dtype=np.float64)
        out[:, sel] = b0 * c[0:3] + bb1 * c[3:6] + bb2 * c[6:9]
        return out

    def light_radiance(self, radiance, light, point):
        """Radiance rows of light samples: textured emitters evaluated at the sampled point."""
        if self.light_a is None:
            return radiance
        uv = points = None
        if self.textures.compiled is not None:        # the samples' triangles, barycentrics and UVs in one loop
            programs = self.textures.has_program["emission"]
            sel, tri, material, b1, b2, u, v, position = self.textures.compiled.light_points(
                light, point, self.light_a, self.light_b, self.emitting, self.material_ids, self.barycentrics.terms,
                self.tri_uv if self.has_emission.any() else None, self.corners if programs.any() else None)
            if not len(sel):
                return radiance
            uv = (u, v) if self.has_emission.any() else None
            if position is not None and material.min() == material.max() and programs[material[0]]:
                # One program at every sample: it runs on these arrays (no takes), so its positions
                # may come from here (the numbers and layout of the context's own, engine/nodes/context.py).
                from ..nodes.context import HitPoints
                points = HitPoints(point=position)
        else:
            ok = light < len(self.light_a)
            a = np.where(ok, self.light_a.take(np.minimum(light, len(self.light_a) - 1)), -1)
            sel = np.flatnonzero(a >= 0)
            if not len(sel):
                return radiance
            a = a.take(sel)
            b = self.light_b.take(light.take(sel))
            p = point if len(sel) == point.shape[1] else point.take(sel, axis=1)
            b1, b2 = self.barycentrics(a, p)
            other = (b >= 0) & ((b1 < 0) | (b2 < 0) | (b1 + b2 > 1))    # the pair's second triangle
            k = np.where(other, b, a)
            if other.any():
                o = np.flatnonzero(other)
                b1[o], b2[o] = self.barycentrics(k.take(o), p.take(o, axis=1))
            tri = self.emitting.take(k)
            material = self.triangle_material.take(tri)
        from ..geometry.scene_geometry import TRIANGLE
        kind = np.full(len(sel), TRIANGLE, np.int8)
        every = len(sel) == len(light)                  # every sample (sel is then 0 .. N-1)
        le = self._apply(radiance if every else radiance[:, sel], self.textures.emission, self.has_emission,
                         material, kind, tri, b1, b2, uv)
        le = self._programs("emission", le, material, kind, tri, b1, b2, points, low=0.0)
        if every:
            return np.asarray(le, dtype=np.float64)
        radiance = np.array(radiance, dtype=np.float64)
        radiance[:, sel] = le
        return radiance


class HitLookup:
    """The texture lookups of some hits (a ShadingPoint's `lookup`, engine/materials/protocol.py):
    the hits' primitive kinds, primitives and barycentrics with the scene's HitTextures, and for
    node programs their HitPoints (engine/nodes/context.py; None without programs).

    A float input (`input`: roughness, metallic, ...) is read once per material ids at these hits:
    the views of one span (`lookup[span]`, as ShadingPoint.__getitem__ makes them for the direct
    light and the scatter of a scatter group) share what they read, so the Principled BSDF's metal
    and specular lobes and its layer weights run a roughness texture or program once per bounce.
    Takes (`take`) read afresh."""

    def __init__(self, textures: HitTextures, kind, prim, b1, b2, points=None, memo=None):
        self.textures, self.kind, self.prim, self.b1, self.b2 = textures, kind, prim, b1, b2
        self.points = points
        self._memo = {} if memo is None else memo       # input name -> (material ids, input_writes)
        self._spans = {}                                # span -> its views' memo

    def __getitem__(self, span) -> "HitLookup":
        return HitLookup(self.textures, self.kind[span], self.prim[span], self.b1[span], self.b2[span],
                         None if self.points is None else self.points[span],
                         self._spans.setdefault((span.start, span.stop, span.step), {}))

    def take(self, index) -> "HitLookup":
        """The lookups of the hits `index`, their arrays gathered when first read (_TakenLookup)."""
        return _TakenLookup(self, index)

    def color(self, color, material):
        """Colour rows (3, N) of materials `material` at these hits (textured ones read)."""
        return self.textures.color(color, material, self.kind, self.prim, self.b1, self.b2, self.points)

    def emission(self, le, material):
        return self.textures.emission(le, material, self.kind, self.prim, self.b1, self.b2, self.points)

    def factor(self, slot, fallback):
        return self.textures.factor(slot, fallback, self.kind, self.prim, self.b1, self.b2)

    def program(self, program):
        """A node program's value (N,) at these hits (a mix factor, engine/materials/mix.py)."""
        return self.textures.run_program(program, self.kind, self.prim, self.b1, self.b2, self.points,
                                         np.arange(len(self.kind)))

    def input(self, name, values, material):
        """`values` (N,) with the hits that read input `name` from an image or a program replaced
        (HitTextures.input), read once per material ids at these hits."""
        if not self.textures.reads_input(name):             # nothing to read: none of these arrays gathered
            return values
        known = self._memo.get(name)
        if known is not None and (known[0] is material or np.array_equal(known[0], material)):
            return apply_writes(values, known[1])
        writes = self.textures.input_writes(name, material, self.kind, self.prim, self.b1, self.b2, self.points)
        self._memo[name] = (material, writes)
        return apply_writes(values, writes)

    def normal(self, shading, material, ng, incoming, specular):
        """The shading normals of these hits with the materials' normal programs (HitTextures.normal)."""
        return self.textures.normal(shading, material, self.kind, self.prim, self.b1, self.b2, self.points,
                                    ng, incoming, specular)

    @property
    def has_normals(self) -> bool:
        return self.textures.attributes is not None and bool(self.textures.textures.has_program["normal"].any())

    def tangent(self, tangents, material):
        """The tangents of these hits with the meshes' corner tangents (HitTextures.tangent); without
        any, `tangents` itself, none of these arrays read."""
        if self.textures.tri_tangent is None:
            return tangents
        return self.textures.tangent(tangents, material, self.kind, self.prim, self.b1, self.b2)


class _TakenLookup(HitLookup):
    """HitLookup.take: the lookups of the hits `index` of `source`, each of the arrays (kind, prim,
    b1, b2, points) gathered from the source's when first read.  Most takes read none: a Mix
    Shader's leaves (engine/materials/mix.py) take the hits' ShadingPoint, with its lookup, once per
    row and per evaluation, and only leaves with textured inputs look anything up.  A take of a take
    gathers from the first source at the composed index (one gather of the index instead of one of
    each array).  The hits' lookup arrays are written once, before any take, so a gather on first
    read gives what a gather at the take would."""
    _FIELDS = ("kind", "prim", "b1", "b2", "points")

    def __init__(self, source: HitLookup, index):
        if isinstance(source, _TakenLookup):
            source, index = source._source, source._index.take(index)
        self.textures, self._source, self._index = source.textures, source, index
        self._memo, self._spans = {}, {}

    def __getattr__(self, name):
        if name not in _TakenLookup._FIELDS:
            raise AttributeError(name)
        value = getattr(self._source, name)
        value = None if value is None else value.take(self._index)
        setattr(self, name, value)
        return value


def apply_writes(values, writes):
    """`values` itself without writes, else a float64 copy with each (hits, new values) written in order."""
    if not writes:
        return values
    out = np.array(values, dtype=np.float64)
    for idx, new in writes:
        out[idx] = new
    return out


def per_hit(si, values, name) -> np.ndarray:
    """The per-material `values` (M,) at the hits `si` (N,), read from an image texture where the hit's
    material has one on the float input `name` (engine/scene/model.py TEXTURED_INPUTS).  Scenes and
    materials without one get exactly values.take(si.material)."""
    out = values.take(si.material)
    if si.lookup is None:
        return out
    return si.lookup.input(name, out, si.material)


def textured_mask(si, name):
    """Which hits (N,) bool have a material with a texture on input `name`; None when none has (or
    `name` is None)."""
    if si.lookup is None or name is None:
        return None
    has = si.lookup.textures.textures.has_input[name]
    if not has.any():
        return None
    mask = has.take(si.material)
    return mask if mask.any() else None


def hit_tangent(si, tangents) -> np.ndarray:
    """The per-material tangent rows `tangents` (3, M) at the hits `si`, the mesh's interpolated corner
    tangent where the hit's material takes it (Material.tangent_source "radial" or "uv")."""
    out = tangents.take(si.material, axis=1)
    if si.lookup is None:
        return out
    return si.lookup.tangent(out, si.material)


class LoadedTextures:
    """A scene's TextureSet, to be bound to the geometry and lights once they are built."""

    def __init__(self, textures: TextureSet, scene):
        self.textures, self.scene = textures, scene

    def bind(self, geometry, lights) -> HitTextures:
        return HitTextures(self.textures, self.scene, geometry.triangles, geometry.triangle_material, lights)


def load_textures(scene, plan, log=print, warnings=None):
    """(LoadedTextures or None, the scene the lights are built from): images are read here, once
    per prepared scene (each worker's PreparedScene), only when the effect plan has `textures`
    on.  Images that cannot be read are logged and added to `warnings` (a worker sends them to
    Blender)."""
    if not plan.enabled.get("textures"):
        return None, scene
    textures = TextureSet(scene, getattr(plan, "backends", {}).get("textures", "numpy"))
    for warning in textures.warnings:
        log(f"warning: {warning}")
        if warnings is not None:
            warnings.append(warning)
    if not textures.needed:
        return None, scene
    return LoadedTextures(textures, scene), with_texture_means(scene, textures)
