"""Gradient Texture (ShaderNodeTexGradient) as Cycles' `svm_gradient` (intern/cycles/kernel/svm/
gradient.h), saturated to [0, 1].  Prop: "gradient_type" (LINEAR, QUADRATIC, EASING, DIAGONAL,
SPHERICAL, QUADRATIC_SPHERE, RADIAL)."""
from __future__ import annotations

import numpy as np

from .common import choice, out_float, out_rows, points, vector
from .perlin import F32

TYPES = ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "SPHERICAL", "QUADRATIC_SPHERE", "RADIAL")
M_2PI_F = F32(2 * np.pi)


def gradient(x, y, z, kind):
    if kind == "LINEAR":
        return x
    if kind == "QUADRATIC":
        r = np.maximum(x, F32(0.0))
        return r * r
    if kind == "EASING":
        r = np.clip(x, F32(0.0), F32(1.0))
        t = r * r
        return F32(3.0) * t - F32(2.0) * t * r
    if kind == "DIAGONAL":
        return (x + y) * F32(0.5)
    if kind == "RADIAL":
        return np.arctan2(y, x) / M_2PI_F + F32(0.5)
    r = np.maximum(F32(0.999999) - np.sqrt(x * x + y * y + z * z), F32(0.0))
    if kind == "QUADRATIC_SPHERE":
        return r * r
    if kind == "SPHERICAL":
        return r
    raise AssertionError(kind)


def gradient_texture(inputs: dict, props: dict, ctx) -> dict:
    x, y, z = vector(inputs, "Vector", points(inputs, ctx))
    kind = choice(props, "gradient_type", TYPES, "LINEAR", "Gradient Texture")
    f = np.clip(gradient(x, y, z, kind), F32(0.0), F32(1.0))
    return {"Fac": out_float(f), "Color": out_rows(f, f, f)}


KERNELS = {"ShaderNodeTexGradient": gradient_texture}
