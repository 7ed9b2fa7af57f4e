"""scripts/bench_sample_files.py's pure parts: the per-sample slope, the ratios, the met flags and
the table (no rendering)."""
import importlib.util
import math
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def script():
    path = os.path.join(ROOT, "scripts", "bench_sample_files.py")
    spec = importlib.util.spec_from_file_location("bench_sample_files", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def timings(setup, per_spp, counts, cpu_share=0.8):
    """Times of a renderer with a fixed per-render cost `setup` and `per_spp` seconds a sample."""
    return {str(s): dict(wall=setup + per_spp * s, cpu=cpu_share * (setup + per_spp * s)) for s in counts}


def row(bench, cycles_spp, tncg_spp, *, cycles_setup=0.5, tncg_setup=2.0, mse=None):
    counts = (16, 64)
    r = dict(file="scene", resolution=96, samples=list(counts), notes=[],
             cycles=timings(cycles_setup, cycles_spp, counts), tncg15=timings(tncg_setup, tncg_spp, counts))
    if mse:
        r["cycles_mse"], r["tncg15_mse"] = mse
    return bench.summarise(r)


def test_the_slope_cancels_the_per_render_cost():
    bench = script()
    # a large setup (BVH build) and a small per-sample time: the slope sees only the latter
    r = row(bench, cycles_spp=0.010, tncg_spp=0.005, cycles_setup=0.3, tncg_setup=5.0)
    assert r["cycles_per_sample_wall"] == pytest.approx(0.010)
    assert r["tncg15_per_sample_wall"] == pytest.approx(0.005)
    assert r["ratio_wall"] == pytest.approx(0.5) and r["time_met_wall"] is True
    assert r["ratio_cpu"] == pytest.approx(0.5)
    # the whole renders are dominated by the setup: their ratio is not the per-sample one
    assert r["whole_ratio_wall"] == pytest.approx((5.0 + 0.32) / (0.3 + 0.64))
    # control: a slope that divides the time at S2 by S2 (setup not cancelled) gives another answer
    wrong = r["tncg15"]["64"]["wall"] / 64
    assert wrong != pytest.approx(r["tncg15_per_sample_wall"], rel=0.1)
    with pytest.raises(ValueError):
        bench.per_sample(1.0, 2.0, 64, 16)


def test_met_flags_at_their_bounds():
    bench = script()
    assert bench.meets_time(0.6) is True and bench.meets_time(0.61) is False
    assert bench.meets_efficiency(2.0) is True and bench.meets_efficiency(1.99) is False
    assert bench.meets_time(float("nan")) is None and bench.meets_efficiency(None) is None
    assert math.isnan(bench.ratio(1.0, 0.0)) and math.isnan(bench.ratio(None, 1.0))
    slow = row(bench, cycles_spp=0.010, tncg_spp=0.007)
    assert slow["time_met_wall"] is False


def test_efficiency_ratio_and_its_flag():
    bench = script()
    # same time per render at S2 when setups match; a quarter of the MSE -> 4x the efficiency
    r = row(bench, cycles_spp=0.01, tncg_spp=0.01, cycles_setup=1.0, tncg_setup=1.0, mse=(4e-3, 1e-3))
    assert r["efficiency_ratio_wall"] == pytest.approx(4.0) and r["efficiency_met"] is True
    r = row(bench, cycles_spp=0.01, tncg_spp=0.01, cycles_setup=1.0, tncg_setup=1.0, mse=(1.5e-3, 1e-3))
    assert r["efficiency_ratio_wall"] == pytest.approx(1.5) and r["efficiency_met"] is False
    assert r["notes"] == []
    r = row(bench, cycles_spp=0.01, tncg_spp=0.01, mse=(1e-3, 5e-3))      # 5x Cycles' MSE: noted
    assert r["notes"] == ["MSE 5.0x Cycles' at S2"] and bench.summarise(r)["notes"] == r["notes"]


def test_table_marks_rows_and_keeps_errors():
    bench = script()
    good = row(bench, cycles_spp=0.010, tncg_spp=0.004, mse=(4e-3, 1e-3))
    bad = row(bench, cycles_spp=0.010, tncg_spp=0.009)
    bad["file"] = "slow"
    broken = dict(file="broken", resolution=256, samples=[4, 16], error="RuntimeError: no camera | x")
    lines = bench.markdown_table([good, bad, broken]).splitlines()
    assert len(lines) == 5
    assert "| 0.40 (0.40) | yes (yes) |" in lines[2]
    assert "| yes (yes) |" in lines[2].split("| 0.40 (0.40) |")[1]               # efficiency 4x
    assert "| 0.90 (0.90) | **no** (**no**) |" in lines[3]
    assert "error: RuntimeError: no camera / x" in lines[4]
    summary = bench.summary_lines([good, bad, broken])
    assert "met on 1 of 2" in summary[0] and "slow@96" in summary[0]
    assert "broken@256" in summary[-1]


def test_samples_table_and_its_scaling():
    bench = script()
    table = bench.parse_samples(["96=16,64", "256=4,16"])
    assert bench.samples_for(96, table) == (16, 64)
    s1, s2 = bench.samples_for(128, table)           # nearest 96, fewer samples for more pixels
    assert s1 < s2 <= 64
    with pytest.raises(Exception):
        bench.parse_samples(["96=64,16"])


def test_repeated_timings_take_each_clocks_median():
    bench = script()
    quiet = [dict(wall=1.0, cpu=1.9), dict(wall=1.1, cpu=2.0)]
    disturbed = dict(wall=4.0, cpu=2.1)                 # another process's burst: wall only
    m = bench.median_timing(quiet + [disturbed])
    assert m["wall"] == 1.1 and m["cpu"] == 2.0 and len(m["runs"]) == 3
    # the mean (the control) follows the disturbed run; the slope of two medians does not
    assert sum(r["wall"] for r in quiet + [disturbed]) / 3 > 2.0
    assert bench.median_timing(quiet) == dict(wall=1.05, cpu=1.95, runs=quiet)
    one = bench.median_timing([disturbed])
    assert one == dict(wall=4.0, cpu=2.1)                # a single run: as before, no "runs"
    with pytest.raises(ValueError):
        bench.median_timing([])
