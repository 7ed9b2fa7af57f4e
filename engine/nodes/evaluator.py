"""Runs a node program (engine/scene/programs.py) over a wavefront of hits: one kernel call per node
over all the hits of the material, as Cycles' SVM runs a shader's nodes in order.

`run(program, ctx)` gives the material input's value: (N,) for a float input, rows (3, N) for a colour.
Inputs are broadcast to full arrays before a kernel sees them (constants: (N,) or (3, N); those a kernel
broadcasts itself, engine/nodes/registry.py broadcast_inputs, as (1,) or (3, 1)), and links
convert between socket types as Cycles' svm_node_convert: colour to float is the luminance of the
running Blender's colour space (engine/nodes/converter.py luminance_weights: 3.4's and 4.x/5.0's
differ in the fifth digit), vector to float the average of the three components, float to
colour or vector a grey.  `fold(program, version)` runs what does not depend on the hit once (n = 1) at
export and returns the smaller program, or the constant the input then has.
"""
from __future__ import annotations

import numpy as np

from ..scene.programs import Link, Program, ProgramNode
from .context import NodeContext, Varying
from .registry import broadcast_inputs, kernels, offset_inputs

LUMINANCE = np.array([0.2126729, 0.7151522, 0.0721750])     # without converter.py: Blender 3.4's
THREE = ("RGBA", "VECTOR")


class UnsupportedNode(KeyError):
    """A program names a node type no kernel module provides (the exporter replaces such nodes by the
    socket's default value, so a program from the exporter has none)."""


def luminance(cycles_version) -> np.ndarray:
    """The colour-to-float weights of the running Blender (Cycles' rgb_to_y)."""
    try:
        from .converter import luminance_weights
    except ImportError:
        return LUMINANCE
    return luminance_weights(cycles_version)


def convert(value, source: str, target: str, n: int, weights=LUMINANCE):
    """`value` of socket type `source` as type `target` (full arrays of n points); `weights`: colour to
    float (`luminance`)."""
    value = np.asarray(value, dtype=np.float64)
    if target in THREE:
        if value.ndim == 1:
            return np.broadcast_to(value, (3, n)).copy() if value.shape[0] == n else np.repeat(value[:, None], n, 1)
        return value
    if value.ndim == 2:
        if source == "RGBA":
            return weights @ value
        return value.mean(axis=0)
    return value


def constant(value, n: int):
    """A constant input as a full array: (n,) for a number, rows (3, n) for 3 or 4 numbers (alpha dropped)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        v = np.asarray(value, dtype=np.float64).reshape(-1)
        if v.size == 1:
            return np.full(n, float(v[0]))
        return np.repeat(v[:3, None], n, axis=1)
    return np.full(n, float(value))


def run_nodes(program: Program, ctx: NodeContext, table=None):
    """The outputs of every node (a list of {output identifier: array})."""
    table = kernels() if table is None else table
    weights = luminance(ctx.cycles_version)
    outputs = []
    for node in program.nodes:
        kernel = table.get(node.kind)
        if kernel is None:
            raise UnsupportedNode(node.kind)
        one = broadcast_inputs(node.kind)          # constants the kernel broadcasts: one value, not n
        inputs = {key: (convert(outputs[v.node][v.output], v.source, v.target, ctx.n, weights) if isinstance(v, Link)
                        else constant(v, 1 if key in one else ctx.n)) for key, v in node.inputs.items()}
        for key in offset_inputs(node.kind):
            if isinstance(node.inputs.get(key), Link) and ctx.shifted is not None:
                inputs[f"_{key}_at"] = _at_offsets(upstream(program, node.inputs[key]), ctx, table)
        outputs.append(kernel(inputs, node.props, ctx))
    return outputs


def upstream(program: Program, link: Link) -> Program:
    """The program of the nodes feeding `link` (an input of a node of `program`), its output that link's."""
    needed, stack = set(), [link.node]
    while stack:
        i = stack.pop()
        if i not in needed:
            needed.add(i)
            stack += [v.node for v in program.nodes[i].inputs.values() if isinstance(v, Link)]
    order = sorted(needed)
    index = {old: new for new, old in enumerate(order)}
    nodes = [ProgramNode(program.nodes[i].kind, program.nodes[i].name, program.nodes[i].props,
                         {k: (Link(index[v.node], v.output, v.source, v.target) if isinstance(v, Link) else v)
                          for k, v in program.nodes[i].inputs.items()}) for i in order]
    return Program(nodes, (index[link.node], link.output, link.source), link.target, list(program.uv_maps))


def _at_offsets(sub: Program, ctx: NodeContext, table):
    """offset rows (3, N) -> the value of `sub` at the points shifted by it (ctx.shifted)."""
    return lambda offset: run(sub, ctx.shifted(offset), table)


def run(program: Program, ctx: NodeContext, table=None) -> np.ndarray:
    """The program's value at the ctx.n points: (N,) for type VALUE, rows (3, N) for RGBA / VECTOR."""
    outputs = run_nodes(program, ctx, table)
    node, output, source = program.output
    return convert(outputs[node][output], source, program.type, ctx.n, luminance(ctx.cycles_version))


def _scalar(value):
    """A folded output (n = 1) as a constant input: a float or a tuple of 3."""
    value = np.asarray(value, dtype=np.float64)
    if value.ndim == 2:
        return tuple(float(c) for c in value[:3, 0])
    return float(value.reshape(-1)[0])


def fold(program: Program, cycles_version=(5, 0), table=None):
    """(the program with every node that does not depend on the hit evaluated once and its outputs
    made constants of the nodes that read them, unread nodes dropped; or None) and (the constant value
    of the input when the whole program is constant; else None)."""
    table = kernels() if table is None else table
    ctx = NodeContext(1, cycles_version)
    weights = luminance(cycles_version)
    outputs: list = []

    def known(v):
        """Whether the linked output has a constant value (a node may give some outputs, not others)."""
        return outputs[v.node] is not None and v.output in outputs[v.node]
    for node in program.nodes:
        links = [v for v in node.inputs.values() if isinstance(v, Link)]
        if not all(known(v) for v in links) or node.kind not in table:
            outputs.append(None)
            continue
        inputs = {key: (convert(outputs[v.node][v.output], v.source, v.target, 1, weights) if isinstance(v, Link)
                        else constant(v, 1)) for key, v in node.inputs.items()}
        try:
            outputs.append(table[node.kind](inputs, node.props, ctx))
        except Varying:
            outputs.append(None)
    last, output, source = program.output
    if outputs[last] is not None and output in outputs[last]:
        return None, _scalar(convert(outputs[last][output], source, program.type, 1, weights))
    # Keep the varying nodes the output reads; constants feed them as values.
    needed, stack = set(), [last]
    while stack:
        i = stack.pop()
        if i in needed:
            continue
        needed.add(i)
        stack += [v.node for v in program.nodes[i].inputs.values() if isinstance(v, Link) and not known(v)]
    order = sorted(needed)
    index = {old: new for new, old in enumerate(order)}
    nodes = []
    for old in order:
        node = program.nodes[old]
        inputs = {}
        for key, v in node.inputs.items():
            if isinstance(v, Link) and known(v):
                inputs[key] = _scalar(convert(outputs[v.node][v.output], v.source, v.target, 1, weights))
            elif isinstance(v, Link):
                inputs[key] = Link(index[v.node], v.output, v.source, v.target)
            else:
                inputs[key] = v
        nodes.append(ProgramNode(node.kind, node.name, node.props, inputs))
    return Program(nodes, (index[last], output, source), program.type, list(program.uv_maps)), None
