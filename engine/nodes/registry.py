"""Every node kernel, by Blender node type: the KERNELS of engine/nodes/inputs.py, image.py, color.py,
math.py, converter.py, normals.py, vector_transform.py and the procedural/ package, merged.  A module
that is not there means its nodes are unsupported (the exporter then warns and uses the socket's default value)."""
from __future__ import annotations

import importlib

KERNEL_MODULES = ("inputs", "image", "color", "math", "converter", "procedural", "normals", "vector_transform")
_TABLE: dict | None = None
_OFFSETS: dict = {}
_BROADCAST: dict = {}


def kernels() -> dict:
    """{bl_idname: kernel(inputs, props, ctx) -> {output identifier: array}} of every module there is."""
    global _TABLE
    if _TABLE is None:
        table = {}
        for name in KERNEL_MODULES:
            full = f"{__package__}.{name}"
            try:
                module = importlib.import_module(full)
            except ModuleNotFoundError as exc:
                if exc.name != full:
                    raise
                continue
            table.update(getattr(module, "KERNELS", {}))
            _OFFSETS.update(getattr(module, "OFFSET_INPUTS", {}))
            _BROADCAST.update(getattr(module, "BROADCAST_INPUTS", {}))
        _TABLE = table
    return _TABLE


def offset_inputs(kind: str) -> tuple:
    """The inputs of node type `kind` that its kernel also reads at shifted points (a module's
    OFFSET_INPUTS, e.g. Bump's Height: engine/nodes/evaluator.py gives the kernel "_Height_at")."""
    kernels()
    return _OFFSETS.get(kind, ())


def broadcast_inputs(kind: str) -> tuple:
    """The inputs of node type `kind` whose constants its kernel takes as one value, (1,) or (3, 1), and
    broadcasts against its other inputs (a module's BROADCAST_INPUTS): the same numbers as full arrays
    of that value, without making them (engine/nodes/evaluator.py run_nodes)."""
    kernels()
    return _BROADCAST.get(kind, ())


def supported(kind: str) -> bool:
    return kind in kernels()
