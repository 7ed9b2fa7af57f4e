"""The per-user cache of computed tables (engine/core/table_cache.py): a table read from it has the
bits of the computed one, and a change of the code or the inputs never reads a stale file."""
import numpy as np

from engine.core import table_cache
from engine.materials import principled


def use_cache_in(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))


def test_the_principled_s_tables_read_back_bit_identical(tmp_path, monkeypatch):
    """Computed, written, then read by a process that has not computed them (the lru cache
    cleared): the same bits as estimate_interpolation_factor; read from the file, not computed."""
    use_cache_in(tmp_path, monkeypatch)
    principled.interpolation_factor.cache_clear()
    cases = [(0.3, 1.45), (0.05, None), (1.0, 1.5)]
    first = [principled.interpolation_factor(r, e) for r, e in cases]
    assert len(list((tmp_path / "tables").iterdir())) == len(cases)
    principled.interpolation_factor.cache_clear()
    monkeypatch.setattr(principled, "estimate_interpolation_factor", lambda *a: 1 / 0)    # never computed
    for (r, e), table in zip(cases, first):
        read = principled.interpolation_factor(r, e)
        assert np.array_equal(read, table)
    principled.interpolation_factor.cache_clear()
    monkeypatch.undo()
    for (r, e), table in zip(cases, first):
        assert np.array_equal(principled.estimate_interpolation_factor(r, e), table)


def test_a_change_of_the_code_or_the_inputs_never_reads_a_stale_table(tmp_path, monkeypatch):
    """Control: the table of the old code is on disk, but the changed source computes anew."""
    use_cache_in(tmp_path, monkeypatch)
    source = tmp_path / "kernel.py"
    source.write_text("def f(): return 1\n")
    calls = []

    def compute(value):
        calls.append(value)
        return np.full(4, value, dtype=np.float64)

    assert table_cache.cached("t", (str(source),), (1.0,), lambda: compute(1.0))[0] == 1.0
    assert table_cache.cached("t", (str(source),), (1.0,), lambda: compute(9.0))[0] == 1.0    # read
    assert calls == [1.0]
    assert table_cache.cached("t", (str(source),), (2.0,), lambda: compute(2.0))[0] == 2.0    # new input
    source.write_text("def f(): return 2\n")
    table_cache.code_digest.cache_clear()
    assert table_cache.cached("t", (str(source),), (1.0,), lambda: compute(3.0))[0] == 3.0    # new code
    assert calls == [1.0, 2.0, 3.0]


def test_an_unreadable_table_is_computed_again(tmp_path, monkeypatch):
    use_cache_in(tmp_path, monkeypatch)
    source = tmp_path / "kernel.py"
    source.write_text("x = 1\n")
    path = table_cache.table_path("t", (str(source),), (1.0,))
    with open(path, "wb") as fh:
        fh.write(b"not a table")
    assert table_cache.cached("t", (str(source),), (1.0,), lambda: np.ones(3)).tolist() == [1.0, 1.0, 1.0]
    assert np.load(path).tolist() == [1.0, 1.0, 1.0]
