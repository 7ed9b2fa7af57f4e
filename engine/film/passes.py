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

Only albedo, normal and depth are traced (``TRACED``); when none of them is asked for the tracer
does no extra work at all (effect plan entry ``passes``).  Sums go through the same ordered merge
as the radiance (engine/rendering/frame.py FrameFilm), so every pass is the same bit for bit
whatever the workers.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError
from ..core.settings import PASSES, SETTING

TRACED = ("albedo", "normal", "depth")
NOISY = "noisy"                 # with --denoise: the image before denoising (Cycles' "Noisy Image")
WRITTEN = PASSES + (NOISY,)     # layer order in the EXR, after Combined
BLENDER_NAME = {"albedo": "Denoising Albedo", "normal": "Denoising Normal", "depth": "Depth",
                "samples": "Debug Sample Count", "variance": "Variance", NOISY: "Noisy Image"}
CHANNELS = {"albedo": "RGB", "normal": "XYZ", "depth": "Z", "samples": "X", "variance": "RGB", NOISY: "RGB"}
# Blender's pass types for RenderEngine.register_pass
PASS_TYPE = {"albedo": "COLOR", "normal": "VECTOR", "depth": "VALUE", "samples": "VALUE", "variance": "COLOR",
             NOISY: "COLOR"}
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

    def __init__(self, pixels: int, camera, surface: bool = True):
        self.n = pixels
        self.surface = surface          # albedo or normal asked for: paths carry their specular tints
        self.position, self.axes = camera_frame(camera)
        self.albedo = np.zeros((pixels, 3))
        self.normal = np.zeros((pixels, 3))
        self.depth = np.zeros(pixels)
        self.depth_hits = np.zeros(pixels)

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

    def sums(self) -> dict:
        return {"albedo": self.albedo, "normal": self.normal, "depth": self.depth, "depth_hits": self.depth_hits}


class FrameFeatures:
    """The frame's feature sums, merged tile by tile (by FrameFilm, in chunk order)."""

    def __init__(self, width: int, height: int):
        self.albedo = np.zeros((height, width, 3))
        self.normal = np.zeros((height, width, 3))
        self.depth = np.zeros((height, width))
        self.depth_hits = np.zeros((height, width))

    def add(self, tile, sums: dict) -> None:
        h, w = tile.y1 - tile.y0, tile.x1 - tile.x0
        s = (slice(tile.y0, tile.y1), slice(tile.x0, tile.x1))
        self.albedo[s] += sums["albedo"].reshape(h, w, 3)
        self.normal[s] += sums["normal"].reshape(h, w, 3)
        self.depth[s] += sums["depth"].reshape(h, w)
        self.depth_hits[s] += sums["depth_hits"].reshape(h, w)


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
    if "samples" in passes:
        out["samples"] = count[..., None].astype(np.float32)
    if "variance" in passes:
        out["variance"] = film.variance_of_mean().astype(np.float32)
    return out


def exr_channels(passes) -> list:
    """The channel names of the multi-layer EXR, in file order: Combined first (as Blender)."""
    names = [f"{LAYER}.Combined.{c}" for c in "RGBA"]
    for p in WRITTEN:
        if p in passes:
            names += [f"{LAYER}.{BLENDER_NAME[p]}.{c}" for c in CHANNELS[p]]
    return names


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
