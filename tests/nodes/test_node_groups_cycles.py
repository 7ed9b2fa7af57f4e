"""Node groups against Cycles, pixel by pixel (tests/nodes/flat_quad.py): a group nested in another
(Warp inside Tint: a reroute and a muted node inside, a group socket's float into a vector), the
outer group used twice with different inputs (one socket unlinked: the group node's value), feeding
a Noise texture's Vector and a colour chain (Mix, Gamma, Hue/Saturation), a colour through a Float
group socket (its luminance before 5.0, the colour in 5.0), an unlinked Group Output socket (its
value) and an unlinked group Vector into a texture (its implicit coordinates before 5.0, the value in
5.0), a Vector Math and a Mapping (the value).  The graph is compiled
by the exporter's GraphCompiler in the same Blender (tests/nodes/group_graphs.py) and run by the
tracer's evaluator at the pixel centres.  Blender 5.0 and 3.4.  CONTROLS: the group's Color and Fac
swapped inside (compiled from the swapped graph, compared with the true image), and the graph compiled
by the other Blender's group rules, fail."""
import numpy as np
import pytest

from tests.nodes import flat_quad, group_graphs

pytestmark = pytest.mark.slow
TOL = 2e-5
RES = 32


def tracer_values(kept, points, version, generated_at):
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
        # Generated (a texture's implicit coordinates) at Cycles' own hit points: the quad's texture
        # space is [-1, 1]^2 x {0}, a flat z reading 0.5
        p = generated_at
        ctx = NodeContext(points.shape[1], version, {"object": points, "position": points,
                                                     "generated": np.stack([(p[0] + 1) / 2, (p[1] + 1) / 2,
                                                                            np.full(p.shape[1], 0.5)])})
        value = run(program, ctx)
        out[name] = value if value.ndim == 2 else np.repeat(value[None], 3, axis=0)
    return out


def errors(images, values):
    return {name: float(np.abs(images[name].reshape(-1, 3).T - values[name]).max()) for name in images}


def _check(blender, version):
    images, points, kept = flat_quad.render(group_graphs.build_nested, resolution=RES, blender=blender, kept=True)
    assert set(images) == {"first", "second", "value", "spare", "chain", "narrow", "implicit", "math", "mapped", "P"}
    hits = images.pop("P").reshape(-1, 3).T
    err = errors(images, tracer_values(kept, points, version, hits))
    print(f"node groups {blender}: max abs error per output {err}")
    assert max(err.values()) < TOL, err
    assert np.ptp(images["chain"]) > 0.1 and np.allclose(images["spare"], 0.25)
    assert np.allclose(images["math"], (0.3, 0.6, 0.9))                # the unlinked group Vector's value
    if version < (5, 0):                          # a texture's hidden Vector: its implicit Generated ...
        assert np.ptp(images["implicit"]) > 0.9
    else:                                         # ... or, 5.0, the group socket's value (its x: 0.3)
        assert np.allclose(images["implicit"], 0.3)
    # CONTROL: the swapped group's programs against the true image
    _, _, swapped = flat_quad.render(group_graphs.build_nested, resolution=RES, blender=blender, kept=True, swap=True)
    bad = errors(images, tracer_values(swapped, points, version, hits))
    print(f"node groups {blender}, control (Color and Fac swapped inside): {bad}")
    assert bad["first"] > 100 * TOL and bad["chain"] > 100 * TOL
    # CONTROL: the programs compiled by the other Blender's group rules (3.4's proxies / 5.0's inlining)
    other = [3, 4] if version >= (5, 0) else [5, 0]
    _, _, others = flat_quad.render(group_graphs.build_nested, resolution=RES, blender=blender, kept=True, rules=other)
    bad = errors(images, tracer_values(others, points, version, hits))
    print(f"node groups {blender}, control (compiled by {other}'s rules): {bad}")
    assert bad["narrow"] > 0.1 and bad["value"] > 0.1 and bad["implicit"] > 0.1


def test_nested_groups_agree_with_cycles_50():
    _check("5.0", (5, 0))


def test_nested_groups_agree_with_cycles_34():
    _check("3.4", (3, 4))
