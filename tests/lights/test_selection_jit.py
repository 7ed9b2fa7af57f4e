"""The light tree's compiled walk (engine/lights/selection_jit.py) against the NumPy one
(engine/lights/selection.py) on inputs recorded from a render of the built-in many-lights room,
and on random trees with the cases of importance (receivers inside bounds, two-sided lamps,
lights of no power, empty children)."""
import numpy as np
import pytest

from engine.lights.selection import LightTree
from tests.backend_capture import capture, require_compiled

TWIN = "engine.lights.selection_jit"     # imported after require_compiled(): numba may be missing


@pytest.fixture(scope="module")
def calls():
    require_compiled()
    return capture("many_lights")


def test_captured_walks_are_bit_identical(calls):
    from engine.lights.selection_jit import TreeTables
    assert calls["sample"] and calls["pmf"]
    for tree, x, n, u in calls["sample"]:
        light, pmf = tree._tree_sample(x, n, u)
        light_c, pmf_c = TreeTables(tree).sample(x, n, u)
        assert np.array_equal(light, light_c) and np.array_equal(pmf, pmf_c)
    for tree, x, n, light in calls["pmf"]:
        assert np.array_equal(tree._tree_pmf(x, n, light), TreeTables(tree).pmf(x, n, light))


def test_captured_picks_are_bit_identical(calls):
    """LightTree.sample in one compiled loop (TreeTables.select: the defensive mixing too)."""
    from engine.lights.selection import DEFENSIVE
    from engine.lights.selection_jit import TreeTables
    assert calls["pick"]
    for tree, x, n, u in calls["pick"]:
        light, pmf = tree.sample(x, n, u)
        light_c, pmf_c = TreeTables(tree).select(x, n, u, DEFENSIVE)
        assert np.array_equal(light, light_c) and np.array_equal(pmf, pmf_c)
        assert np.array_equal(tree.pmf(x, n, light), TreeTables(tree).mixed_pmf(x, n, light, DEFENSIVE))


def random_tree(rng, k, backend, two_sided=0.3):
    c = rng.random((k, 3)) * 4.0
    axis = rng.normal(size=(k, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    cos_o = np.where(rng.random(k) < two_sided, -1.0, rng.random(k))       # some two-sided
    power = rng.random(k) + 0.01
    power[k // 2] = 0.0
    return LightTree(c, rng.random(k) * 0.2, axis, cos_o, power, power, backend=backend), c


@pytest.mark.parametrize("k, two_sided", [(2, 0.3), (3, 0.3), (37, 0.3), (300, 0.3), (3, 1.0), (36, 1.0)])
def test_random_trees_sample_and_pmf_agree(k, two_sided):
    """two_sided 1.0: every level without a cone (the walk copies no cone columns into its lanes)."""
    require_compiled()
    rng = np.random.default_rng(k)
    tree, c = random_tree(rng, k, "numpy", two_sided)
    compiled, _ = random_tree(np.random.default_rng(k), k, "numba", two_sided)
    assert two_sided < 1.0 or not any(level["oriented"] for level in compiled.levels[1:])
    m = 4000
    x = rng.random((3, m)) * 4.0
    x[:, :k] = c[:m].T[:, :k]                         # receivers at lamp centres (inside the bounds)
    n = rng.normal(size=(3, m))
    n /= np.linalg.norm(n, axis=0)
    u = rng.random(m)
    light, pmf = tree.sample(x, n, u)
    light_c, pmf_c = compiled.sample(x, n, u)
    assert np.array_equal(light, light_c) and np.array_equal(pmf, pmf_c)
    assert np.array_equal(tree.pmf(x, n, light), compiled.pmf(x, n, light))


def test_control_a_changed_table_is_seen():
    """The comparison can fail: one node's power changed in the compiled tables changes pmfs."""
    require_compiled()
    from engine.lights.selection_jit import TreeTables
    rng = np.random.default_rng(5)
    tree, _ = random_tree(rng, 37, "numpy")
    x, n = rng.random((3, 500)) * 4.0, np.tile([[0.0], [0.0], [1.0]], 500)
    light = rng.integers(0, 37, 500)
    tables = TreeTables(tree)
    tables.nodes[0, 14] *= 1.5
    assert not np.array_equal(tree._tree_pmf(x.astype(np.float32), n.astype(np.float32), light),
                              tables.pmf(x, n, light))
