"""The image world: Blender's Environment Texture -> Background -> World Output as a light at
infinity, importance-sampled by the image (pbrt-v3's InfiniteAreaLight, pbrt-v4's
ImageInfiniteLight with its PiecewiseConstant2D).

* Directions -> image coordinates as Cycles' kernel does it (kernel/camera/projection.h):
  equirectangular u = (pi - atan2(y, x)) / 2 pi, v = 1 - acos(z) / pi (v = 1 is straight up,
  u = 0.5 looks along +x); mirror ball u = (x' + 1) / 2, v = (z' + 1) / 2 with
  d' = (d - (0, 1, 0)) / (2 sqrt((1 - y) / 2)).  The lookup is engine/materials/textures.py's
  (Linear / Closest, extension REPEAT as Cycles' EnvironmentTextureNode).  A Mapping node is the
  3x3 `matrix` of engine/scene/model.py Environment: the texture sees normalize(M d).
* Sampling: a piecewise-constant density over the image's cells, each weighted by the luminance
  averaged over the cell (bilinear lookups reach the neighbouring texels: weights 1/8, 3/4, 1/8
  per axis, so every cell where the radiance is not 0 has a weight), times sin theta for the
  equirectangular map (its cells near the poles cover less solid angle).  An image narrower than
  Cycles' importance map (MAP_WIDTH, its World > Settings > Map Resolution default) has its
  Linear lookup's luminance taken at the centres of K x K sub-cells per texel (K even, so that
  no centre lies on a line of texel centres: every sub-cell where the bilinear radiance is not 0
  has a weight), as Cycles evaluates its map: a small bright sun's bilinear edge then no longer
  spreads over cells of one density (light samples' radiance / pdf 6x less variable on the
  `hdri` sample's floor, docs/accuracy.md "MSE against Cycles by sample count").  Per unit solid angle:
  equirectangular p_w = p_uv / (2 pi^2 sin theta); mirror ball p_w = p_uv / 16 (the mirror ball
  is an equal-area map: d omega = 16 du dv over the disk; samples outside the disk fail, pdf 0);
  a matrix M adds the Jacobian |det M| / |M d|^3.
* The light kind (engine/lights/protocol.py) is `EnvironmentLight`: picked among the lights at
  infinity by its flux as the constant world (engine/lights/distant.py WorldLight) is; bounce rays
  that escape reach it and are MIS-weighted with `pdf_li` (the integrator's misses stage,
  engine/integrators/path_tracer.py).  `EnvironmentMap.seen` is what escaping rays see, camera rays
  their own background (Light Path "Is Camera Ray").
"""
from __future__ import annotations

import os

import numpy as np

from ..core.vec import dot, rows
from ..materials.mix import LUMINANCE
from ..materials.textures import as_float, lookup, read_image, rgb, srgb_to_linear
from .distant import DistantKind
from .protocol import infinite_sample

CELL_KERNEL = np.array([0.125, 0.75, 0.125])       # a bilinear lookup's mean over a cell, per axis
MOST_CELLS = 1 << 22                                 # larger images are summed 2 x 2 for the density
MAP_WIDTH = 1024                                     # Cycles' default importance map width


# -- Cycles' projections ---------------------------------------------------------------------------
def direction_to_equirectangular(d):
    """(u, v) of unit directions d (rows), Cycles' direction_to_equirectangular."""
    u = (np.pi - np.arctan2(d[1], d[0])) * (0.5 / np.pi)
    v = 1.0 - np.arccos(np.clip(d[2], -1.0, 1.0)) * (1.0 / np.pi)
    return u, v


def equirectangular_to_direction(u, v):
    """Unit directions (rows) and sin theta of image coordinates (u, v)."""
    phi, theta = np.pi - 2.0 * np.pi * u, np.pi * (1.0 - v)
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)]), s


