"""Render passes besides Combined: what they are called in Blender, how they are accumulated, and
how they are written as layers of a multi-layer EXR.

Passes (``--passes albedo,normal,depth,samples,variance``; Blender's names, as Cycles'
``list_render_passes`` registers them, so the compositor's Denoise node and users know them):

  albedo    ``Denoising Albedo`` (R, G, B): the first non-specular hit's diffuse colour times the
            tints of the mirror/glass bounces before it, as Cycles' denoising albedo
            (film_write_denoising_features_surface); emission and the background seen before it add
            their radiance, unclipped as in Cycles (the denoiser clips to [0, 1]).  Averaged over all
            samples.
  normal    ``Denoising Normal`` (X, Y, Z): that hit's normal (facing the ray) in Cycles' camera
            space: x right, y up, z along the view direction (so a wall facing the camera is
            (0, 0, -1)); 0 for the background.  Averaged.
  depth     ``Depth`` (Z): distance of the camera ray's first hit along the camera's view axis
            (Blender's Z), averaged over the samples that hit something; 1e10 where none did.
            (Cycles writes the first sample's Z only.)
  samples   ``Debug Sample Count`` (X): camera samples per pixel (Cycles' name).
  variance  ``Variance`` (R, G, B): the variance of each pixel's mean (sample variance / n).

Cycles' data and light passes of the camera ray's first hit (``FIRST_HIT``; Cycles'
film_write_data_passes and film_write_emission_or_background_pass, written only for camera rays,
which pass through Area lights):

  mist            ``Mist`` (Z): 1 - the mean over the samples of (1 - m), m = clamp((d - start) /
                  depth, 0, 1) ^ falloff, d the hit's distance from the camera, (start, depth,
                  falloff) = Scene.mist (World > Mist Pass); a miss counts (1 - m) = 0, so 1.
  world_normal    ``Normal`` (X, Y, Z): the first hit's world-space shading normal, facing the ray
                  (Cycles' sd->N, flipped for back faces); averaged, a miss counts 0.
  uv              ``UV`` (U, V, A): the active render UV map's (u, v, 1) at triangle hits
                  (Cycles' primitive_uv), 0 elsewhere; averaged (A: the share of samples with UVs).
  position        ``Position`` (X, Y, Z): the world-space hit point of the pixel's sample 0 (Cycles
                  writes position and the indices for sample 0 only, not averaged); 0 for a miss.
  object_index    ``Object Index`` (X): the sample-0 hit's object Pass Index.
  material_index  ``Material Index`` (X): the sample-0 hit's material Pass Index.
  emission        ``Emission`` (R, G, B): emission the camera ray sees directly (surfaces and Area
                  lights, as Combined has it); averaged.
  environment     ``Environment`` (R, G, B): the background seen directly by camera rays; averaged.

Cycles' light passes (``LIGHT``; light_passes.h): ``Diffuse Direct`` ... ``Transmission Indirect``
(R, G, B), the light of paths by the class of their first (non-straight) bounce: diffuse lobes
(translucent too), other reflections (glossy, mirror, glass reflection) or other transmissions
(glass, refraction).  Direct: light sampled at the first vertex (shadow rays) and emission or
background found by the ray after it; Indirect: everything later.  So Combined = Emission +
Environment + the six light passes (Cycles' identity, without AO, volumes or shadow catchers).  A
BSDF with lobes of several classes (Principled, Mix) files each sample under the class of the lobe it
sampled (Cycles splits by each lobe's share of the evaluated BSDF): the sum is exact, the split
between such a material's diffuse and glossy passes is only right on average over its lobes' choice.

Cryptomatte (``CRYPTO``: crypto_object, crypto_material, crypto_asset; engine/film/cryptomatte.py):
``CryptoObject00`` .. ``CryptoObject02`` (r, g, b, a: id, coverage, id, coverage), the manifest in
the EXR's metadata (cryptomatte_metadata).

Only TRACED passes cost tracer work; when none of them is asked for the tracer does no extra work
at all (effect plan entry ``passes``), and each first-hit pass only runs when asked for.  Sums go through the same ordered merge
as the radiance (engine/rendering/frame.py FrameFilm), so every pass is the same bit for bit
whatever the workers.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError
from ..core.settings import PASSES, SETTING
from ..geometry.scene_geometry import TRIANGLE
from ..materials.principled import MU_POINTS, _read, f0_from_ior, interpolation_factor
from ..materials.textures import triangle_uvs
from . import cryptomatte

FIRST_HIT = ("mist", "world_normal", "uv", "position", "object_index", "material_index", "emission",
             "environment")
LIGHT = ("diffuse_direct", "diffuse_indirect", "glossy_direct", "glossy_indirect", "transmission_direct",
         "transmission_indirect")        # index: 2 x class (0 diffuse, 1 glossy, 2 transmission) + indirect
COLOR = ("diffuse_color", "glossy_color", "transmission_color")   # index: the class
EXTRA = FIRST_HIT + LIGHT + COLOR       # the passes TileFeatures.extra holds
CRYPTO = cryptomatte.KINDS              # Cryptomatte (engine/film/cryptomatte.py): LEVELS layers each
TRACED = ("albedo", "normal", "depth") + EXTRA + CRYPTO
NOISY = "noisy"                 # with --denoise: the image before denoising (Cycles' "Noisy Image")
WRITTEN = PASSES + (NOISY,)     # layer order in the EXR, after Combined
BLENDER_NAME = {"albedo": "Denoising Albedo", "normal": "Denoising Normal", "depth": "Depth",
                "samples": "Debug Sample Count", "variance": "Variance", NOISY: "Noisy Image",
                "mist": "Mist", "world_normal": "Normal", "uv": "UV", "position": "Position",
                "object_index": "Object Index", "material_index": "Material Index", "emission": "Emission",
                "environment": "Environment", **{n: n.replace("_", " ").title() for n in LIGHT + COLOR},
                **cryptomatte.LAYER_NAME}
# Blender 5.0's names ("Diffuse Direct" ...); 3.x's: mcrt_addon/passes.py LEGACY_NAMES
CHANNELS = {"albedo": "RGB", "normal": "XYZ", "depth": "Z", "samples": "X", "variance": "RGB", NOISY: "RGB",
            "mist": "Z", "world_normal": "XYZ", "uv": "UVA", "position": "XYZ", "object_index": "X",
            "material_index": "X", "emission": "RGB", "environment": "RGB", **{n: "RGB" for n in LIGHT + COLOR},
            **{n: "rgba" * cryptomatte.LEVELS for n in CRYPTO}}     # the spec's lower-case channels
# Blender's pass types for RenderEngine.register_pass
PASS_TYPE = {"albedo": "COLOR", "normal": "VECTOR", "depth": "VALUE", "samples": "VALUE", "variance": "COLOR",
             NOISY: "COLOR", "mist": "VALUE", "world_normal": "VECTOR", "uv": "VECTOR", "position": "VECTOR",
             "object_index": "VALUE", "material_index": "VALUE", "emission": "COLOR", "environment": "COLOR",
             **{n: "COLOR" for n in LIGHT + COLOR + CRYPTO}}
# The Color passes' class of each material kind (engine/scene/model.py): 0 diffuse (its colour),
# 1 glossy (its colour: no Fresnel), GLASS_CLASS split by Fresnel; other kinds (principled, mix,
# transparent: ANY_CLASS) put their colour in all three, a stand-in for Cycles' per-closure albedos
# that keeps Colour x (Direct + Indirect) their light.
GLASS_CLASS, ANY_CLASS = 2, -1
COLOR_CLASS = {"diffuse": 0, "translucent": 0, "mirror": 1, "glossy": 1, "glass": GLASS_CLASS, "refraction": GLASS_CLASS}
SAMPLE_ZERO = ("position", "object_index", "material_index")     # Cycles: sample 0's value, not averaged
CAMERA_LIGHT = ("emission", "environment")                       # radiance seen by camera rays
NO_DEPTH = 1e10                 # Blender's Z of the background
LAYER = "ViewLayer"             # the view layer name in the EXR's channel names


class PassError(ValueError):
    """A bad --passes value (one line)."""


def parse_passes(text) -> tuple:
    """'albedo,normal' -> ('albedo', 'normal') in PASSES order; '' or None -> ()."""
    try:
        return SETTING["passes"].parse_choices(text)
    except SceneError as exc:
        raise PassError(str(exc)) from None


def traced(passes) -> bool:
    return any(n in TRACED for n in passes or ())


def camera_frame(camera):
    """(position (3,), axes (3, 3) with columns right, up, back): the camera's orthonormal frame."""
    m = np.asarray(camera.matrix, dtype=np.float64)
    return m[:3, 3].copy(), m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)


