"""Helpers of the node-kernel tests in tests/nodes/: input values that vary over the flat
quad (tests/nodes/flat_quad.py) built from the snapped coordinate with exact float32 operations, their
NumPy twins, and the per-pixel comparison of a kernel's output with Cycles' image."""
from types import SimpleNamespace

import numpy as np

F32 = np.float32


def ctx(n, version=(5, 0)):
    """A minimal NodeContext stand-in: n points, the Blender version."""
    return SimpleNamespace(n=int(n), cycles_version=tuple(version))


def math_node(nodes, links, op, a, b=None, c=None):
    node = nodes.new("ShaderNodeMath")
    node.operation = op
    for i, v in enumerate((a, b, c)):
        if v is None:
            continue
        if isinstance(v, (int, float)):
            node.inputs[i].default_value = float(v)
        else:
            links.new(v, node.inputs[i])
    return node.outputs[0]


def scalars(nodes, links, coord):
    """Sockets a = 3x, b = 2y + 0.3, c = 0.5x + (0.25y + 0.2) (every product exact in float32)."""
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord, sep.inputs[0])
    x, y = sep.outputs[0], sep.outputs[1]
    a = math_node(nodes, links, "MULTIPLY", x, 3.0)
    b = math_node(nodes, links, "MULTIPLY_ADD", y, 2.0, 0.3)
    c = math_node(nodes, links, "MULTIPLY_ADD", x, 0.5, math_node(nodes, links, "MULTIPLY_ADD", y, 0.25, 0.2))
    return a, b, c


def scalar_values(points):
    """The float32 values of scalars() at the pixel centres, as float64 (N,) arrays."""
    x, y = points[0].astype(F32), points[1].astype(F32)
    a = x * F32(3.0)
    b = y * F32(2.0) + F32(0.3)
    c = x * F32(0.5) + (y * F32(0.25) + F32(0.2))
    return a.astype(np.float64), b.astype(np.float64), c.astype(np.float64)


def combine(nodes, links, x, y, z):
    node = nodes.new("ShaderNodeCombineXYZ")
    for i, v in enumerate((x, y, z)):
        if isinstance(v, (int, float)):
            node.inputs[i].default_value = float(v)
        else:
            links.new(v, node.inputs[i])
    return node.outputs[0]


def inputs_of(kept, linked, n):
    """A kernel's inputs: the kept socket defaults as full arrays, replaced by `linked` {identifier: array}."""
    out = {}
    for key, value in kept["inputs"].items():
        v = np.asarray(value, dtype=np.float64)
        out[key] = np.repeat(v[:, None], n, axis=1) if v.ndim else np.full(n, float(v))
    out.update(linked)
    return out


def pixels(image):
    """An AOV / emission image (H, W, 3) as rows (3, N) in coordinates() order."""
    return image.reshape(-1, 3).T


def worst(image, value, rtol=2e-6, atol=2e-6):
    """The largest error of `value` ((N,) grey or rows (3, N)) against Cycles' image, in units of
    the tolerance atol + rtol |cycles| (<= 1 passes)."""
    got = pixels(image)
    want = np.broadcast_to(value, got.shape) if np.ndim(value) == 2 else np.broadcast_to(value, (3, got.shape[1]))
    err = np.abs(got - want) / (atol + rtol * np.abs(got))
    return float(np.nanmax(np.where(np.isnan(got) & np.isnan(want), 0.0, err)))


def sock(node, identifier, outputs=False):
    """The input (or output) socket with this identifier, enabled or not (Blender 5.0 finds a
    disabled socket by name only through its identifier)."""
    for s in (node.outputs if outputs else node.inputs):
        if s.identifier == identifier:
            return s
    raise KeyError(f"{node.bl_idname} has no socket {identifier!r}")