def direction_to_mirror_ball(d):
    """(u, v) of unit directions d (rows), Cycles' direction_to_mirrorball."""
    x, y, z = d[0], d[1] - 1.0, d[2]
    div = 2.0 * np.sqrt(np.maximum(-0.5 * y, 0.0))
    scale = np.where(div > 0.0, 1.0 / np.where(div > 0.0, div, 1.0), 1.0)
    return 0.5 * (x * scale + 1.0), 0.5 * (z * scale + 1.0)


def mirror_ball_to_direction(u, v):
    """Unit directions (rows) of image coordinates (u, v) and whether they are on the ball:
    the reflection of the view ray (0, 1, 0) about the ball's normal (x, -c, z)."""
    x, z = 2.0 * u - 1.0, 2.0 * v - 1.0
    r2 = x * x + z * z
    on = r2 <= 1.0
    c = np.sqrt(np.maximum(1.0 - r2, 0.0))
    d = np.stack([2.0 * c * x, 1.0 - 2.0 * c * c, 2.0 * c * z])
    return d, on


# -- the 2-D distribution --------------------------------------------------------------------------
class PiecewiseConstant2D:
    """A density over [0, 1)^2 constant on the cells of a (H, W) weight grid (row j: v in
    [j / H, (j + 1) / H), column i: u): rows by their marginal, then the column in the row
    (pbrt's PiecewiseConstant2D).  Densities are per unit (u, v) area."""

    def __init__(self, weights):
        w = np.maximum(np.asarray(weights, dtype=np.float64), 0.0)
        self.h, self.w = w.shape
        row = w.sum(axis=1)
        total = row.sum()
        if not total > 0:
            raise ValueError("the weights are all 0")
        self.marginal = np.concatenate([[0.0], np.cumsum(row)]) / total
        self.marginal[-1] = 1.0
        safe = np.where(row > 0, row, 1.0)[:, None]
        self.conditional = np.concatenate([np.zeros((self.h, 1)), np.cumsum(w, axis=1) / safe], axis=1)
        self.conditional[:, -1] = 1.0
        # Row j's upper column bounds, shifted by j: one increasing array for every row's search.
        self.flat = (np.arange(self.h)[:, None] + self.conditional[:, 1:]).ravel()
        self.density = w * (self.h * self.w / total)
        self.last_row = int(np.flatnonzero(row > 0)[-1])
        self.conditional_flat, self.density_flat = self.conditional.ravel(), self.density.ravel()   # views
        self.jit = None         # the compiled twin (engine/lights/environment_jit.py), set by EnvironmentMap.use_backend

    def sample(self, u1, u2):
        """(u, v, density) from uniforms u1 (the column) and u2 (the row)."""
        if self.jit is not None:            # the same numbers in one loop
            return self.jit.sample(self, u1, u2)
        j = np.minimum(np.searchsorted(self.marginal, u2, side="right") - 1, self.last_row)
        lo, hi = self.marginal.take(j), self.marginal.take(j + 1)
        dv = np.clip((u2 - lo) / (hi - lo), 0.0, 1.0)
        i = np.clip(np.searchsorted(self.flat, j + u1, side="right") - j * self.w, 0, self.w - 1)
        flat = j * (self.w + 1) + i
        lo, hi = self.conditional.take(flat), self.conditional.take(flat + 1)
        du = np.clip((u1 - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
        u = np.minimum((i + du) / self.w, np.nextafter(1.0, 0.0))
        v = np.minimum((j + dv) / self.h, np.nextafter(1.0, 0.0))
        return u, v, self.density.take(j * self.w + i)

    def pdf(self, u, v):
        if self.jit is not None:
            return self.jit.pdf(self, u, v)
        i = np.clip(np.floor(np.asarray(u) * self.w).astype(np.int64), 0, self.w - 1)
        j = np.clip(np.floor(np.asarray(v) * self.h).astype(np.int64), 0, self.h - 1)
        return self.density.take(j * self.w + i)


# -- the map -------------------------------------------------------------------------------------------
def _axis(t, n):
    """engine/materials/textures.py lookup's Linear REPEAT weights along one axis of n texels at
    coordinates t: (weight of the next texel, texel, next texel)."""
    x = t * n - 0.5
    f = np.floor(x)
    i = f.astype(np.int64)
    return x - f, np.mod(i, n), np.mod(i + 1, n)


def cell_mean(lum, axis):
    """sum(k * np.roll(lum, s, axis) for k, s in zip(CELL_KERNEL, (1, 0, -1))), bit for bit (the
    same products and sums in the same order, 0 + the first), in two buffers instead of nine: a
    2048 x 1024 map's construction is bound by memory (tests/lights/test_environment_build.py)."""
    out, term = np.empty_like(lum), np.empty_like(lum)
    for weight, shift in zip(CELL_KERNEL, (1, 0, -1)):
        target = out if shift == 1 else term
        if shift == 0:
            np.multiply(weight, lum, out=target)
        else:
            _roll_into(lum, shift, axis, target)
            np.multiply(weight, target, out=target)
        if shift == 1:
            np.add(0, out, out=out)
        else:
            np.add(out, term, out=out)
    return out


def _roll_into(a, shift, axis, out) -> None:
    """out[...] = np.roll(a, shift, axis) for shift +1 or -1."""
    head, tail = [slice(None)] * a.ndim, [slice(None)] * a.ndim
    if shift == 1:
        head[axis], tail[axis] = slice(1, None), slice(None, -1)
        out[tuple(head)] = a[tuple(tail)]
        head[axis], tail[axis] = slice(0, 1), slice(-1, None)
    else:
        head[axis], tail[axis] = slice(None, -1), slice(1, None)
        out[tuple(head)] = a[tuple(tail)]
        head[axis], tail[axis] = slice(-1, None), slice(0, 1)
    out[tuple(head)] = a[tuple(tail)]


def fine_lookup(pixels, us, vs):
    """(len(vs) * len(us), C) float64: lookup(pixels, u, v, "Linear", "REPEAT") at every (u, v) of the
    grid of columns `us` and rows `vs` (row by row), bit for bit.  The bilinear weights of a grid
    depend on the column or the row only, so each texel row is blended along u once, then pairs of
    those rows along v: the same operations on the same numbers as lookup's
    (1 - ty)((1 - tx) p00 + tx p10) + ty((1 - tx) p01 + tx p11), without reading 4 texels per
    point (a 128 x 64 world at 8 x 8 sub-cells: 0.2 -> 0.03 CPU s, docs/performance.md "A render's
    fixed cost"; tests/lights/test_environment.py)."""
    tx, x0, x1 = _axis(np.asarray(us, dtype=np.float64), pixels.shape[1])
    ty, y0, y1 = _axis(np.asarray(vs, dtype=np.float64), pixels.shape[0])
    texels = pixels.astype(np.float64)
    tx = tx[None, :, None]
    along_u = (1 - tx) * texels[:, x0] + tx * texels[:, x1]             # (H, len(us), C)
    ty = ty[:, None, None]
    out = (1 - ty) * along_u[y0] + ty * along_u[y1]                      # (len(vs), len(us), C)
    return out.reshape(-1, pixels.shape[2])


def load_pixels(tex):
    """(pixels (H, W, C) float32 bottom row first, decode_after: 8-bit sRGB decoded after the
    lookup) of an engine/scene/textures.py ImageTexture, as engine/materials/textures.py loads it;
    raises OSError when it cannot be read."""
    if tex.pixels is not None:
        pixels = np.asarray(tex.pixels)                 # float32 as it is (only read here): no copy
        pixels, is_float = (pixels if pixels.dtype == np.float32 else as_float(pixels)), tex.is_float
    else:
        if not tex.path or not os.path.isfile(tex.path):
            raise OSError("file not found")
        pixels, is_float = read_image(tex.path)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    decode_after = tex.is_srgb and not is_float
    if tex.is_srgb and is_float:
        pixels = srgb_to_linear(pixels).astype(np.float32)
    return np.ascontiguousarray(pixels), decode_after


_LAST = {"keep": False, "key": None, "map": None}       # keep_last_map's (world, image) and map


def keep_last_map(keep: bool = True) -> None:
    """For a process that prepares scene after scene (the viewport's and Persistent Data's workers,
    engine/pools/viewport.py): EnvironmentMap.of gives the last map back for a world and image
    equal to the last ones (values compared, not objects: every preparation unpickles new ones),
    so a frame of an animation whose objects moved does not build the image world's tables again
    (sky.blend's 2048 x 1024 map: 0.08-0.6 CPU s per worker and frame).  The map is a function of
    those two alone, and nothing changes it after it is built.  Images given as a file are not kept."""
    _LAST.update(keep=keep, key=None, map=None)


def _same_world(env, texture, last_env, last_texture) -> bool:
    """Whether (env, texture) equal (last_env, last_texture): every field of the world, and the
    image's pixels (dtype, shape, values), colour space and kind."""
    if env != last_env or texture.pixels is None or last_texture.pixels is None:
        return False
    a, b = np.asarray(texture.pixels), np.asarray(last_texture.pixels)
    return (texture.colorspace == last_texture.colorspace and texture.is_float == last_texture.is_float
            and a.dtype == b.dtype and a.shape == b.shape and (a is b or bool(np.array_equal(a, b))))


class EnvironmentMap:
    """One scene's image world (engine/scene/model.py Environment) with its pixels: radiance per
    direction, and the importance sampler.  `sin_theta_in_density`: False only for a test's
    control (a sampler that forgets the equirectangular map's sin theta)."""

    def __init__(self, env, pixels, decode_after: bool, sin_theta_in_density: bool = True):
        self.env = env
        self.pixels, self.decode_after = pixels, decode_after
        self.compiled = None            # the lookup's compiled twin (use_backend)
        self.equirectangular = env.projection == "equirectangular"
        self.matrix = np.asarray(env.matrix, dtype=np.float64)
        self.identity = bool(np.array_equal(self.matrix, np.eye(3)))
        self.inverse = np.linalg.inv(self.matrix)
        self.det = abs(float(np.linalg.det(self.matrix)))
        self.strength = float(env.strength)
        # Float32 (H, W, 3) views where it can (a 8k x 4k image: no float64 copies of the colour).
        colour = np.maximum(self._linear(pixels.reshape(-1, pixels.shape[2])), np.float32(0.0))
        colour = colour.reshape(*pixels.shape[:2], 3)
        area = self._cell_areas(*colour.shape[:2])
        mean = np.einsum("hw,hwc->c", area, colour, dtype=np.float64) / max(area.sum(), 1e-300)
        self.mean = np.maximum(mean, 0.0) * self.strength          # mean radiance over the sphere
        lum = (colour @ LUMINANCE.astype(np.float32)).astype(np.float64)
        del colour
        k = self._sub_cells(*lum.shape)
        if env.interpolation != "Closest" and k > 1:    # the bilinear luminance at sub-cell centres
            lum = self._fine_luminance(pixels, k)
        elif env.interpolation != "Closest":            # a bilinear lookup's mean over each cell
            lum = cell_mean(cell_mean(lum, 0), 1)
        while lum.size > MOST_CELLS and lum.shape[0] % 2 == 0 and lum.shape[1] % 2 == 0:
            lum = 0.25 * (lum[0::2, 0::2] + lum[1::2, 0::2] + lum[0::2, 1::2] + lum[1::2, 1::2])
        if lum.shape != area.shape:
            area = self._cell_areas(*lum.shape)
        weight = lum * area if sin_theta_in_density or not self.equirectangular else lum
        self.distribution = PiecewiseConstant2D(weight)

    @staticmethod
    def _sub_cells(h, w):
        """K (1 or even) sub-cells per texel side: the map at least MAP_WIDTH wide, at most MOST_CELLS."""
        k = 2 * -(-MAP_WIDTH // (2 * w)) if w < MAP_WIDTH else 1
        while k > 1 and h * w * k * k > MOST_CELLS:
            k -= 2
        return k

    def _fine_luminance(self, pixels, k):
        """(h k, w k) the Linear lookup's luminance (no strength) at the sub-cell centres."""
        h, w = pixels.shape[0] * k, pixels.shape[1] * k
        values = fine_lookup(pixels, (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
        colour = np.maximum(self._linear(values), 0.0)
        return (colour @ LUMINANCE.astype(np.float64)).reshape(h, w)

    def _cell_areas(self, h, w):
        """(h, w) the relative solid angle of each cell: sin theta of its centre (equirectangular), or
        1 for the cells that reach into the mirror ball's disk and 0 for the others."""
        v = (np.arange(h) + 0.5) / h
        if self.equirectangular:
            return np.repeat(np.sin(np.pi * (1.0 - v))[:, None], w, axis=1)
        cu, cv = (np.arange(w) + 0.5) / w - 0.5, v - 0.5
        du = np.maximum(np.abs(cu)[None, :] - 0.5 / w, 0.0)
        dv = np.maximum(np.abs(cv)[:, None] - 0.5 / h, 0.0)
        return (du * du + dv * dv < 0.25).astype(np.float64)

    @classmethod
    def of(cls, scene):
        """The scene's map, or None: no environment, or its image cannot be read (Scene.validate
        warned about a missing file; the constant background is used).  In a process that keeps
        its last map (keep_last_map), the last one when the world and its image are the same."""
        env = getattr(scene, "environment", None)
        if env is None:
            return None
        texture = scene.textures[env.texture]
        if _LAST["keep"] and _LAST["key"] is not None and _same_world(env, texture, *_LAST["key"]):
            return _LAST["map"]
        try:
            pixels, decode_after = load_pixels(texture)
            built = cls(env, pixels, decode_after)
        except (OSError, RuntimeError, ValueError):
            return None
        if _LAST["keep"] and texture.pixels is not None:     # a file's content may change under its name
            _LAST.update(key=(env, texture), map=built)
        return built

    @property
    def lights(self) -> bool:
        """Whether the image lights the scene (else only camera rays see it)."""
        return bool(self.env.lighting) and self.strength > 0 and bool(self.mean.max() > 0)

    def _linear(self, values):
        """(N, C) looked-up values -> (N, 3) linear colour."""
        col = rgb(values)
        return srgb_to_linear(col) if self.decode_after else col

    def _texture_direction(self, d):
        if self.identity:
            return d, None
        t = self.matrix @ d
        length = np.sqrt(dot(t, t))
        return t / np.maximum(length, 1e-300), length

    def use_backend(self, backend: str) -> None:
        """The image lookups and the sampler on `backend` ("numba": engine/materials/textures_jit.py's twin of
        lookup and engine/lights/environment_jit.py's of PiecewiseConstant2D, the same numbers; else NumPy's).  Set by each render's PathTracer: a kept map (keep_last_map) serves
        the renders after it, whatever their backend."""
        self.compiled = self.distribution.jit = None
        if backend == "numba":                  # and the sampler's twin (engine/lights/environment_jit.py)
            from . import environment_jit
            self.distribution.jit = environment_jit
        if backend == "numba" and self.pixels.dtype == np.float32 and self.pixels.flags.c_contiguous:
            from ..materials import textures_jit
            self.compiled = textures_jit

    def image(self, d):
        """(3, N) the image's linear colour (no strength) seen along unit directions d."""
        t, _ = self._texture_direction(d)
        u, v = direction_to_equirectangular(t) if self.equirectangular else direction_to_mirror_ball(t)
        if self.compiled is not None:       # the three colour channels read in one compiled loop
            values = self.compiled.lookup(self.pixels, u, v, self.env.interpolation, "REPEAT",
                                          (0, 3) if self.pixels.shape[2] >= 3 else None)
        else:
            values = lookup(self.pixels, u, v, self.env.interpolation, "REPEAT")
        return self._linear(values).T

    def radiance(self, d):
        """(3, N) radiance along d for the rays that light the scene."""
        return self.image(d) * self.strength

    def seen(self, d, camera, background):
        """(3, N) what rays leaving along d see: camera rays (bool (N,)) the camera background,
        the others the image (or, when it does not light, the constant `background`)."""
        env = self.env
        out = self.radiance(d) if env.lighting else np.repeat(np.asarray(background, np.float64)[:, None], d.shape[1], 1)
        cam = np.flatnonzero(camera)
        if len(cam):
            if env.camera_color is not None:
                out[:, cam] = np.asarray(env.camera_color, dtype=np.float64)[:, None]
            else:
                k = env.strength if env.camera_strength is None else env.camera_strength
                out[:, cam] = self.image(d.take(cam, axis=1)) * k
        return out

    def sample(self, u1, u2):
        """(unit directions rows, their density per unit solid angle; 0 where a sample failed)."""
        u, v, p_uv = self.distribution.sample(u1, u2)
        if self.equirectangular:
            t, s = equirectangular_to_direction(u, v)
            with np.errstate(divide="ignore", invalid="ignore"):
                pdf = np.where(s > 0.0, p_uv / (2.0 * np.pi * np.pi * s), 0.0)
        else:
            t, on = mirror_ball_to_direction(u, v)
            pdf = np.where(on, p_uv * (1.0 / 16.0), 0.0)
        if self.identity:
            return t, pdf
        d = self.inverse @ t
        d = d / np.sqrt(dot(d, d))
        return d, pdf * self._jacobian(d)

    def _jacobian(self, d):
        """d omega_texture / d omega_world at unit world directions d: |det M| / |M d|^3."""
        m = self.matrix @ d
        return self.det / np.sqrt(dot(m, m)) ** 3

    def pdf(self, d):
        """(N,) the density `sample` has for unit directions d (rows)."""
        t, _ = self._texture_direction(d)
        if self.equirectangular:
            u, v = direction_to_equirectangular(t)
            s = np.hypot(t[0], t[1])                      # sin theta (accurate near the poles)
            with np.errstate(divide="ignore", invalid="ignore"):
                pdf = np.where(s > 0.0, self.distribution.pdf(u, v) / (2.0 * np.pi * np.pi * s), 0.0)
        else:
            u, v = direction_to_mirror_ball(t)
            pdf = self.distribution.pdf(u, v) * (1.0 / 16.0)
        return pdf if self.identity else pdf * self._jacobian(d)


class EnvironmentLight(DistantKind):
    """The image world as a light kind: one light, sampled by the image (EnvironmentMap)."""
    name = "environment"
    description = "the environment image"
    reached_by_escaping_rays = True
    count = 1

    def __init__(self, environment: EnvironmentMap, scene_radius: float):
        r2 = max(scene_radius, 1e-300) ** 2
        self.map = environment
        self.radiance = rows(environment.mean[None, :])            # the mean, for the light tables
        self.one_sided = np.zeros(1, dtype=bool)
        self.flux = np.array([np.pi * float(np.mean(environment.mean)) * 4.0 * np.pi * r2])
        self.scene_radius = scene_radius

    def sample_emission(self, idx, u1, u2, u3, u4, targets=None):
        """Photons (engine/integrators/photons/): a direction towards the image drawn by its sampler
        (u1, u2), the photon travelling the other way, from the disk facing it (u3, u4)."""
        towards, pdf = self.map.sample(u1, u2)
        travel = -towards
        return self._disk_rays(travel, u3, u4, travel, self.map.radiance(towards), pdf, targets)

    def sample_li(self, x, idx, u1, u2, n=None, solid_angle: bool = True):
        direction, pdf = self.map.sample(u1, u2)
        return infinite_sample(x, direction, self.map.radiance(direction), pdf)

    def pdf_li(self, x, idx, point, n=None, direction=None, solid_angle: bool = True, pmf=1.0):
        """The image's density of `direction` (pmf: a probability multiplied in, as WorldLight's)."""
        return pmf * self.map.pdf(direction)

    def le(self, idx, point, direction):
        return self.map.radiance(direction)
