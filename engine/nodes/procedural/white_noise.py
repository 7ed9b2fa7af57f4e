"""White Noise Texture (ShaderNodeTexWhiteNoise) as Cycles' `svm_node_tex_white_noise`
(intern/cycles/kernel/svm/white_noise.h): lookup3 of the float32 bit patterns of the input, so a
result matches Cycles only where the input coordinate is bit-identical.  Prop: "noise_dimensions"."""
from __future__ import annotations

from .common import dims_of, out_float, out_rows, points, scalar, vector
from .hash import (hash_float2_to_float3, hash_float3_to_float3,
                                          hash_float4_to_float3, hash_float_n_to_float,
                                          hash_float_to_float3)


def white_noise_texture(inputs: dict, props: dict, ctx) -> dict:
    n = points(inputs, ctx)
    x, y, z = vector(inputs, "Vector", n)
    w = scalar(inputs, "W", n, 0.0)
    dims = dims_of(props, "noise_dimensions", "White Noise Texture")
    k = {1: (w,), 2: (x, y), 3: (x, y, z), 4: (x, y, z, w)}[dims]
    color = {1: hash_float_to_float3, 2: hash_float2_to_float3, 3: hash_float3_to_float3,
             4: hash_float4_to_float3}[dims](*k)
    return {"Value": out_float(hash_float_n_to_float(*k)), "Color": out_rows(*color)}


KERNELS = {"ShaderNodeTexWhiteNoise": white_noise_texture}
