"""Procedural texture nodes with Cycles' results, one module per texture family; `KERNELS` maps
each node's bl_idname to its kernel `kernel(inputs, props, ctx) -> {output identifier: array}`
(value conventions in engine/nodes/procedural/common.py)."""
from engine.nodes.procedural import brick, checker, gradient, magic, noise, voronoi, wave, white_noise

KERNELS = {}
for _module in (noise, voronoi, wave, gradient, magic, checker, brick, white_noise):
    KERNELS.update(_module.KERNELS)
