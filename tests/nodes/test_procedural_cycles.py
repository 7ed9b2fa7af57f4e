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
    swizzled = {}
    result = {}
    for i, case in enumerate(cases.values()):
        node = nodes.new(bl_idname)
        for key, value in case.get("props", {}).items():
            setattr(node, key, value)
        sockets = {s.identifier: s for s in node.inputs}
        if "Vector" in sockets:
            links.new(_swizzle(nodes, links, sep, case.get("swizzle"), swizzled) or coord, sockets["Vector"])
        if "W" in sockets:
            links.new(sep.outputs["X"], sockets["W"])
        for key, value in case.get("inputs", {}).items():
            sockets[key].default_value = value
        outs = {s.identifier: s for s in node.outputs}
        for j, out in enumerate(case.get("outputs", outputs)):
            result[aov_name(i, j)] = outs[out]
    return result


def _swizzle(nodes, links, sep, order, made):
    """Vector (c[order[0]], c[order[1]], c[order[2]]) of the coordinate c, by Combine XYZ (exact
    copies of float32 components: a 3-D texture then varies along its z too); None: c itself."""
    if not order:
        return None
    key = tuple(order)
    if key not in made:
        comb = nodes.new("ShaderNodeCombineXYZ")
        for axis, src in zip("XYZ", key):
            links.new(sep.outputs["XYZ"[src]], comb.inputs[axis])
        made[key] = comb.outputs[0]
    return made[key]


def render_cases(bl_idname, cases, outputs, blender="5.0", z=Z, resolution=RES):
    """Cycles' values {'<case>_<output>': (N, 3)} and the pixel-centre points (3, N)."""
    from tests.nodes.flat_quad import render
    images, pts = render(build, resolution=resolution, blender=blender, z=z, bl_idname=bl_idname,
                         cases=cases, outputs=list(outputs))
    refs = {}
    for i, (name, case) in enumerate(cases.items()):
        for j, out in enumerate(case.get("outputs", outputs)):
            refs[f"{name}_{out}"] = images[aov_name(i, j)].reshape(-1, 3)
    return refs, pts


def kernel_values(bl_idname, cases, outputs, pts, version=(5, 0)):
    """The kernels' values at the points, keyed and shaped like `render_cases`."""
    values = {}
    for name, case in cases.items():
        got = evaluate(bl_idname, case, pts, version)
        for out in case.get("outputs", outputs):
            g = got[out]
            values[f"{name}_{out}"] = np.repeat(g[:, None], 3, axis=1) if g.ndim == 1 else g.T
    return values


def compare(bl_idname, cases, outputs, version=(5, 0), blender="5.0", z=Z, resolution=RES):
    """{'<case>_<output>': (kernel values, Cycles values)} as (N, 3) arrays (floats repeated)."""
    refs, pts = render_cases(bl_idname, cases, outputs, blender, z, resolution)
    got = kernel_values(bl_idname, cases, outputs, pts, version)
    return {k: (got[k], refs[k]) for k in refs}


def evaluate(bl_idname, case, pts, version=(5, 0)):
    vec = pts[list(case["swizzle"])] if case.get("swizzle") else pts
    inputs = {"Vector": vec, "W": pts[0].copy()}
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


def assert_differ(pairs, tol=TOL, min_share=0.05):
    """The control: every pair must disagree on a clear share of the pixels (outputs that are
    constant in Cycles' image, such as Radius of an F1 Voronoi, carry nothing and are skipped)."""
    pairs = {k: (g, r) for k, (g, r) in pairs.items() if np.ptp(r) > 0}
    assert pairs
    report = {k: mismatch(g, r, tol) for k, (g, r) in pairs.items()}
    same = {k: v for k, v in report.items() if v[0] < min_share}
    assert not same, f"control did not fail: {same}"


