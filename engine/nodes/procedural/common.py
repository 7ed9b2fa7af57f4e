"""What the procedural texture kernels share: reading sockets as float32, the Blender version,
which outputs a caller wants, and returning float64 sockets (engine/nodes value conventions:
float sockets (N,), vector and colour sockets rows (3, N))."""
from __future__ import annotations

import numpy as np

from ...core.errors import SceneError

F32 = np.float32
DEFAULT_VERSION = (5, 0)


def version_of(ctx) -> tuple:
    """(major, minor) of the Blender whose Cycles the kernel imitates (ctx.cycles_version)."""
    v = getattr(ctx, "cycles_version", None)
    return tuple(v[:2]) if v else DEFAULT_VERSION


def wanted(ctx, name: str) -> bool:
    """Whether output ``name`` is needed: ctx may carry `outputs` (identifiers in use) so that a
    kernel skips outputs that cost extra work (Noise's Color triples its cost); all by default."""
    outs = getattr(ctx, "outputs", None)
    return outs is None or name in outs


def scalar(inputs: dict, name: str, n: int, default: float) -> np.ndarray:
    """Float socket ``name`` as a float32 (N,) array (``default`` where the socket is absent)."""
    v = inputs.get(name)
    if v is None:
        return np.full(n, default, dtype=F32)
    return np.broadcast_to(np.asarray(v, dtype=F32), (n,)).copy()


def vector(inputs: dict, name: str, n: int, default=(0.0, 0.0, 0.0)):
    """Vector or colour socket ``name`` as a tuple of three float32 (N,) arrays."""
    v = inputs.get(name)
    if v is None:
        return tuple(np.full(n, c, dtype=F32) for c in default)
    v = np.asarray(v, dtype=F32)
    if v.ndim == 1:
        v = v[:, None]
    return tuple(np.broadcast_to(v[i], (n,)).copy() for i in range(3))


def points(inputs: dict, ctx):
    """The number of points of the batch (ctx.n, else the Vector input's length)."""
    n = getattr(ctx, "n", None)
    if n is None:
        v = inputs.get("Vector")
        n = np.asarray(v).shape[-1] if v is not None else 1
    return int(n)


def out_float(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64)


def out_rows(*comps) -> np.ndarray:
    return np.stack([np.asarray(c, dtype=np.float64) for c in comps])


def dims_of(props: dict, key: str, node: str = "texture") -> int:
    """1 to 4 from the dimensions enum ("1D".."4D", default "3D")."""
    return int(choice(props, key, ("1D", "2D", "3D", "4D"), "3D", node)[0])


def choice(props: dict, key: str, allowed, default: str, node: str) -> str:
    """Enum property ``key`` of ``node``; SceneError naming the node if it is none of ``allowed``."""
    value = str(props.get(key, default))
    if value not in allowed:
        raise SceneError(f"{node}: {key} {value!r} is not one of {', '.join(allowed)}")
    return value
