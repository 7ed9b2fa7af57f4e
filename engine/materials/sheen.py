"""The microfiber sheen of the Principled BSDF v2 (Cycles 4.0+'s Sheen closure, its
kernel/closure/bsdf_sheen.h; a public source: blender/cycles src/kernel/): Zeltner, Burley and Chiang,
"Practical Multiple-Scattering Sheen Using Linearly Transformed Cosines" (2022).

The lobe is a linearly transformed cosine in the frame (x, y, n) whose x axis is wo's direction
along the surface (Cycles' make_orthonormals_safe_tangent(N, wi)): for a direction w in that frame

    D(w) = max(w_z, 0) / pi x (a / |(a w_x + b w_z, a w_y, w_z)|^2)^2,

a density over the hemisphere (the cosine lobe mapped by M = [[1, 0, -b], [0, 1, 0], [0, 0, a]]:
its integral is 1).  f cos = R x D and pdf = D, so every sample's weight is the albedo R: the
lobe reflects exactly R(mu, roughness) of white light.  a, b and R come from the fitted table
(32 x 32: mu = cos(theta_o) j / 31 along a row, roughness i / 31 down the rows, read bilinearly as
Cycles' lookup_table_read_2D), engine/materials/sheen_ltc.npz, which scripts/make_sheen_table.py
takes from Cycles' source (the fit is Zeltner et al.'s, not reproduced here: docs/materials.md).
Roughness is clamped to [1e-3, 1]; where the table gives |a| < 1e-5 or R < 1e-5 there is no lobe
(Cycles skips the closure).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from ..core.vec import dot, normalize
from .microfacet import shading_frame, to_local, to_world
from .protocol import BSDFFlags

TABLE_FILE = Path(__file__).with_name("sheen_ltc.npz")
SIZE = 32
ROUGHNESS_RANGE = (1e-3, 1.0)
CUTOFF = 1e-5
LOBE = BSDFFlags.DIFFUSE | BSDFFlags.REFLECTION      # Cycles labels it LABEL_REFLECT | LABEL_DIFFUSE


@lru_cache(maxsize=1)
def table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, b, R), each (32, 32) [roughness row, mu column], float64."""
    with np.load(TABLE_FILE) as data:
        return tuple(np.asarray(data[k], dtype=np.float64) for k in ("a", "b", "albedo"))


def read_2d(values: np.ndarray, mu: np.ndarray, roughness: np.ndarray) -> np.ndarray:
    """values (32, 32) at (mu, roughness) (N,): bilinear, each coordinate clamped to [0, 1]."""
    x = np.clip(mu, 0.0, 1.0) * (SIZE - 1)
    y = np.clip(roughness, 0.0, 1.0) * (SIZE - 1)
    i = np.minimum(x.astype(np.int64), SIZE - 1)
    j = np.minimum(y.astype(np.int64), SIZE - 1)
    i1, j1 = np.minimum(i + 1, SIZE - 1), np.minimum(j + 1, SIZE - 1)
    tx, ty = x - i, y - j
    row0 = (1.0 - tx) * values[j, i] + tx * values[j, i1]
    row1 = (1.0 - tx) * values[j1, i] + tx * values[j1, i1]
    return (1.0 - ty) * row0 + ty * row1


def clamp_roughness(roughness) -> np.ndarray:
    return np.clip(np.asarray(roughness, dtype=np.float64), *ROUGHNESS_RANGE)


def sheen_params(mu: np.ndarray, roughness: np.ndarray):
    """(a, b, R) (N,) each at cos(theta_o) = mu and the (clamped) roughness; R = 0 where there is no lobe."""
    a_t, b_t, r_t = table()
    rough = clamp_roughness(roughness)
    a, b, r = read_2d(a_t, mu, rough), read_2d(b_t, mu, rough), read_2d(r_t, mu, rough)
    r = np.where((np.abs(a) < CUTOFF) | (r < CUTOFF), 0.0, r)
    return a, b, r


def sheen_albedo(mu: np.ndarray, roughness: np.ndarray) -> np.ndarray:
    """R(mu, roughness) (N,): the lobe's albedo, which darkens the layers below it."""
    return sheen_params(mu, roughness)[2]


def ltc_value(local: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """D(w) (N,) for directions `local` (3, N) in the lobe's frame (see the module)."""
    len_sqr = (a * local[0] + b * local[2]) ** 2 + (a * local[1]) ** 2 + local[2] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        val = np.maximum(local[2], 0.0) / np.pi * (a / len_sqr) ** 2
    return np.nan_to_num(val)


class MicrofiberSheen:
    """The sheen lobe at hits, for a (N,) roughness per hit: `eval` gives D(wi) (the pdf; f cos
    = R x D, R from `params`), `sample` a direction of density D.  Not a BSDF of the material
    table: the Principled BSDF (engine/materials/principled.py) weighs it."""

    @staticmethod
    def frame(si):
        """(x, y) of the lobe's frame: x along wo's projection on the surface."""
        return shading_frame(si.n, si.wo)

    def params(self, si, roughness):
        return sheen_params(np.clip(dot(si.wo, si.n), 0.0, 1.0), roughness)

    def eval(self, si, wi: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        x, y = self.frame(si)
        return ltc_value(to_local(wi, x, y, si.n), a, b)

    def sample(self, si, u1: np.ndarray, u2: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """wi (3, N): a cosine direction (concentric disk, as Cycles' sample_uniform_disk) mapped by M."""
        r, phi = _concentric_disk(u1, u2)
        dx, dy = r * np.cos(phi), r * np.sin(phi)
        dz = np.sqrt(np.maximum(1.0 - dx * dx - dy * dy, 0.0))
        local = normalize(np.stack([dx - dz * b, dy, dz * a]))
        x, y = self.frame(si)
        return normalize(to_world(local, x, y, si.n))


def _concentric_disk(u1: np.ndarray, u2: np.ndarray):
    """(radius, angle) of Shirley and Chiu's concentric map of the unit square to the disk."""
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    first = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(first, a, b)
        phi = np.where(first, np.pi / 4 * (b / a), np.pi / 2 - np.pi / 4 * (a / b))
    zero = (a == 0.0) & (b == 0.0)
    return np.where(zero, 0.0, r), np.where(zero, 0.0, np.nan_to_num(phi))
