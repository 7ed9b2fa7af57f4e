"""Make engine/materials/ggx_albedo.npz: the GGX albedo tables of engine/materials/albedo_tables.py
by our own Monte Carlo (fixed seeds, so the file is reproducible), and print the check against
published values (docs: the albedo tables' check).

    python scripts/make_albedo_tables.py [--strata 256]

E[j, i] = E(mu_j, roughness_i) on Cycles' 32 x 32 grid; E_avg[i] = integral of 2 mu E(mu) d mu by
64-point Gauss-Legendre quadrature in mu, each node by the same estimator.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.materials.albedo_tables import SIZE, TABLE_FILE, estimate_albedo, grid  # noqa: E402

QUADRATURE_NODES = 64


def make(strata: int):
    rough = grid()
    e = np.empty((SIZE, SIZE))
    for i, r in enumerate(rough):
        for j, mu in enumerate(rough):
            e[j, i] = estimate_albedo(r, mu, strata, seed=1000 * i + j)
    x, w = np.polynomial.legendre.leggauss(QUADRATURE_NODES)
    mus, weights = 0.5 * (x + 1.0), 0.5 * w
    e_avg = np.array([sum(wk * 2.0 * mk * estimate_albedo(r, mk, strata // 2, seed=500_000 + 1000 * i + k)
                          for k, (mk, wk) in enumerate(zip(mus, weights))) for i, r in enumerate(rough)])
    return np.clip(e, 0.0, 1.0), np.clip(e_avg, 0.0, 1.0)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--strata", type=int, default=256, help="strata per axis (samples = strata^2 per cell)")
    args = parser.parse_args()
    e, e_avg = make(args.strata)
    np.savez_compressed(TABLE_FILE, E=e.astype(np.float32), E_avg=e_avg.astype(np.float32))
    print(f"wrote {TABLE_FILE}")


if __name__ == "__main__":
    main()
