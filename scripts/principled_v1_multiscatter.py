"""Measures the Principled BSDF v1's "Multiscatter GGX" approximation (engine/materials/principled_v1.py:
single scattering with the height-correlated G2 times the energy compensation) against the random walk
Cycles 3.4 runs (Heitz et al. 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model"; Cycles'
kernel/closure/bsdf_microfacet_multi.h and _impl.h at v3.4.0, mf_sample_glossy with the interpolated
Fresnel), ported here line by line to NumPy for the measurement only.

For each roughness, incidence mu = cos(theta_o) and colour it prints the directional albedo of the
specular lobe: the walk's (mean of its sample weights) and ours (mean of PrincipledV1's sample
values for a material whose only closure is that lobe), and their ratio.  docs/materials.md quotes
the table.

  .venv/bin/python scripts/principled_v1_multiscatter.py [--samples N]
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from engine import RenderSettings  # noqa: E402
from engine.materials.glossy import fresnel_dielectric  # noqa: E402
from engine.materials.principled_v1 import PrincipledV1, specular_ior  # noqa: E402
from engine.materials.protocol import ShadingPoint  # noqa: E402
from engine.scene.model import PRINCIPLED, Material, PrincipledV1 as Inputs  # noqa: E402


# -- Cycles 3.4's random walk (bsdf_microfacet_multi.h), isotropic, vectorised ----------------------
def mf_lambda(w, alpha):
    z = w[2]
    inv_z2 = 1.0 / np.maximum(z * z, 1e-7)
    v = np.sqrt(1.0 + alpha * alpha * (w[0] ** 2 + w[1] ** 2) * inv_z2)
    v = np.where(z <= 0.0, -v, v)
    lam = 0.5 * (v - 1.0)
    return np.where(z > 0.9999, 0.0, np.where(z < -0.9999, -0.9999, lam))


def mf_g1(w, c1, lam):
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g = np.power(c1, lam)
    return np.where(w[2] > 0.9999, 1.0, np.where(w[2] < 1e-5, 0.0, g))


def mf_sample_p22_11(cos_i, rx, ry):
    special = (cos_i > 0.9999) | (np.abs(cos_i) < 1e-6)
    r = np.sqrt(rx / np.maximum(1.0 - rx, 1e-7))
    phi = 2.0 * np.pi * ry
    sx0, sy0 = r * np.cos(phi), r * np.sin(phi)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_i = np.sqrt(np.maximum(1.0 - cos_i * cos_i, 0.0))
        tan_i = sin_i / cos_i
        proj_a = 0.5 * (cos_i + 1.0)
        a = 2.0 * rx * proj_a / cos_i - 1.0
        tmp = a * a - 1.0
        bad = (proj_a < 1e-4) | (np.abs(tmp) < 1e-7)
        tmp = 1.0 / tmp
        d = np.sqrt(np.maximum(tan_i * tan_i * tmp * tmp - (a * a - tan_i * tan_i) * tmp, 0.0))
        sx2 = tan_i * tmp + d
        sx = np.where((a < 0.0) | (sx2 > 1.0 / tan_i), tan_i * tmp - d, sx2)
    u2 = np.where(ry >= 0.5, 2.0 * (ry - 0.5), 2.0 * (0.5 - ry))
    z = (u2 * (u2 * (u2 * 0.27385 - 0.73369) + 0.46341)) / (u2 * (u2 * (u2 * 0.093073 + 0.309420) - 1.0) + 0.597999)
    sy = z * np.sqrt(1.0 + sx * sx)
    sy = np.where(ry >= 0.5, sy, -sy)
    sx = np.where(bad, 0.0, sx)
    sy = np.where(bad, 0.0, sy)
    return np.where(special, sx0, sx), np.where(special, sy0, sy)


def mf_sample_vndf(wi, alpha, rx, ry):
    w11 = np.stack([alpha * wi[0], alpha * wi[1], wi[2]])
    w11 /= np.sqrt((w11 * w11).sum(axis=0))
    sx, sy = mf_sample_p22_11(w11[2], rx, ry)
    length = np.sqrt(w11[0] ** 2 + w11[1] ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(length > 0.0, w11[0] / length, 0.0)
        s = np.where(length > 0.0, w11[1] / length, 0.0)
    slope_x = alpha * (c * sx - s * sy)
    slope_y = alpha * (s * sx + c * sy)
    m = np.stack([-slope_x, -slope_y, np.ones_like(slope_x)])
    return m / np.sqrt((m * m).sum(axis=0))


def interpolate(l, h, eta, f0, cspec0):
    fh = (fresnel_dielectric(np.clip((l * h).sum(axis=0), 0.0, 1.0), np.full(l.shape[1], eta)) - f0) / (1.0 - f0)
    return cspec0[:, None] * (1.0 - fh) + fh


def walk_albedo(mu, alpha, eta, cspec0, n, rng):
    """Mean weight of mf_sample_glossy (use_fresnel) from wi at mu: the lobe's directional albedo."""
    wi = np.stack([np.full(n, np.sqrt(1.0 - mu * mu)), np.zeros(n), np.full(n, mu)])
    f0 = float(fresnel_dielectric(np.ones(1), np.full(1, eta))[0])
    throughput = np.ones((3, n))
    wr = -wi
    lam = mf_lambda(wr, alpha)
    hr, c1, g1 = np.ones(n), np.ones(n), np.zeros(n)
    alive = np.ones(n, dtype=bool)
    escaped = np.zeros((3, n))
    for order in range(10):
        u = rng.random(n)
        up, down, mid = wr[2] > 0.9999, wr[2] < -0.9999, np.abs(wr[2]) >= 1e-4
        leave = alive & (up | (~down & mid & (u > 1.0 - g1)))
        escaped[:, leave] = throughput[:, leave]
        alive &= ~leave
        c1_down = c1 * u
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            c1_mid = np.where(lam >= 0.0, 1.0, c1 * np.power(1.0 - u, -1.0 / lam))
        c1 = np.where(alive & down, c1_down, np.where(alive & ~down & mid, c1_mid, c1))
        hr = np.where(alive & (down | mid), 2.0 * np.clip(c1, 0.0, 1.0) - 1.0, hr)
        g1 = np.where(alive & (down | mid), mf_g1(wr, c1, lam), g1)
        ry, rx = rng.random(n), rng.random(n)
        wm = mf_sample_vndf(-wr, alpha, rx, ry)
        t = interpolate(-wr, wm, eta, f0, cspec0)
        throughput = np.where(alive, t if order == 0 else throughput * t, throughput)
        wr = np.where(alive, wr - 2.0 * wm * (wr * wm).sum(axis=0), wr)
        lam = mf_lambda(wr, alpha)
        c1h = np.clip(0.5 * (hr + 1.0), 0.0, 1.0)
        g1 = np.where(alive, mf_g1(wr, c1h, lam), g1)
        c1 = np.where(alive, c1h, c1)
    return escaped.mean(axis=1)


