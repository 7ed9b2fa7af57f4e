"""engine/cli/bench.py runs and prints its figures for each worker count (a benchmark's figures are
printed, never required: `make bench`)."""
import os

from engine.cli.bench import run_bench


def test_bench_prints_a_row_per_worker_count(capsys):
    rows = run_bench(resolution=(16, 16), samples=2)
    out = capsys.readouterr().out
    cores = os.cpu_count() or 1
    assert out.startswith("TNCG15 MC bench: built-in Cornell scene 16x16, 2 spp")
    assert set(rows) == {1, cores} | ({"speedup"} if cores > 1 else set())
    assert all(rows[n]["render_seconds"] > 0 and rows[n]["threads"] == n for n in (1, cores))
    assert out.count("k paths/s") == len({1, cores}) and "per sample pass (16x16" in out
