"""Checker Texture (ShaderNodeTexChecker) as Cycles' `svm_checker` (intern/cycles/kernel/svm/
checker.h): the parity of the integer cells of the (slightly shrunk) scaled coordinate."""
from __future__ import annotations

import numpy as np

from .common import out_float, points, scalar, vector
from .perlin import F32


def checker(p):
    xi, yi, zi = (np.abs(np.floor((c + F32(0.000001)) * F32(0.999999)).astype(np.int64)) for c in p)
    return np.where((xi % 2 == yi % 2) == (zi % 2 == 1), F32(1.0), F32(0.0))


def checker_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    scale = scalar(inputs, "Scale", n, 5.0)
    f = checker(tuple(c * scale for c in vector(inputs, "Vector", n)))
    c1 = np.asarray(vector(inputs, "Color1", n, (0.8, 0.8, 0.8)), dtype=np.float64)
    c2 = np.asarray(vector(inputs, "Color2", n, (0.2, 0.2, 0.2)), dtype=np.float64)
    return {"Fac": out_float(f), "Color": np.where(f == 1.0, c1, c2)}


KERNELS = {"ShaderNodeTexChecker": checker_texture}
