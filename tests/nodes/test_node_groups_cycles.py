"""Node groups against Cycles, pixel by pixel (tests/nodes/flat_quad.py): a group nested in another
(Warp inside Tint: a reroute and a muted node inside, a group socket's float into a vector), the
outer group used twice with different inputs (one socket unlinked: the group node's value), feeding
a Noise texture's Vector and a colour chain (Mix, Gamma, Hue/Saturation), a colour through a Float
group output (its luminance) and an unlinked Group Output socket (its value).  The graph is compiled
by the exporter's GraphCompiler in the same Blender (tests/nodes/group_graphs.py) and run by the
tracer's evaluator at the pixel centres.  Blender 5.0 and 3.4.  CONTROL: the group's Color and Fac
swapped inside (compiled from the swapped graph, compared with the true image) fails."""
import numpy as np
import pytest

from tests.nodes import flat_quad, group_graphs

pytestmark = pytest.mark.slow
TOL = 2e-5
RES = 32


def tracer_values(kept, points, version):
    from engine.nodes.context import NodeContext
    from engine.nodes.evaluator import run
    from engine.scene.programs import read_program
    out = {}
    for name, entry in kept["programs"].items():
        assert entry["warnings"] == [], entry["warnings"]
        assert entry["program"] is not None or entry["value"] is not None, name
        if entry["program"] is None:
            out[name] = np.repeat(np.asarray(entry["value"], dtype=np.float64).reshape(-1, 1)[:3], points.shape[1], 1)
            continue
        program = read_program(entry["program"], name)
        ctx = NodeContext(points.shape[1], version, {"object": points, "position": points})
        value = run(program, ctx)
        out[name] = value if value.ndim == 2 else np.repeat(value[None], 3, axis=0)
    return out


def errors(images, values):
    return {name: float(np.abs(images[name].reshape(-1, 3).T - values[name]).max()) for name in images}


def _check(blender, version):
    images, points, kept = flat_quad.render(group_graphs.build_nested, resolution=RES, blender=blender, kept=True)
    assert set(images) == {"first", "second", "value", "spare", "chain", "narrow"}
    err = errors(images, tracer_values(kept, points, version))
    print(f"node groups {blender}: max abs error per output {err}")
    assert max(err.values()) < TOL, err
    assert np.ptp(images["chain"]) > 0.1 and np.allclose(images["spare"], 0.25)
    # CONTROL: the swapped group's programs against the true image
    _, _, swapped = flat_quad.render(group_graphs.build_nested, resolution=RES, blender=blender, kept=True, swap=True)
    bad = errors(images, tracer_values(swapped, points, version))
    print(f"node groups {blender}, control (Color and Fac swapped inside): {bad}")
    assert bad["first"] > 100 * TOL and bad["chain"] > 100 * TOL


def test_nested_groups_agree_with_cycles_50():
    _check("5.0", (5, 0))


def test_nested_groups_agree_with_cycles_34():
    _check("3.4", (3, 4))
