"""Procedural texture nodes with Cycles' results, one module per texture family; `KERNELS` maps
each node's bl_idname to its kernel `kernel(inputs, props, ctx) -> {output identifier: array}`
(value conventions in engine/nodes/procedural/common.py).  The merged kernels run with NumPy's
floating-point warnings off: a non-finite or huge coordinate gives what the float32 arithmetic
gives (as in Cycles), not a warning per batch."""
import functools

import numpy as np

from . import (brick, checker, gradient, magic, musgrave, noise, voronoi, wave,
                                     white_noise)


def _quiet(kernel):
    @functools.wraps(kernel)
    def run(inputs, props, ctx):
        with np.errstate(all="ignore"):
            return kernel(inputs, props, ctx)
    return run


KERNELS = {}
for _module in (noise, musgrave, voronoi, wave, gradient, magic, checker, brick, white_noise):
    KERNELS.update({name: _quiet(kernel) for name, kernel in _module.KERNELS.items()})
