"""Directional albedo E(roughness, mu, eta) and average albedo E_avg(roughness, eta) of the
single-scatter GGX dielectric (reflection + refraction, F = the dielectric Fresnel, weight G2 / G1
per sample, no 1 / eta^2 scaling), for Cycles 4.x's "Multiscatter GGX" glass
(engine/materials/dielectric.py energy_scale).

The tables are made by scripts/make_glass_albedo_tables.py with `estimate_albedo` below (our own
Monte Carlo, fixed seeds) and stored in ggx_glass_albedo.npz beside this file.  Their layout is
Cycles' ggx_glass_E / ggx_glass_inv_E (its app/cycles_precompute.cpp and lookup_table.h): 16 x 16
x 16 points at roughness = i / 15, mu = j / 15 (clamped to at least 1e-4) and z = k / 15 (clamped to
[1e-4, 0.99]) with eta = (1 + z^2) / (1 - z^2) (z = sqrt((eta - 1) / (eta + 1))); one table for
eta > 1 and one for 1 / eta (leaving the glass); trilinear reads.  E_avg = integral over mu of
2 mu E(mu) on the same (roughness, z) grid.

As Cycles' shipped tables (made at its commit 34125e1d0, whose sampler did not yet reject refracted
directions on the viewer's side), the estimate keeps those samples (`refraction_side=False`); with
that our tables match Cycles' within 0.004 away from the degenerate rows mu = 0 and eta = 1
(docs/materials.md).  Cycles' kernel today rejects them, so its compensated rough glass (and ours)
does not quite reach 1 in the white furnace where they are common: rough, grazing, leaving glass.
At |eta - 1| < 1e-4 (the first z row) refraction is a delta pass-through of weight 1, so E = 1.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from .dielectric_lobe import MicrofacetDielectric, dielectric_alpha
from .fresnel import INDEX_MATCHED

TABLE_FILE = Path(__file__).with_name("ggx_glass_albedo.npz")
SIZE = 16


def grid_roughness() -> np.ndarray:
    return np.clip(np.arange(SIZE) / (SIZE - 1), 1e-4, 1.0)


def grid_z() -> np.ndarray:
    return np.clip(np.arange(SIZE) / (SIZE - 1), 1e-4, 0.99)


def eta_of_z(z):
    """The IOR (> 1) of a table coordinate z: F0 = z^4 (Cycles' ior_parametrization)."""
    z2 = np.asarray(z, dtype=np.float64) ** 2
    return (1.0 + z2) / (1.0 - z2)


def z_of_eta(eta):
    """The table coordinate of eta (either side: eta and 1 / eta have the same z)."""
    eta = np.asarray(eta, dtype=np.float64)
    return np.sqrt(np.abs((eta - 1.0) / (eta + 1.0)))


def estimate_albedo(roughness: float, mu: float, eta: float, strata: int, seed: int,
                    refraction_side: bool = False) -> float:
    """E of the GGX dielectric lobe (engine/materials/dielectric_lobe.py MicrofacetDielectric) seen at
    cos = mu with eta = n_far / n_near: the mean sample weight over strata x strata jittered
    direction samples, each with its own lobe uniform.  refraction_side=False: as Cycles' tables
    (see above); True: the lobe's albedo as it samples."""
    rng = np.random.default_rng(seed)
    i = np.arange(strata * strata)
    u1 = (i // strata + rng.random(i.size)) / strata
    u2 = (i % strata + rng.random(i.size)) / strata
    u_lobe = rng.permutation((np.arange(i.size) + rng.random(i.size)) / i.size)
    n = i.size
    mu = max(mu, 1e-6)
    wo = np.stack([np.full(n, np.sqrt(max(0.0, 1.0 - mu * mu))), np.zeros(n), np.full(n, mu)])
    alpha = np.full(n, float(dielectric_alpha(roughness)))
    if abs(eta - 1.0) < INDEX_MATCHED:
        return 1.0
    _, weight, _, _, ok = MicrofacetDielectric().sample(wo, alpha, np.full(n, eta), np.zeros(n, bool), u_lobe, u1, u2,
                                                        refraction_side=refraction_side)
    return float(np.where(ok, weight, 0.0).mean())


@lru_cache(maxsize=1)
def tables() -> dict:
    """{"E", "E_inv": (16 z x 16 mu x 16 roughness), "E_avg", "E_avg_inv": (16 z x 16 roughness)}."""
    with np.load(TABLE_FILE) as data:
        return {key: data[key].astype(np.float64) for key in ("E", "E_inv", "E_avg", "E_avg_inv")}


def _coords(x):
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0) * (SIZE - 1)
    i = np.minimum(x.astype(np.int64), SIZE - 1)
    return i, np.minimum(i + 1, SIZE - 1), x - i


def _read_2d(table, x, y):
    """Bilinear in (x = roughness, y) over table[y, x] (Cycles' lookup_table_read_2D)."""
    x0, x1, tx = _coords(x)
    y0, y1, ty = _coords(y)
    low = (1.0 - tx) * table[y0, x0] + tx * table[y0, x1]
    high = (1.0 - tx) * table[y1, x0] + tx * table[y1, x1]
    return (1.0 - ty) * low + ty * high


def albedo(roughness, mu, eta) -> np.ndarray:
    """E at (roughness, mu, eta), trilinear as Cycles' lookup_table_read_3D (arrays broadcast)."""
    t = tables()
    roughness, mu, eta = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (roughness, mu, eta)))
    z0, z1, tz = _coords(z_of_eta(eta))
    out = np.empty(roughness.shape)
    for key, mask in (("E", eta >= 1.0), ("E_inv", eta < 1.0)):
        if mask.any():
            e = t[key]
            r, m, a, b, w = roughness[mask], mu[mask], z0[mask], z1[mask], tz[mask]
            lo = _read_2d_stack(e, a, r, m)
            hi = _read_2d_stack(e, b, r, m)
            out[mask] = (1.0 - w) * lo + w * hi
    return out


def _read_2d_stack(e, zi, roughness, mu):
    x0, x1, tx = _coords(roughness)
    y0, y1, ty = _coords(mu)
    low = (1.0 - tx) * e[zi, y0, x0] + tx * e[zi, y0, x1]
    high = (1.0 - tx) * e[zi, y1, x0] + tx * e[zi, y1, x1]
    return (1.0 - ty) * low + ty * high


def average_albedo(roughness, eta) -> np.ndarray:
    """E_avg at (roughness, eta), bilinear over (roughness, z)."""
    t = tables()
    roughness, eta = np.broadcast_arrays(np.asarray(roughness, dtype=np.float64), np.asarray(eta, dtype=np.float64))
    z = z_of_eta(eta)
    return np.where(eta >= 1.0, _read_2d(t["E_avg"], roughness, z), _read_2d(t["E_avg_inv"], roughness, z))