def with_inputs(cases, **changes):
    """The cases with inputs scaled (name=factor) where present or default-valued."""
    out = {}
    for name, case in cases.items():
        c = {"props": dict(case.get("props", {})), "inputs": dict(case.get("inputs", {}))}
        for key in ("outputs", "swizzle"):
            if key in case:
                c[key] = case[key]
        for key, factor in changes.items():
            c["inputs"][key] = c["inputs"].get(key, DEFAULT_SCALE) * factor
        out[name] = c
    return out


def with_props(cases, **props):
    return {name: {**case, "props": {**case.get("props", {}), **props}} for name, case in cases.items()}


def check_family(bl_idname, cases, outputs, control, tol=TOL, flips=0.0, blender="5.0",
                 version=(5, 0), min_share=0.05):
    """Kernel = Cycles on every case and output; the control cases must not be."""
    refs, pts = render_cases(bl_idname, cases, outputs, blender)
    got = kernel_values(bl_idname, cases, outputs, pts, version)
    report = assert_agree({k: (got[k], refs[k]) for k in refs}, flips, tol)
    ctrl_cases, ctrl_version, ctrl_pts = control
    ctrl = kernel_values(bl_idname, ctrl_cases, outputs, pts if ctrl_pts is None else ctrl_pts,
                         ctrl_version or version)
    assert_differ({k: (ctrl[k], refs[k]) for k in ctrl if k in refs}, tol, min_share)
    return report


DEFAULT_SCALE = 5.0

