"""Procedural texture nodes with Cycles' results (one module per texture family); `KERNELS` maps
each node's bl_idname to its kernel (engine/nodes value conventions, see common.py)."""
from engine.nodes.procedural import noise, voronoi

KERNELS = {}
for _module in (noise, voronoi):
    KERNELS.update(_module.KERNELS)
