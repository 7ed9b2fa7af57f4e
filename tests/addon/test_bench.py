"""The add-on's benchmarks run and their arithmetic is right (their figures are not checked: a
benchmark prints, a test does not time): mcrt_addon/bench.py at a small size, and the metrics and
table of mcrt_addon/bench_estimators.py."""
import argparse
import re

import numpy as np
import pytest

from mcrt_addon import bench_estimators as be
from mcrt_addon.bench import bench_export, grid_mesh


def test_grid_mesh_has_about_the_triangles_asked_for(empty_scene):
    me = grid_mesh("Grid", 2000)
    me.calc_loop_triangles()
    assert 1800 <= len(me.loop_triangles) <= 2000 and len(me.vertices) == 32 * 32


def test_bench_export_runs_and_shares_instanced_meshes(capsys):
    assert bench_export(n_triangles=2000, n_instances=3) == 0
    out = capsys.readouterr().out
    assert re.search(r"single mesh: 1,922 triangles, 1,024 vertices", out), out
    assert "smooth-shaded (1 mesh with corner normals)" in out and "with corner UVs" in out
    assert re.search(r"instances: 3 objects sharing one mesh, [\d,]+ triangles in total: .* \(mesh arrays read 1 time",
                     out), out


def test_error_metrics_against_hand_computed_values():
    ref = np.ones((2, 2, 3))
    image = ref.copy()
    image[0, 0] = [2, 1, 1]                           # one channel of one pixel off by 1
    m = be.error_metrics(image, ref)
    assert m["mse"] == pytest.approx(1 / 12) and m["relmse"] == pytest.approx(1 / (1 + be.RELMSE_EPS) / 12)
    assert m["worst10_share"] == 1.0 and m["nonfinite"] == 0 and m["mean"] == pytest.approx(13 / 12)
    assert be.error_metrics(ref, ref)["worst10_share"] == 0.0
    with pytest.raises(ValueError, match="image shapes differ"):
        be.error_metrics(np.ones((2, 3, 3)), ref)


def test_derived_efficiency_and_the_table():
    cycles = be.derived({"renderer": "cycles", "estimator": "", "mse": 0.01, "seconds": 2.0, "relmse": 0.04,
                         "worst10_share": 0.5}, None)
    assert cycles["efficiency"] == pytest.approx(50.0) and np.isnan(cycles["efficiency_vs_cycles"])
    ours = be.derived({"renderer": "tncg15", "estimator": "mis", "mse": 0.02, "seconds": 0.5, "relmse": 0.02,
                       "worst10_share": 0.25, "cpu_seconds": 1.0}, cycles["efficiency"])
    assert ours["efficiency_vs_cycles"] == pytest.approx(2.0) and ours["efficiency_cpu"] == pytest.approx(50.0)
    assert ours["seconds_to_relmse_1e-2"] == pytest.approx(1.0)
    table = be.markdown_table({"cornell": {"rows": [cycles, ours]}}).splitlines()
    assert len(table) == 4 and "| cornell | Cycles | 2.00 |" in table[2] and "| – |" in table[2]
    assert "| cornell | TNCG15 mis | 0.50 |" in table[3]


@pytest.mark.parametrize("argv, message", [(["--samples", "0"], "--samples must be >= 1"),
                                           (["--threads", "-1"], "--max-depth and --threads must be >= 0"),
                                           (["--resolution", "0", "8"], "--resolution must be positive")])
def test_bad_arguments_are_refused(argv, message, capsys):
    parser = argparse.ArgumentParser()
    be.add_arguments(parser)
    with pytest.raises(SystemExit):
        be.check_arguments(parser, parser.parse_args(argv))
    assert message in capsys.readouterr().err
    be.check_arguments(parser, parser.parse_args([]))
