"""How much the image sampler (engine/lights/environment.py) gains over cosine sampling under the
sample sky of scripts/make_sample_hdr.py (a gradient and a small sun ~40x brighter per steradian...
the sun's texels carry most of the light): the relative MSE of the irradiance estimate
E(n) = integral L(w) max(cos, 0) dw at surfaces of random normals, per sample, for both samplers
(cosine: L pi; image: L cos / p), against the exact E (a sum over the texels).  Equal sample counts,
so the ratio is the speed-up in samples to equal error; no timing.  Printed with `-s`:

    pytest -s tests/lights/test_environment_convergence.py

Measured: see docs/world.md.  Control: a sampler that ignores the image (uniform directions) does
not reach the ratio.
"""
import numpy as np

from engine.lights.environment import EnvironmentMap, equirectangular_to_direction
from engine.sampling.warps import cosine_directions
from engine.scene.model import Environment
from scripts.make_sample_hdr import sky_pixels

N = 64                          # samples per normal
NORMALS = 48


def setup():
    m = EnvironmentMap(Environment(0, interpolation="Closest"), sky_pixels(), False)
    h, w = m.pixels.shape[:2]
    # Exact irradiance of the Closest-interpolated image: a fine midpoint sum over each texel.
    k = 8
    u = (np.arange(w * k) + 0.5) / (w * k)
    v = (np.arange(h * k) + 0.5) / (h * k)
    uu, vv = np.meshgrid(u, v)
    d, s = equirectangular_to_direction(uu.ravel(), vv.ravel())
    weight = s * (2 * np.pi * np.pi) / (w * k * h * k)
    le = m.radiance(d).mean(axis=0)
    rng = np.random.default_rng(7)
    n = rng.normal(size=(3, NORMALS))
    n /= np.sqrt((n * n).sum(axis=0))
    exact = np.array([(le * np.maximum(ni @ d, 0.0) * weight).sum() for ni in n.T])
    return m, n, exact


def rel_mse(estimates, exact):
    return float(np.mean(((estimates - exact[:, None]) ** 2).mean(axis=1) / exact ** 2))


def estimates(m, n, how, trials=200, seed=8):
    rng = np.random.default_rng(seed)
    out = np.empty((n.shape[1], trials))
    for i, ni in enumerate(n.T):
        u1, u2 = rng.random((2, trials * N))
        nn = np.repeat(ni[:, None], trials * N, axis=1)
        if how == "cosine":
            d = cosine_directions(u1, u2, nn)
            f = m.radiance(d).mean(axis=0) * np.pi
        else:
            if how == "image":
                d, pdf = m.sample(u1, u2)
            else:                                  # control: uniform directions over the sphere
                z = 1 - 2 * u1
                r = np.sqrt(1 - z * z)
                d, pdf = np.stack([r * np.cos(2 * np.pi * u2), r * np.sin(2 * np.pi * u2), z]), np.full(len(u1), 0.25 / np.pi)
            cos = np.maximum((ni[:, None] * d).sum(axis=0), 0.0)
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(pdf > 0, m.radiance(d).mean(axis=0) * cos / pdf, 0.0)
        out[i] = f.reshape(trials, N).mean(axis=1)
    return out


def test_image_sampling_beats_cosine_sampling_tenfold():
    m, n, exact = setup()
    cosine = rel_mse(estimates(m, n, "cosine"), exact)
    image = rel_mse(estimates(m, n, "image"), exact)
    uniform = rel_mse(estimates(m, n, "uniform"), exact)
    print(f"\nrelMSE at {N} samples: cosine {cosine:.4g}, image {image:.4g} (ratio {cosine / image:.1f}); "
          f"control, uniform: {uniform:.4g} (ratio {cosine / uniform:.2f})")
    assert cosine / image >= 10.0
    assert cosine / uniform < 10.0
