"""Magic Texture (ShaderNodeTexMagic) as Cycles' `svm_magic` (intern/cycles/kernel/svm/magic.h):
nested sines and cosines, float32.  Prop: "turbulence_depth" (int 0..10); Fac is the colour's
average."""
from __future__ import annotations

import numpy as np

from .common import out_float, out_rows, points, scalar, vector
from .perlin import F32

M_2PI_F = F32(2 * np.pi)


def magic(p, scale, depth, distortion):
    px, py, pz = (np.fmod(c, M_2PI_F) for c in p)
    x = np.sin((px + py + pz) * F32(5.0) * scale)
    y = np.cos((-px + py - pz) * F32(5.0) * scale)
    z = -np.cos((-px - py + pz) * F32(5.0) * scale)
    d = distortion
    if depth > 0:
        x, y, z = x * d, y * d, z * d
        y = -np.cos(x - y + z) * d
        steps = [
            ("x", lambda x, y, z: np.cos(x - y - z)),
            ("z", lambda x, y, z: np.sin(-x - y - z)),
            ("x", lambda x, y, z: -np.cos(-x + y - z)),
            ("y", lambda x, y, z: -np.sin(-x + y + z)),
            ("y", lambda x, y, z: -np.cos(-x + y + z)),
            ("x", lambda x, y, z: np.cos(x + y + z)),
            ("z", lambda x, y, z: np.sin(x + y - z)),
            ("x", lambda x, y, z: -np.cos(-x - y + z)),
            ("y", lambda x, y, z: -np.sin(x - y + z)),
        ]
        for level, (axis, fn) in enumerate(steps, start=2):
            if depth < level:
                break
            v = fn(x, y, z) * d
            if axis == "x":
                x = v
            elif axis == "y":
                y = v
            else:
                z = v
    nz = distortion != 0
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = distortion * F32(2.0)
        x, y, z = (np.where(nz, c / d2, c) for c in (x, y, z))
    return F32(0.5) - x, F32(0.5) - y, F32(0.5) - z


def magic_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    p = vector(inputs, "Vector", n)
    color = magic(p, scalar(inputs, "Scale", n, 5.0), int(props.get("turbulence_depth", 2)),
                  scalar(inputs, "Distortion", n, 1.0))
    fac = (color[0] + color[1] + color[2]) * F32(1.0 / 3.0)
    return {"Fac": out_float(fac), "Color": out_rows(*color)}


KERNELS = {"ShaderNodeTexMagic": magic_texture}
