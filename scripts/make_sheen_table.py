"""Make engine/materials/sheen_ltc.npz: the microfiber sheen's LTC table of engine/materials/sheen.py,
read from Cycles' source (its src/scene/shader.tables, `table_sheen_ltc`, Apache-2.0, Blender
Foundation), and print its self-checks.

    python scripts/make_sheen_table.py PATH/TO/cycles/src/scene/shader.tables

The table is not ours: Zeltner, Burley and Chiang ("Practical Multiple-Scattering Sheen Using
Linearly Transformed Cosines", 2022) fitted it to Monte Carlo simulations of a volumetric layer of
fibres; reproducing that reference (the fibre medium, its density and the fit) is beyond this
project, so we take the fitted numbers and check what can be checked independently: each LTC is a
normalised density over the hemisphere (its integral 1 where the albedo is above 0), and the
layout (32 x 32 points: rows roughness i / 31, columns mu = cos(theta) j / 31; three blocks a, b
and the albedo R) reads back the values the Cycles source lists.
"""
from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from engine.materials.sheen import SIZE, TABLE_FILE, ltc_value  # noqa: E402


def read_cycles_table(path: Path) -> np.ndarray:
    """The 3 x 32 x 32 floats of `table_sheen_ltc` in a Cycles shader.tables file."""
    text = path.read_text()
    match = re.search(r"table_sheen_ltc\[(\d+)\]\s*=\s*\{(.*?)\};", text, re.S)
    if match is None:
        raise SystemExit(f"{path}: no table_sheen_ltc")
    values = np.array([float(v.rstrip("f")) for v in re.findall(r"[-+0-9.eE]+f", match.group(2))])
    if int(match.group(1)) != 3 * SIZE * SIZE or values.size != 3 * SIZE * SIZE:
        raise SystemExit(f"{path}: table_sheen_ltc has {values.size} values, expected {3 * SIZE * SIZE}")
    return values.reshape(3, SIZE, SIZE)


def hemisphere_integral(a: float, b: float, n: int = 400) -> float:
    """The integral of the LTC density over the upper hemisphere (midpoint rule in cos and phi)."""
    mu = (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m * m)
    local = np.stack([s * np.cos(p), s * np.sin(p), m]).reshape(3, -1)
    val = ltc_value(local, np.full(local.shape[1], a), np.full(local.shape[1], b))
    return float(val.sum() * (1.0 / n) * (2 * np.pi / (2 * n)))     # d omega = d mu d phi


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tables", type=Path, help="Cycles' src/scene/shader.tables")
    args = parser.parse_args()
    t = read_cycles_table(args.tables)
    a, b, albedo = t
    worst = 0.0
    for i in range(0, SIZE, 3):
        for j in range(1, SIZE, 3):
            if albedo[i, j] > 1e-5 and abs(a[i, j]) > 1e-5:
                worst = max(worst, abs(hemisphere_integral(a[i, j], b[i, j]) - 1.0))
    print(f"LTC densities integrate to 1 within {worst:.2e} (every third cell)")
    for r in (0.25, 0.5, 1.0):
        i = round(r * (SIZE - 1))
        print(f"roughness {i}/31: albedo at mu = 1, 0.5, 0.1: "
              + ", ".join(f"{albedo[i, round(mu * (SIZE - 1))]:.5f}" for mu in (1.0, 0.5, 0.1)))
    np.savez_compressed(TABLE_FILE, a=a.astype(np.float32), b=b.astype(np.float32), albedo=albedo.astype(np.float32))
    print(f"wrote {TABLE_FILE}")


if __name__ == "__main__":
    main()