class TileFeatures:
    """Per-sample first-hit features of one work unit, summed per pixel of its tile."""

    def __init__(self, pixels: int, camera, surface: bool = True, first_hit: "FirstHitTables | None" = None):
        self.n = pixels
        self.surface = surface          # albedo or normal asked for: paths carry their specular tints
        self.position, self.axes = camera_frame(camera)
        self.albedo = np.zeros((pixels, 3))
        self.normal = np.zeros((pixels, 3))
        self.depth = np.zeros(pixels)
        self.depth_hits = np.zeros(pixels)
        self.first_hit = first_hit      # FIRST_HIT passes asked for: their tables, else None
        wanted = () if first_hit is None else first_hit.wanted
        self.extra = {name: np.zeros((pixels, len(CHANNELS[name]))) for name in wanted}
        self.camera_light = bool(set(CAMERA_LIGHT) & set(wanted))
        self.light_split = bool(set(LIGHT) & set(wanted))     # paths carry their first bounce's class
        self.crypto = {name: [] for name in wanted if name in CRYPTO}      # (pixel, id) per sample hit

    def _sum(self, target, pixel, rows):
        for c in range(rows.shape[0]):
            target[:, c] += np.bincount(pixel, weights=rows[c], minlength=self.n)

    def add_albedo(self, pixel, albedo) -> None:
        """albedo: rows (3, N) added to their pixels."""
        if len(pixel):
            self._sum(self.albedo, pixel, albedo)

    def add_normal(self, pixel, normal) -> None:
        """World-space unit normals, rows (3, N), stored in Cycles' camera space: (right, up,
        view direction) . n, the view direction being -back (Cycles' cameras look down +z)."""
        if len(pixel):
            a = self.axes * np.array([1.0, 1.0, -1.0])
            cam = np.stack([a[0, i] * normal[0] + a[1, i] * normal[1] + a[2, i] * normal[2] for i in range(3)])
            self._sum(self.normal, pixel, cam)

    def add_depth(self, pixel, point) -> None:
        """Hit points rows (3, N): Z = (P - camera) . view axis (the view axis is -back)."""
        if len(pixel):
            back = self.axes[:, 2]
            z = -sum((point[i] - self.position[i]) * back[i] for i in range(3))
            self.depth += np.bincount(pixel, weights=z, minlength=self.n)
            self.depth_hits += np.bincount(pixel, minlength=self.n)

    def add_first_hit(self, pixel, sample, point, normal, material, kind, prim, u, v, color=None,
                      cos_i=None) -> None:
        """The FIRST_HIT data passes of camera rays' first surfaces: hit points and world-space
        shading normals facing the ray (rows (3, N)), material ids and the hits' (kind, prim, u, v);
        for the Color passes the hits' colours (3, N) and cosines to the viewer (N,)."""
        if not len(pixel):
            return
        t, x = self.first_hit, self.extra
        for name, entries in self.crypto.items():
            ids = (t.material_crypto.take(material) if name == "crypto_material"
                   else t.primitive_crypto[name].take(t.kind_base.take(kind) + prim))
            entries.append((pixel, ids))
        if color is not None and set(COLOR) & set(x):
            colors = t.lobe_colors(material, color, cos_i)
            for k, name in enumerate(COLOR):
                if name in x:
                    self._sum(x[name], pixel, colors[k])
        if "mist" in x:
            x["mist"][:, 0] += np.bincount(pixel, weights=1.0 - t.mist(point, self.position), minlength=self.n)
        if "world_normal" in x:
            self._sum(x["world_normal"], pixel, normal)
        if "uv" in x:
            self._sum(x["uv"], pixel, t.uv(kind, prim, u, v))
        zero = np.flatnonzero(sample == 0)
        if len(zero) and set(SAMPLE_ZERO) & set(x):
            pz = pixel.take(zero)
            if "position" in x:
                self._sum(x["position"], pz, point.take(zero, axis=1) + t.origin[:, None])
            if "object_index" in x:
                x["object_index"][:, 0] += np.bincount(pz, weights=t.object_index(kind.take(zero), prim.take(zero)),
                                                       minlength=self.n)
            if "material_index" in x:
                x["material_index"][:, 0] += np.bincount(pz, weights=t.material_index.take(material.take(zero)),
                                                         minlength=self.n)

    def add_camera_light(self, name, pixel, radiance) -> None:
        """Emission or environment (CAMERA_LIGHT) seen by camera rays: radiance rows (3, N)."""
        if name in self.extra and len(pixel):
            self._sum(self.extra[name], pixel, radiance)

    def add_light(self, lobe, direct, pixel, radiance) -> None:
        """Light passes: radiance rows (3, N) of paths whose first bounce had class `lobe` (N,)
        (0 diffuse, 1 glossy, 2 transmission), Direct where `direct` (N,) else Indirect."""
        which = 2 * lobe.astype(np.int64) + np.where(direct, 0, 1)
        for k, name in enumerate(LIGHT):
            if name in self.extra:
                sel = np.flatnonzero(which == k)
                if len(sel):
                    self._sum(self.extra[name], pixel.take(sel), radiance.take(sel, axis=1))

    def sums(self) -> dict:
        crypto = {name: np.concatenate([np.stack([p.astype(np.float64), i]) for p, i in entries], axis=1)
                  if entries else np.zeros((2, 0)) for name, entries in self.crypto.items()}
        return {"albedo": self.albedo, "normal": self.normal, "depth": self.depth, "depth_hits": self.depth_hits,
                **self.extra, **crypto}


