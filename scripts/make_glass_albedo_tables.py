"""Make engine/materials/ggx_glass_albedo.npz: the GGX glass albedo tables of
engine/materials/glass_albedo.py by our own Monte Carlo (fixed seeds, so the file is reproducible).

    python scripts/make_glass_albedo_tables.py [--strata 64]

E[k, j, i] = E(roughness_i, mu_j, eta(z_k)) on Cycles' 16 x 16 x 16 grid, E_inv the same at 1 / eta;
E_avg[k, i] = integral of 2 mu E(mu) d mu by 32-point Gauss-Legendre quadrature in mu, each node by
the same estimator.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.materials.glass_albedo import (SIZE, TABLE_FILE, estimate_albedo, eta_of_z, grid_roughness,  # noqa: E402
                                           grid_z)

QUADRATURE_NODES = 32


def make(strata: int):
    rough, mus, zs = grid_roughness(), grid_roughness(), grid_z()
    x, w = np.polynomial.legendre.leggauss(QUADRATURE_NODES)
    nodes, weights = 0.5 * (x + 1.0), 0.5 * w
    out = {}
    for name, invert, base in (("E", False, 0), ("E_inv", True, 5_000_000)):
        e = np.empty((SIZE, SIZE, SIZE))
        e_avg = np.empty((SIZE, SIZE))
        for k, z in enumerate(zs):
            eta = float(eta_of_z(z))
            eta = 1.0 / eta if invert else eta
            for i, r in enumerate(rough):
                for j, mu in enumerate(mus):
                    e[k, j, i] = estimate_albedo(r, mu, eta, strata, seed=base + 10_000 * k + 100 * i + j)
                e_avg[k, i] = sum(wq * 2.0 * mq * estimate_albedo(r, mq, eta, strata // 2,
                                                                   seed=base + 2_000_000 + 10_000 * k + 100 * i + q)
                                  for q, (mq, wq) in enumerate(zip(nodes, weights)))
            print(f"{name} z={z:.3f} eta={eta:.3f}: E(r=0.5, mu=1)={e[k, -1, 7]:.4f} E_avg(r=1)={e_avg[k, -1]:.4f}",
                  flush=True)
        out[name] = np.clip(e, 0.0, 1.0)
        out[name.replace("E", "E_avg")] = np.clip(e_avg, 0.0, 1.0)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--strata", type=int, default=64, help="strata per axis (samples = strata^2 per cell)")
    args = parser.parse_args()
    tables = make(args.strata)
    np.savez_compressed(TABLE_FILE, **{k: v.astype(np.float32) for k, v in tables.items()})
    print(f"wrote {TABLE_FILE}")


if __name__ == "__main__":
    main()
