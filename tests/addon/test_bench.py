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


def test_materials_bench_diffuse_stand_in_and_table():
    """mcrt_addon/bench_materials.py: every material becomes a Lambertian of its base colour (a mix
    by its leaves' constant weights, emission kept), and the table's ratios."""
    from mcrt_addon import bench_materials as bm
    from engine.scene.model import Material, Mix, MixFactor, MixLeaf, Principled, Scene
    mix = Mix([MixLeaf(Material("a", kind="glossy", color=(1.0, 0.0, 0.0)), [MixFactor(value=0.25)]),
               MixLeaf(Material("b", color=(0.0, 1.0, 0.0)), [MixFactor(value=0.25, invert=True)])])
    scene = Scene(camera=None, materials=[Material("m", kind="mix", mix=mix, emission=(1.0, 1.0, 1.0)),
                                          Material("p", kind="principled", principled=Principled(metallic=1.0),
                                                   color=(0.5, 0.4, 0.3)),
                                          Material("r", diffuse_roughness=0.8)])
    diffuse = bm.as_lambert(scene)
    assert [m.kind for m in diffuse.materials] == ["diffuse"] * 3 and scene.materials[0].kind == "mix"
    assert diffuse.materials[0].color == pytest.approx((0.25, 0.75, 0.0)) and diffuse.materials[0].emission == (1, 1, 1)
    assert diffuse.materials[1].color == (0.5, 0.4, 0.3) and diffuse.materials[1].principled is None
    assert diffuse.materials[2].diffuse_roughness == 0.0
    rows = [be.derived(dict(renderer=k, mse=mse, relmse=mse, seconds=t), 50.0)
            for k, mse, t in (("cycles", 0.01, 2.0), ("tncg15", 0.02, 0.5), ("tncg15_diffuse", 0.03, 0.25))]
    table = bm.markdown_table({"plates": dict(rows=rows, efficiency_vs_cycles=rows[1]["efficiency_vs_cycles"],
                                               rough_over_diffuse_seconds=2.0)}).splitlines()
    assert table[2] == ("| plates | 2.00 | 1.000e-02 | 50 | 0.50 | 2.000e-02 | 100 | 2 | 0.25 | 2.00 |"), table[2]


def test_materials_bench_reads_the_workers_cpu_seconds():
    """bench_materials.process_cpu_seconds: the user + system seconds of live processes by pid, growing
    with their work (control: a process that only sleeps gains none); None for a pid that is gone."""
    import os
    import subprocess
    import sys
    import time
    from mcrt_addon import bench_materials as bm
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; print('up', flush=True); time.sleep(30)"],
                               stdout=subprocess.PIPE, text=True)
    try:
        assert sleeper.stdout.readline() == "up\n"                 # started: its start-up CPU is behind it
        me, other = bm.process_cpu_seconds([os.getpid()]), bm.process_cpu_seconds([sleeper.pid])
        end = time.process_time() + 0.3
        while time.process_time() < end:
            pass
        assert bm.process_cpu_seconds([os.getpid()]) - me >= 0.2
        assert bm.process_cpu_seconds([sleeper.pid]) - other <= 0.05
    finally:
        sleeper.kill()
        sleeper.wait()
    assert bm.process_cpu_seconds([sleeper.pid]) is None


def test_materials_bench_pool_argument():
    from mcrt_addon import bench_materials as bm
    parser = argparse.ArgumentParser()
    bm.add_arguments(parser)
    assert parser.parse_args([]).tncg15_pool == "workers"
    assert parser.parse_args(["--tncg15-pool", "threads"]).tncg15_pool == "threads"
    with pytest.raises(SystemExit):
        parser.parse_args(["--tncg15-pool", "forks"])


@pytest.mark.slow
def test_materials_bench_on_workers_renders_the_threads_image(tmp_path):
    """--tncg15-pool workers (the add-on's warm worker processes, export timed) gives the image of the
    in-process render, and counts the workers' CPU seconds."""
    from mcrt_addon import bench_materials as bm
    make_samples = be.load_make_samples()
    _, blend, _ = be.scene_blend("principled_default", str(tmp_path), make_samples)
    scene = be.open_blend(blend, (24, 16))
    kw = dict(samples=4, max_depth=6, seed=1, threads=2, estimator="mis")
    image, seconds, cpu, stats = bm.render_on_workers(scene, (24, 16), diffuse=False, **kw)
    reference = be.render_tncg15(be.export_tracer_scene(scene, (24, 16)).scene, **kw)[0]
    assert np.array_equal(image, reference) and image.mean() > 0.0
    assert stats["workers_cpu_seconds"] > 0.0 and cpu >= stats["workers_cpu_seconds"] and seconds > 0.0
    diffuse = bm.render_on_workers(scene, (24, 16), diffuse=True, **kw)[0]
    assert not np.array_equal(diffuse, image)                     # control: the stand-in's materials differ
