"""Wave Texture (ShaderNodeTexWave) as Cycles' `svm_wave` (intern/cycles/kernel/svm/wave.h).

Props: "wave_type" (BANDS, RINGS), "bands_direction" (X, Y, Z, DIAGONAL), "rings_direction"
(X, Y, Z, SPHERICAL), "wave_profile" (SIN, SAW, TRI).  Distortion adds normalised fBM of the
coordinate times Detail Scale (engine/nodes/procedural/fractal.py; Blender 3.x's fractal noise
before 4.0).
"""
from __future__ import annotations

import numpy as np

from . import fractal
from .common import choice, out_float, out_rows, points, scalar, vector, version_of
from .perlin import F32

M_PI_2_F = F32(np.pi / 2)
M_2PI_F = F32(2 * np.pi)


def wave(p, props, distortion, detail, dscale, droughness, phase, version):
    p = tuple((c + F32(0.000001)) * F32(0.999999) for c in p)
    x, y, z = p
    node = "Wave Texture"
    if choice(props, "wave_type", ("BANDS", "RINGS"), "BANDS", node) == "BANDS":
        d = choice(props, "bands_direction", ("X", "Y", "Z", "DIAGONAL"), "X", node)
        n = {"X": lambda: x * F32(20.0), "Y": lambda: y * F32(20.0), "Z": lambda: z * F32(20.0),
             "DIAGONAL": lambda: (x + y + z) * F32(10.0)}[d]()
    else:
        d = choice(props, "rings_direction", ("X", "Y", "Z", "SPHERICAL"), "X", node)
        keep = {"X": (0, 1, 1), "Y": (1, 0, 1), "Z": (1, 1, 0), "SPHERICAL": (1, 1, 1)}[d]
        rp = [c * F32(k) for c, k in zip(p, keep)]
        n = np.sqrt(rp[0] * rp[0] + rp[1] * rp[1] + rp[2] * rp[2]) * F32(20.0)
    n = n + phase
    if (distortion != 0).any():
        q = tuple(c * dscale for c in p)
        if version < (4, 0):
            noise = fractal.fractal_noise_legacy(q, detail, droughness, version)
        else:
            rough = np.clip(droughness, F32(0), F32(1)) if version < (4, 1) else droughness
            noise = fractal.fbm(q, detail, rough, np.full_like(detail, F32(2.0)), True, version)
        n = np.where(distortion != 0, n + distortion * (noise * F32(2.0) - F32(1.0)), n)
    profile = choice(props, "wave_profile", ("SIN", "SAW", "TRI"), "SIN", node)
    if profile == "SIN":
        return F32(0.5) + F32(0.5) * np.sin(n - M_PI_2_F)
    n = n / M_2PI_F
    if profile == "SAW":
        return n - np.floor(n)
    return np.abs(n - np.floor(n + F32(0.5))) * F32(2.0)


def wave_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    scale = scalar(inputs, "Scale", n, 5.0)
    p = tuple(c * scale for c in vector(inputs, "Vector", n))
    f = wave(p, props, scalar(inputs, "Distortion", n, 0.0), scalar(inputs, "Detail", n, 2.0),
             scalar(inputs, "Detail Scale", n, 1.0), scalar(inputs, "Detail Roughness", n, 0.5),
             scalar(inputs, "Phase Offset", n, 0.0), version_of(ctx))
    return {"Fac": out_float(f), "Color": out_rows(f, f, f)}


KERNELS = {"ShaderNodeTexWave": wave_texture}
