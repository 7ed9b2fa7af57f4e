"""Directional albedo E(mu, roughness) and average albedo E_avg(roughness) of single-scatter GGX
reflection with F = 1, for Cycles 4.x's multiple-scattering energy compensation
(engine/materials/glossy.py).

The tables are made by scripts/make_albedo_tables.py with `estimate_albedo` below (our own
Monte Carlo, fixed seeds) and stored in ggx_albedo.npz beside this file.  Their layout is
Cycles' (its lookup_table.h and app/cycles_precompute.cpp): 32 x 32 points at roughness
= i / 31 and mu = j / 31 (both clamped to at least 1e-4), alpha = roughness^2, read with
bilinear interpolation; E_avg = integral over mu of 2 mu E(mu), 32 points over roughness.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from .microfacet import g1, g2, ggx_sample_vndf

TABLE_FILE = Path(__file__).with_name("ggx_albedo.npz")
SIZE = 32
GRID_MIN = 1e-4


def grid() -> np.ndarray:
    """The table's roughness (and mu) points: i / 31 clamped to [1e-4, 1]."""
    return np.clip(np.arange(SIZE) / (SIZE - 1), GRID_MIN, 1.0)


def estimate_albedo(roughness: float, mu: float, strata: int, seed: int) -> float:
    """E(mu) of GGX reflection (F = 1, alpha = roughness^2, height-correlated G2) by visible-normal
    sampling: the mean of G2 / G1(wo) over strata x strata jittered samples (one per stratum)."""
    alpha = max(roughness * roughness, 1e-8)
    rng = np.random.default_rng(seed)
    i = np.arange(strata * strata)
    u1 = (i // strata + rng.random(i.size)) / strata
    u2 = (i % strata + rng.random(i.size)) / strata
    n = i.size
    mu = max(mu, 1e-6)
    wo = np.stack([np.full(n, np.sqrt(max(0.0, 1.0 - mu * mu))), np.zeros(n), np.full(n, mu)])
    h = ggx_sample_vndf(wo, alpha, alpha, u1, u2)
    wi = 2.0 * (wo * h).sum(axis=0) * h - wo
    ok = wi[2] > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        weight = np.where(ok, g2(wo, wi, alpha, alpha) / g1(wo, alpha, alpha), 0.0)
    return float(np.nan_to_num(weight).mean())


@lru_cache(maxsize=1)
def tables() -> tuple[np.ndarray, np.ndarray]:
    """(E (32 mu x 32 roughness), E_avg (32,)) from ggx_albedo.npz."""
    with np.load(TABLE_FILE) as data:
        return data["E"].astype(np.float64), data["E_avg"].astype(np.float64)


def _coords(x):
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0) * (SIZE - 1)
    i = np.minimum(x.astype(np.int64), SIZE - 1)
    return i, np.minimum(i + 1, SIZE - 1), x - i


def albedo(roughness, mu) -> np.ndarray:
    """E at (roughness, mu), bilinear as Cycles' lookup_table_read_2D (arrays broadcast)."""
    e, _ = tables()
    r0, r1, tr = _coords(roughness)
    m0, m1, tm = _coords(mu)
    low = (1.0 - tr) * e[m0, r0] + tr * e[m0, r1]
    high = (1.0 - tr) * e[m1, r0] + tr * e[m1, r1]
    return (1.0 - tm) * low + tm * high


def average_albedo(roughness) -> np.ndarray:
    """E_avg at roughness, linear as Cycles' lookup_table_read."""
    _, e_avg = tables()
    r0, r1, tr = _coords(roughness)
    return (1.0 - tr) * e_avg[r0] + tr * e_avg[r1]