NOISE_50 = {
    "n3": {"props": {"noise_dimensions": "3D"}, "inputs": {"Scale": 3.0, "Detail": 2.0}},
    "n2": {"props": {"noise_dimensions": "2D"}, "inputs": {"Scale": 4.0, "Detail": 3.5, "Roughness": 0.6}},
    "n1": {"props": {"noise_dimensions": "1D"}, "inputs": {"Scale": 2.0, "Detail": 1.0}},
    "n4": {"props": {"noise_dimensions": "4D"},
           "inputs": {"Scale": 3.0, "Detail": 2.3, "Distortion": 0.5}},
    "ridged": {"props": {"noise_type": "RIDGED_MULTIFRACTAL"},
               "inputs": {"Scale": 2.0, "Detail": 4.0, "Offset": 1.0, "Gain": 2.0}},
    "hybrid": {"props": {"noise_type": "HYBRID_MULTIFRACTAL", "noise_dimensions": "4D"},
               "inputs": {"Scale": 2.0, "Detail": 3.3, "Offset": 0.5, "Gain": 1.5}},
    "hetero": {"props": {"noise_type": "HETERO_TERRAIN", "noise_dimensions": "2D"},
               "inputs": {"Scale": 2.0, "Detail": 2.5, "Offset": 0.3}},
    "multi": {"props": {"noise_type": "MULTIFRACTAL", "noise_dimensions": "1D"},
              "inputs": {"Scale": 2.0, "Detail": 2.5}},
    "raw": {"props": {"normalize": False}, "inputs": {"Scale": 6.0, "Detail": 5.0, "Lacunarity": 2.5}},
    "xzy": {"swizzle": (0, 2, 1), "inputs": {"Scale": 3.0, "Detail": 3.0, "Distortion": 1.0}},
    "yxx": {"swizzle": (1, 0, 0), "props": {"noise_dimensions": "4D", "noise_type": "HETERO_TERRAIN"},
            "inputs": {"Scale": 2.0, "Detail": 2.0, "Offset": 0.2}},
}
NOISE_34 = {k: NOISE_50[k] for k in ("n3", "n2", "n1", "n4")}
MUSGRAVE_34 = {
    "fbm": {"props": {"musgrave_type": "FBM"}, "inputs": {"Scale": 3.0, "Detail": 2.5}},
    "mf": {"props": {"musgrave_type": "MULTIFRACTAL", "musgrave_dimensions": "2D"},
           "inputs": {"Scale": 2.0, "Detail": 3.0, "Dimension": 1.5}},
    "rm": {"props": {"musgrave_type": "RIDGED_MULTIFRACTAL"},
           "inputs": {"Scale": 2.0, "Detail": 4.0, "Offset": 1.0, "Gain": 2.0}},
    "hm": {"props": {"musgrave_type": "HYBRID_MULTIFRACTAL", "musgrave_dimensions": "4D"},
           "inputs": {"Scale": 2.0, "Detail": 3.3, "Offset": 0.5, "Gain": 1.5}},
    "ht": {"props": {"musgrave_type": "HETERO_TERRAIN", "musgrave_dimensions": "1D"},
           "inputs": {"Scale": 2.0, "Detail": 2.5, "Offset": 0.3, "Lacunarity": 2.5}},
}
VORONOI_METRIC = {      # cases whose metric matters (2-D to 4-D distances)
    "f1e3": {"props": {"feature": "F1"}, "inputs": {"Scale": 3.0}},
    "f1m2": {"props": {"feature": "F1", "distance": "MANHATTAN", "voronoi_dimensions": "2D"},
             "inputs": {"Scale": 4.0}},
    "f1c4": {"props": {"feature": "F1", "distance": "CHEBYCHEV", "voronoi_dimensions": "4D"},
             "inputs": {"Scale": 3.0}},
    "f1k3": {"props": {"feature": "F1", "distance": "MINKOWSKI"}, "inputs": {"Scale": 3.0, "Exponent": 1.5}},
    "f2e3": {"props": {"feature": "F2"}, "inputs": {"Scale": 3.0, "Randomness": 0.8}},
    "sm3": {"props": {"feature": "SMOOTH_F1"}, "inputs": {"Scale": 3.0, "Smoothness": 0.6}},
    "sm2": {"props": {"feature": "SMOOTH_F1", "voronoi_dimensions": "2D", "distance": "MANHATTAN"},
            "inputs": {"Scale": 3.0}},
    "xzy": {"swizzle": (0, 2, 1), "props": {"feature": "F2", "distance": "MINKOWSKI"},
            "inputs": {"Scale": 4.0, "Exponent": 3.0}},
    "yzx": {"swizzle": (1, 2, 0), "props": {"feature": "SMOOTH_F1", "distance": "CHEBYCHEV"},
            "inputs": {"Scale": 3.0}},
}
VORONOI_OTHER = {
    "f1d1": {"props": {"feature": "F1", "voronoi_dimensions": "1D"}, "inputs": {"Scale": 4.0}},
    "de3": {"props": {"feature": "DISTANCE_TO_EDGE"}, "inputs": {"Scale": 3.0}},
    "de1": {"props": {"feature": "DISTANCE_TO_EDGE", "voronoi_dimensions": "1D"}, "inputs": {"Scale": 5.0}},
    "de4": {"props": {"feature": "DISTANCE_TO_EDGE", "voronoi_dimensions": "4D"}, "inputs": {"Scale": 2.0}},
    "ns3": {"props": {"feature": "N_SPHERE_RADIUS"}, "inputs": {"Scale": 3.0}},
    "ns2": {"props": {"feature": "N_SPHERE_RADIUS", "voronoi_dimensions": "2D"}, "inputs": {"Scale": 4.0}},
    "ns1": {"props": {"feature": "N_SPHERE_RADIUS", "voronoi_dimensions": "1D"}, "inputs": {"Scale": 4.0}},
    "dex": {"swizzle": (0, 2, 1), "props": {"feature": "DISTANCE_TO_EDGE"}, "inputs": {"Scale": 4.0}},
    "nsx": {"swizzle": (2, 0, 1), "props": {"feature": "N_SPHERE_RADIUS"}, "inputs": {"Scale": 4.0}},
}
VORONOI_FRACTAL = {     # Blender 4.0+
    "fr3": {"props": {"feature": "F1", "normalize": True}, "inputs": {"Scale": 2.0, "Detail": 2.5, "Roughness": 0.6}},
    "fr2": {"props": {"feature": "F2", "voronoi_dimensions": "2D"}, "inputs": {"Scale": 2.0, "Detail": 1.0}},
    "frs": {"props": {"feature": "SMOOTH_F1", "voronoi_dimensions": "4D", "normalize": True},
            "inputs": {"Scale": 1.5, "Detail": 1.5, "Lacunarity": 2.5}},
    "fre": {"props": {"feature": "DISTANCE_TO_EDGE", "voronoi_dimensions": "2D", "normalize": True},
            "inputs": {"Scale": 3.0, "Detail": 1.5}},
}
VORONOI_OUTPUTS = ("Distance", "Color", "Position", "W", "Radius")
WAVE = {
    "b": {"props": {"wave_type": "BANDS"}, "inputs": {"Scale": 1.0}},
    "bd": {"props": {"bands_direction": "DIAGONAL", "wave_profile": "SAW"},
           "inputs": {"Scale": 0.5, "Phase Offset": 0.3}},
    "bz": {"props": {"bands_direction": "Z", "wave_profile": "TRI"}, "inputs": {"Scale": 3.0}},
    "ry": {"props": {"wave_type": "RINGS", "rings_direction": "Y", "wave_profile": "TRI"},
           "inputs": {"Scale": 0.7}},
    "rs": {"props": {"wave_type": "RINGS", "rings_direction": "SPHERICAL"},
           "inputs": {"Scale": 0.5, "Distortion": 3.0, "Detail": 2.5, "Detail Scale": 2.0}},
    "rx": {"swizzle": (0, 2, 1), "props": {"wave_type": "RINGS", "rings_direction": "X"},
           "inputs": {"Scale": 0.8, "Distortion": 1.0}},
}
GRADIENT = {k: {"props": {"gradient_type": k}} for k in
            ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "SPHERICAL", "QUADRATIC_SPHERE", "RADIAL")}