class FirstHitTables:
    """What the FIRST_HIT passes look up per hit, built once per prepared scene: the camera and
    mist settings, each primitive's object Pass Index (in engine/geometry/scene_geometry.py's
    primitive slots), each material's Pass Index and the triangles' corner UVs."""

    def __init__(self, scene, geometry, passes, origin=None):
        # a class's Direct / Indirect are divided by its Color (Cycles' pass_divide): computed with them
        needed = set(passes) | {COLOR[i // 2] for i, n in enumerate(LIGHT) if n in passes}
        self.wanted = tuple(n for n in EXTRA + CRYPTO if n in needed)
        self.primitive_crypto = {n: cryptomatte.primitive_ids(scene, geometry, n) for n in ("crypto_object", "crypto_asset")
                                 if n in self.wanted}
        self.material_crypto = cryptomatte.material_ids(scene) if "crypto_material" in self.wanted else None
        # the tracing origin (engine/scene/tracing_origin.py) the scene was moved by: Position is in world space
        self.origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
        start, depth, falloff = (float(v) for v in scene.mist)
        self.mist_start, self.mist_falloff = start, falloff
        self.mist_inv_depth = 1.0 / depth if depth > 0.0 else 0.0          # as Cycles' Film::device_update
        tri = [np.full(len(m.triangles), m.pass_index, np.float64) for m in scene.meshes if len(m.triangles)]
        lights = geometry.lights.count if geometry.has_lights else 0
        self.primitive_object = np.concatenate([np.zeros(1)] + tri + [
            np.array([s.pass_index for s in scene.spheres], np.float64),
            np.array([q.pass_index for q in scene.quads], np.float64), np.zeros(lights)])
        self.kind_base = geometry.kind_base
        self.material_index = np.array([m.pass_index for m in scene.materials], np.float64)
        self.color_class = np.array([COLOR_CLASS.get(m.kind, ANY_CLASS) for m in scene.materials], np.int64)
        self.glass_s = None                 # glass: the Fresnel's interpolation factor table per material
        if set(COLOR) & set(self.wanted) and (self.color_class == GLASS_CLASS).any():
            self.glass_s = np.stack([interpolation_factor(float(m.roughness or 0.0), float(m.ior))
                                     if COLOR_CLASS.get(m.kind, ANY_CLASS) == GLASS_CLASS else np.zeros(MU_POINTS)
                                     for m in scene.materials])
            self.glass_f0 = f0_from_ior(np.array([m.ior for m in scene.materials], np.float64))
        self.tri_uv = self.has_uv = None
        if "uv" in self.wanted:
            self.tri_uv = np.ascontiguousarray(triangle_uvs(scene).reshape(-1, 6).T)       # rows (6, T)
            self.has_uv = np.concatenate([np.full(len(m.triangles), m.uvs is not None)
                                          for m in scene.meshes if len(m.triangles)] or [np.zeros(0, bool)])

    def lobe_colors(self, material, color, cos_i) -> np.ndarray:
        """(3 classes, 3, N): Cycles' Diffuse / Glossy / Transmission Color of first hits (the
        closures' bsdf_albedo: the weight, a glass's split by its microfacet-averaged Fresnel
        F = F0 + (1 - F0) s(cos_i), bsdf_microfacet_estimate_albedo); `color` the hits' colours."""
        out = np.zeros((3,) + color.shape)
        cls = self.color_class.take(material)
        for k in (0, 1):
            sel = np.flatnonzero((cls == k) | (cls == ANY_CLASS))
            out[k][:, sel] = color[:, sel]
        other = np.flatnonzero(cls == ANY_CLASS)
        out[2][:, other] = color[:, other]
        glass = np.flatnonzero(cls == GLASS_CLASS)
        if len(glass) and self.glass_s is not None:
            m = material.take(glass)
            f0 = self.glass_f0.take(m)
            f = f0 + (1.0 - f0) * _read(self.glass_s, m, np.abs(cos_i.take(glass)))
            out[1][:, glass] = color[:, glass] * f
            out[2][:, glass] = color[:, glass] * (1.0 - f)
        return out

    def mist(self, point, camera) -> np.ndarray:
        """Cycles' mist of hit points rows (3, N) seen from `camera` (3,):
        clamp((|P - camera| - start) / depth, 0, 1) ^ falloff."""
        d = np.sqrt(sum((point[i] - camera[i]) ** 2 for i in range(3)))
        m = np.clip((d - self.mist_start) * self.mist_inv_depth, 0.0, 1.0)
        return m if self.mist_falloff == 1.0 else m ** self.mist_falloff

    def object_index(self, kind, prim) -> np.ndarray:
        return self.primitive_object.take(self.kind_base.take(kind) + prim)

    def uv(self, kind, prim, u, v) -> np.ndarray:
        """Rows (3, N): (u, v, 1) of the UV map at triangle hits with UVs, 0 elsewhere."""
        out = np.zeros((3, len(kind)))
        tri = np.flatnonzero(kind == TRIANGLE)
        if len(tri):
            p = prim.take(tri)
            tri = tri[self.has_uv.take(p)]
            p = prim.take(tri)
            if len(tri):
                uv, a, b = self.tri_uv[:, p], u.take(tri), v.take(tri)
                w = 1.0 - a - b
                out[0, tri] = w * uv[0] + a * uv[2] + b * uv[4]
                out[1, tri] = w * uv[1] + a * uv[3] + b * uv[5]
                out[2, tri] = 1.0
        return out


class FrameFeatures:
    """The frame's feature sums, merged tile by tile (by FrameFilm, in chunk order)."""

    def __init__(self, width: int, height: int):
        self.albedo = np.zeros((height, width, 3))
        self.normal = np.zeros((height, width, 3))
        self.depth = np.zeros((height, width))
        self.depth_hits = np.zeros((height, width))
        self.extra = {}                 # FIRST_HIT passes: name -> (H, W, channels)
        self.crypto = {}                # Cryptomatte: name -> [(frame pixel, id) rows (2, k)]
        self.width = width

    def add(self, tile, sums: dict) -> None:
        h, w = tile.y1 - tile.y0, tile.x1 - tile.x0
        s = (slice(tile.y0, tile.y1), slice(tile.x0, tile.x1))
        self.albedo[s] += sums["albedo"].reshape(h, w, 3)
        self.normal[s] += sums["normal"].reshape(h, w, 3)
        self.depth[s] += sums["depth"].reshape(h, w)
        self.depth_hits[s] += sums["depth_hits"].reshape(h, w)
        for name in CRYPTO:
            if name in sums and sums[name].shape[1]:
                p = sums[name][0].astype(np.int64)
                frame = (tile.y0 + p // w) * self.width + tile.x0 + p % w
                self.crypto.setdefault(name, []).append((frame, sums[name][1]))
        for name in EXTRA:
            if name in sums:
                c = len(CHANNELS[name])
                if name not in self.extra:
                    self.extra[name] = np.zeros(self.depth.shape + (c,))
                self.extra[name][s] += sums[name].reshape(h, w, c)


def pass_images(film, passes) -> dict:
    """{pass name: (H, W, channels) float32} from a FrameFilm (count, variance_of_mean, features)."""
    out = {}
    count = film.count
    n = np.maximum(count, 1)[..., None]
    f = getattr(film, "features", None)
    if "albedo" in passes and f is not None:
        out["albedo"] = (f.albedo / n).astype(np.float32)
    if "normal" in passes and f is not None:
        out["normal"] = (f.normal / n).astype(np.float32)
    if "depth" in passes and f is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.where(f.depth_hits > 0, f.depth / np.maximum(f.depth_hits, 1), NO_DEPTH)
        out["depth"] = z[..., None].astype(np.float32)
    for name in EXTRA:
        if name in passes and f is not None:
            total = f.extra.get(name, np.zeros(count.shape + (len(CHANNELS[name]),)))
            if name in LIGHT:               # divided by its class's Color, as Cycles (sample counts cancel)
                empty = np.zeros(total.shape)
                out[name] = divide_even_color(total, f.extra.get(COLOR[LIGHT.index(name) // 2], empty)).astype(np.float32)
                continue
            value = total if name in SAMPLE_ZERO else total / n
            out[name] = (1.0 - value if name == "mist" else value).astype(np.float32)
    for name in CRYPTO:
        if name in passes and f is not None:
            entries = f.crypto.get(name, [])
            pixel = np.concatenate([e[0] for e in entries]) if entries else np.zeros(0, np.int64)
            ids = np.concatenate([e[1] for e in entries]) if entries else np.zeros(0)
            out[name] = cryptomatte.layers(pixel, ids, count, count.shape)
    if "samples" in passes:
        out["samples"] = count[..., None].astype(np.float32)
    if "variance" in passes:
        out["variance"] = film.variance_of_mean().astype(np.float32)
    return out


def divide_even_color(a, b) -> np.ndarray:
    """a / b per channel (..., 3), 0 where b is 0 and then, as Cycles' safe_divide_even_color, the
    other channels' ratio (their mean; one of them if two are 0) so a grey stays grey."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    zero = b == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(zero, 0.0, a / np.where(zero, 1.0, b))
    good = (~zero).sum(axis=-1, keepdims=True)
    mean = np.where(good > 0, q.sum(axis=-1, keepdims=True) / np.maximum(good, 1), 0.0)
    return np.where(zero, mean, q)


def exr_channels(passes) -> list:
    """The channel names of the multi-layer EXR, in file order: Combined first (as Blender)."""
    names = [f"{LAYER}.Combined.{c}" for c in "RGBA"]
    for p in WRITTEN:
        if p in passes:
            if p in CRYPTO:                 # CryptoObject00.r/g/b/a, CryptoObject01.r ...
                names += [f"{LAYER}.{BLENDER_NAME[p]}{i // 4:02d}.{c}" for i, c in enumerate(CHANNELS[p])]
            else:
                names += [f"{LAYER}.{BLENDER_NAME[p]}.{c}" for c in CHANNELS[p]]
    return names


def cryptomatte_metadata(scene, passes, layer=LAYER) -> list:
    """The EXR attributes (name, value) of the Cryptomatte manifests of `passes`."""
    out = []
    for name in CRYPTO:
        if name in passes:
            out += list(cryptomatte.manifest_metadata(scene, name, layer).items())
    return out


def multilayer_pixels(image, passes: dict):
    """(H, W, C) float32 pixels and channel names: Combined RGBA (the image's alpha when it has one,
    else 1), then each pass."""
    h, w = image.shape[:2]
    image = np.asarray(image, dtype=np.float32)
    alpha = image[..., 3:4] if image.shape[-1] == 4 else np.ones((h, w, 1), np.float32)
    layers = [image[..., :3], alpha]
    for p in WRITTEN:
        if p in passes:
            layers.append(np.asarray(passes[p], dtype=np.float32).reshape(h, w, len(CHANNELS[p])))
    return np.concatenate(layers, axis=-1), exr_channels([p for p in WRITTEN if p in passes])


def write_multilayer_exr(path: str, image, passes: dict, attributes=()) -> None:
    """One EXR with Blender's multi-layer channel names (``ViewLayer.Depth.Z`` ...), checked as
    engine/film/image_files.py's writer (OpenImageIO errors raise OSError)."""
    from .image_files import _write_checked
    pixels, names = multilayer_pixels(image, passes)
    _write_checked(path, pixels, "float", [("compression", "zip"), *attributes], channel_names=names)


def read_multilayer_exr(path: str) -> dict:
    """{channel name: (H, W) float32} of an EXR file, single-part (ours, Blender 3.x) or multi-part
    (Blender 5.0 writes one part per pass)."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise OSError(f"cannot read '{path}': {oiio.geterror()}")
    out, part = {}, 0
    while inp.seek_subimage(part, 0):
        names = list(inp.spec().channelnames)
        pixels = np.asarray(inp.read_image(part, 0, 0, len(names), "float"), dtype=np.float32)
        pixels = pixels.reshape(pixels.shape[0], pixels.shape[1], -1)
        out.update({name: pixels[..., i] for i, name in enumerate(names)})
        part += 1
    inp.close()
    return out