# -- ours ---------------------------------------------------------------------------------------------
def our_albedo(mu, roughness, color, metallic, n, rng):
    m = Material("M", PRINCIPLED, tuple(color), roughness=roughness, multiscatter=True,
                 principled=Inputs(metallic=metallic))
    bsdf = PrincipledV1([m], RenderSettings())
    wo = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
    up = np.array([0.0, 0.0, 1.0])

    def tile(v):
        return np.tile(v[:, None], (1, n))
    si = ShadingPoint(tile(wo), tile(up), tile(up), tile(up), tile(np.asarray(color, float)), np.zeros(n, dtype=np.int64))
    return bsdf.sample(si, rng.random(n), (rng.random(n), rng.random(n))).value.mean(axis=1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=int, default=400_000)
    args = parser.parse_args(argv)
    eta = float(specular_ior(0.5))
    cases = [("white metal", (1.0, 1.0, 1.0), 1.0), ("orange metal", (0.8, 0.45, 0.2), 1.0),
             ("dielectric (specular 0.5)", (0.0, 0.0, 0.0), 0.0)]
    print("| surface | roughness | mu | walk (Cycles 3.4) R, G, B | ours R, G, B | ours / walk (R) |")
    print("|---|---|---|---|---|---|")
    for label, color, metallic in cases:
        cspec0 = np.asarray(color) * metallic + 0.04 * (1.0 - metallic)
        for roughness in (0.4, 0.8, 1.0):
            for mu in (0.2, 0.5, 0.9):
                rng = np.random.default_rng(7)
                walk = walk_albedo(mu, roughness * roughness, eta, cspec0, args.samples, rng)
                ours = our_albedo(mu, roughness, color, metallic, args.samples, rng)
                print(f"| {label} | {roughness:g} | {mu:g} | {', '.join(f'{v:.4f}' for v in walk)} | "
                      f"{', '.join(f'{v:.4f}' for v in ours)} | {ours[0] / walk[0]:.4f} |")


if __name__ == "__main__":
    main()