MAGIC = {
    "d0": {"props": {"turbulence_depth": 0}, "inputs": {"Scale": 2.0}},
    "d2": {"props": {"turbulence_depth": 2}},
    "d5": {"props": {"turbulence_depth": 5}, "inputs": {"Distortion": 2.5}},
    "d10": {"props": {"turbulence_depth": 10}, "inputs": {"Scale": 1.3}},
    "xzy": {"swizzle": (0, 2, 1), "props": {"turbulence_depth": 3}},
}
CHECKER = {"c": {"inputs": {"Scale": 5.0}},
           "c2": {"inputs": {"Scale": 7.3, "Color1": [1.0, 0.5, 0.1, 1.0]}},
           "xzy": {"swizzle": (0, 2, 1), "inputs": {"Scale": 4.1}}}
BRICK = {
    "b": {"inputs": {"Scale": 2.0}},
    "b2": {"props": {"offset": 0.3, "offset_frequency": 3, "squash": 0.6, "squash_frequency": 2},
           "inputs": {"Scale": 3.0, "Mortar Size": 0.05, "Mortar Smooth": 0.4, "Bias": 0.2}},
    "b3": {"inputs": {"Scale": 1.5, "Mortar Smooth": 0.0, "Brick Width": 0.7, "Row Height": 0.3,
                      "Mortar": [0.1, 0.9, 0.3, 1.0]}},
}
WHITE = {f"w{d}": {"props": {"noise_dimensions": f"{d}D"}} for d in (1, 2, 3, 4)}
WHITE["xzy"] = {"swizzle": (0, 2, 1)}


@pytest.mark.slow
def test_noise_matches_cycles_50_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexNoise", NOISE_50, ("Fac", "Color"),
                 (with_inputs(NOISE_50, Scale=1.01), None, None), tol=5e-5)


@pytest.mark.slow
def test_noise_matches_blender_34_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexNoise", NOISE_34, ("Fac", "Color"),
                 (with_inputs(NOISE_34, Scale=1.01), None, None), tol=5e-5, blender="3.4",
                 version=(3, 4))


@pytest.mark.slow
def test_musgrave_matches_blender_34_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexMusgrave", MUSGRAVE_34, ("Fac",),
                 (with_inputs(MUSGRAVE_34, Scale=1.01), None, None), tol=5e-5, blender="3.4",
                 version=(3, 4))


