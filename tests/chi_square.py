"""Statistics shared by the tests: the χ² test of a sampler against its own density, with cells
pooled as Mitsuba 3's `chi2.py` and pbrt-v4's `bsdfs_test.cpp` do.

* `pooled_chi2(observed, expected)`: cells with expected counts below 5 are merged (smallest
  first), then Pearson's statistic gives the p-value.
* `sphere_chi2(sample, pdf, n)`: any sampler of directions against its density per unit solid
  angle, on a grid of (cos θ, φ) cells of equal solid angle; the expected count of a cell is the
  density integrated over it by a midpoint rule on a finer grid.  Samples with zero weight
  (`sample` returns None for them, or a direction of zeros) count in no cell, and the density's
  integral need not be 1 (a sampler that fails some of the time has a total below 1).

Every test that uses these has a control: the same harness fails a wrong sampler.
"""
from __future__ import annotations

import numpy as np
from scipy import stats

ALPHA = 0.01                 # a correct sampler fails 1 % of seeds; each test fixes its seed


def pooled_chi2(observed, expected):
    """Pool cells with expected < 5 (Mitsuba/pbrt), return (chi2 p-value, dof)."""
    order = np.argsort(expected)
    obs, exp = np.asarray(observed)[order].astype(float), np.asarray(expected)[order].astype(float)
    pooled_o, pooled_e, acc_o, acc_e = [], [], 0.0, 0.0
    for o, e in zip(obs, exp):
        acc_o += o
        acc_e += e
        if acc_e >= 5:
            pooled_o.append(acc_o)
            pooled_e.append(acc_e)
            acc_o = acc_e = 0.0
    if acc_e > 0:
        pooled_o[-1] += acc_o
        pooled_e[-1] += acc_e
    pooled_o, pooled_e = np.array(pooled_o), np.array(pooled_e)
    chi2 = ((pooled_o - pooled_e) ** 2 / pooled_e).sum()
    dof = len(pooled_o) - 1
    return stats.chi2.sf(chi2, dof), dof


def sphere_cells(directions, z_bins: int, phi_bins: int) -> np.ndarray:
    """Cell index of each unit direction (3, N) on the (z = cos θ, φ) grid over the sphere."""
    x, y, z = directions
    iz = np.clip(((z + 1.0) * 0.5 * z_bins).astype(np.int64), 0, z_bins - 1)
    phi = np.mod(np.arctan2(y, x), 2 * np.pi)
    ip = np.clip((phi / (2 * np.pi) * phi_bins).astype(np.int64), 0, phi_bins - 1)
    return iz * phi_bins + ip


def sphere_expected(pdf, z_bins: int, phi_bins: int, n: int, refine: int = 8) -> np.ndarray:
    """Expected counts of n samples per cell: pdf (directions (3, M) -> (M,) per steradian)
    integrated over each cell by the midpoint rule on refine x refine sub-cells."""
    kz, kp = z_bins * refine, phi_bins * refine
    z = -1.0 + (np.arange(kz) + 0.5) * (2.0 / kz)
    phi = (np.arange(kp) + 0.5) * (2 * np.pi / kp)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(np.maximum(1.0 - zz * zz, 0.0))
    d = np.stack([r * np.cos(pp), r * np.sin(pp), zz]).reshape(3, -1)
    density = np.asarray(pdf(d), dtype=np.float64).reshape(kz, kp)
    area = (2.0 / kz) * (2 * np.pi / kp)                  # solid angle of a sub-cell
    return n * (density * area).reshape(z_bins, refine, phi_bins, refine).sum(axis=(1, 3)).ravel()


def sphere_chi2(sample, pdf, n: int = 200_000, z_bins: int = 24, phi_bins: int = 48, seed: int = 0,
                refine: int = 8):
    """(p-value, dof) of the χ² test of `sample` against `pdf` over the sphere.

    sample(u) takes uniforms u of shape (2, n) and returns unit directions (3, n) (rows of
    zeros, or NaN, for samples that failed); pdf(d) returns the density per steradian at
    unit directions d (3, M); refine: the midpoint rule's sub-cells per cell side (steep
    densities need more)."""
    u = np.random.default_rng(seed).random((2, n))
    d = np.asarray(sample(u), dtype=np.float64)
    ok = np.isfinite(d).all(axis=0) & (np.abs(d).sum(axis=0) > 0)
    observed = np.bincount(sphere_cells(d[:, ok], z_bins, phi_bins), minlength=z_bins * phi_bins)
    expected = sphere_expected(pdf, z_bins, phi_bins, n, refine)
    return pooled_chi2(observed, expected)
