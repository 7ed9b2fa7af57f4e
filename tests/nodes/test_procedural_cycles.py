"""Procedural texture kernels (engine/nodes/procedural/) against Cycles, pixel by pixel.

Each render puts many settings of one texture node on the flat quad of tests/nodes/flat_quad.py
(one Shader AOV per setting and output), Vector = the pixel centre's object coordinate (z fixed)
and W = its x, and compares `KERNELS[bl_idname]` at the same points.  Cycles and the kernels both
compute in float32; the bound is a few float32 ulps of the values involved (TOL), except at the
few pixels where a float32 rounding difference moves a point across a cell border (Voronoi,
Checker, Brick): there at most FLIP_SHARE of the pixels may differ.  Every family has a control
that must fail: the same comparison with a wrong constant (scale off by 1 %, another metric...).
"""
import types

import numpy as np
import pytest

from engine.nodes.procedural import KERNELS

RES = 64
Z = 0.37
TOL = 2e-5                  # absolute, on values of order 1 (float32 ulp at 1: 1.2e-7)
FLIP_SHARE = 0.002          # share of pixels allowed to land in another cell (float32 borders)


def aov_name(case_index, output_index):
    """'t<case>o<output>': no AOV name ends with another (the harness finds passes by suffix)."""
    return f"t{case_index}o{output_index}"


def build(nodes, links, coord, bl_idname="", cases=None, outputs=()):
    """Blender side: one node per case, each output to an AOV named by `aov_name`."""
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coord, sep.inputs[0])
    result = {}
    for i, case in enumerate(cases.values()):
        node = nodes.new(bl_idname)
        for key, value in case.get("props", {}).items():
            setattr(node, key, value)
        sockets = {s.identifier: s for s in node.inputs}
        if "Vector" in sockets:
            links.new(coord, sockets["Vector"])
        if "W" in sockets:
            links.new(sep.outputs["X"], sockets["W"])
        for key, value in case.get("inputs", {}).items():
            sockets[key].default_value = value
        outs = {s.identifier: s for s in node.outputs}
        for j, out in enumerate(case.get("outputs", outputs)):
            result[aov_name(i, j)] = outs[out]
    return result


def compare(bl_idname, cases, outputs, version=(5, 0), blender="5.0", z=Z, resolution=RES):
    """{'<case>_<output>': (kernel values, Cycles values)} as (N, 3) arrays (floats repeated)."""
    from tests.nodes.flat_quad import render
    images, pts = render(build, resolution=resolution, blender=blender, z=z, bl_idname=bl_idname,
                         cases=cases, outputs=list(outputs))
    pairs = {}
    for i, (name, case) in enumerate(cases.items()):
        got = evaluate(bl_idname, case, pts, version)
        for j, out in enumerate(case.get("outputs", outputs)):
            g = got[out]
            g = np.repeat(g[:, None], 3, axis=1) if g.ndim == 1 else g.T
            pairs[f"{name}_{out}"] = (g, images[aov_name(i, j)].reshape(-1, 3))
    return pairs


def evaluate(bl_idname, case, pts, version=(5, 0)):
    inputs = {"Vector": pts, "W": pts[0].copy()}
    for key, value in case.get("inputs", {}).items():
        inputs[key] = np.broadcast_to(np.asarray(value, dtype=float).reshape(-1, 1)
                                      if np.ndim(value) else np.asarray(value, dtype=float),
                                      (len(value), pts.shape[1]) if np.ndim(value) else (pts.shape[1],))
    ctx = types.SimpleNamespace(n=pts.shape[1], cycles_version=version)
    return KERNELS[bl_idname](inputs, dict(case.get("props", {})), ctx)


def mismatch(got, ref, tol=TOL):
    """Share of pixels whose value differs by more than tol (relative above 1), and the worst."""
    d = np.abs(got - ref) / np.maximum(1.0, np.abs(ref))
    bad = (d > tol).any(axis=1)
    return bad.mean(), float(d.max())


def assert_agree(pairs, flips=0.0, tol=TOL):
    report = {k: mismatch(g, r, tol) for k, (g, r) in pairs.items()}
    worst = {k: v for k, v in report.items() if v[0] > flips}
    assert not worst, f"pixels off (share, max diff): {worst}"
    return report


def assert_differ(pairs, tol=TOL):
    """The control: every pair must disagree on a clear share of the pixels."""
    report = {k: mismatch(g, r, tol) for k, (g, r) in pairs.items()}
    same = {k: v for k, v in report.items() if v[0] < 0.05}
    assert not same, f"control did not fail: {same}"