def _other_metric(cases):
    swap = {"EUCLIDEAN": "MANHATTAN", "MANHATTAN": "CHEBYCHEV", "CHEBYCHEV": "EUCLIDEAN",
            "MINKOWSKI": "EUCLIDEAN"}
    return {k: {**c, "props": {**c["props"], "distance": swap[c["props"].get("distance", "EUCLIDEAN")]}}
            for k, c in cases.items()}


@pytest.mark.slow
def test_voronoi_matches_cycles_50_and_another_metric_fails():
    check_family("ShaderNodeTexVoronoi", VORONOI_METRIC, ("Distance", "Color", "Position"),
                 (_other_metric(VORONOI_METRIC), None, None), flips=FLIP_SHARE)


@pytest.mark.slow
def test_voronoi_features_and_fractal_match_cycles_50_and_blender_45_hashes_fail():
    cases = {**VORONOI_OTHER, **VORONOI_FRACTAL}
    # The control: the same kernel with Blender 4.5's lookup3 cell hashes (5.0 moved to PCG);
    # 1-D Voronoi kept its hashes, so the control leaves out the 1-D cases.
    ctrl = {k: c for k, c in cases.items() if c["props"].get("voronoi_dimensions") != "1D"}
    check_family("ShaderNodeTexVoronoi", cases, VORONOI_OUTPUTS, (ctrl, (4, 5), None),
                 flips=FLIP_SHARE, min_share=0.01)


@pytest.mark.slow
def test_voronoi_matches_blender_34_and_blender_50_hashes_fail():
    cases = {**VORONOI_METRIC, **VORONOI_OTHER}
    ctrl = {k: c for k, c in cases.items() if c["props"].get("voronoi_dimensions") != "1D"}
    check_family("ShaderNodeTexVoronoi", cases, ("Distance", "Color", "Radius"), (ctrl, (5, 0), None),
                 flips=FLIP_SHARE, blender="3.4", version=(3, 4), min_share=0.01)


@pytest.mark.slow
def test_wave_matches_cycles_50_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexWave", WAVE, ("Fac",), (with_inputs(WAVE, Scale=1.01), None, None))


@pytest.mark.slow
def test_gradient_matches_cycles_50_and_another_type_fails():
    kinds = list(GRADIENT)
    ctrl = {k: {"props": {"gradient_type": kinds[(i + 1) % len(kinds)]}} for i, k in enumerate(kinds)}
    check_family("ShaderNodeTexGradient", GRADIENT, ("Fac", "Color"), (ctrl, None, None))


@pytest.mark.slow
def test_magic_matches_cycles_50_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexMagic", MAGIC, ("Fac", "Color"),
                 (with_inputs(MAGIC, Scale=1.01), None, None), tol=1e-4)


@pytest.mark.slow
def test_checker_matches_cycles_50_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexChecker", CHECKER, ("Fac", "Color"),
                 (with_inputs(CHECKER, Scale=1.01), None, None), flips=FLIP_SHARE, min_share=0.01)


@pytest.mark.slow
def test_brick_matches_cycles_50_and_scale_off_by_1_percent_fails():
    check_family("ShaderNodeTexBrick", BRICK, ("Fac", "Color"),
                 (with_inputs(BRICK, Scale=1.01), None, None), flips=FLIP_SHARE, min_share=0.01)


@pytest.mark.slow
def test_white_noise_matches_cycles_50_bit_for_bit_and_one_ulp_off_fails():
    from tests.nodes.flat_quad import coordinates
    pts = coordinates(RES, Z)
    nudged = np.nextafter(pts.astype(np.float32), np.float32(np.inf)).astype(np.float64)
    report = check_family("ShaderNodeTexWhiteNoise", WHITE, ("Value", "Color"), (WHITE, None, nudged),
                          tol=0.0)
    assert all(v == (0.0, 0.0) for v in report.values())
