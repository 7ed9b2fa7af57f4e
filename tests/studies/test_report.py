"""engine/studies/report.py: the study's formatting and fits (the tables and plots themselves are
written by tests/studies/test_study.py's quick study)."""
from types import SimpleNamespace

import numpy as np
import pytest

from engine.studies.report import denoise_summary, fmt_time, markdown_table, spp_slope


def row(label, spp, rmse, t=1.0, **extra):
    return SimpleNamespace(label=label, t=t, seconds=[t, t], rmse=rmse, rel_mse=[rmse ** 2] * 2, variance=rmse ** 2,
                           bias2=0.0, efficiency=1 / (rmse ** 2 * t), extra=dict(spp=spp, **extra),
                           time_to_target=lambda: float("inf"))


def test_fmt_time():
    assert fmt_time(float("inf")) == "never" and fmt_time(float("nan")) == "never"
    assert fmt_time(1.234) == "1.23 s" and fmt_time(150) == "2.5 min"


def test_spp_slope_of_monte_carlo_convergence_is_minus_one_half():
    rows = [row(f"{n} spp", n, 0.3 / np.sqrt(n)) for n in (4, 16, 64, 256)]
    assert spp_slope(rows) == pytest.approx(-0.5, abs=1e-12)
    assert np.isnan(spp_slope(rows[:1]))


def test_markdown_table_has_a_row_per_setting():
    table = markdown_table([row("4 spp", 4, 0.1), row("16 spp", 16, 0.05, t=3.0)]).splitlines()
    assert len(table) == 4 and table[2].startswith("| 4 spp | 1.000 ± 0.000 | 0.1 |")
    assert table[3].endswith("| never |") and all(line.count("|") == 9 for line in table)


def test_denoise_summary_needs_both_rows():
    assert denoise_summary([row("4 spp", 4, 0.1)]) == []
    line, = denoise_summary([row("4 spp + OIDN", 4, 0.02, t=1.0, denoised=True), row("64 spp", 64, 0.04, t=8.0)])
    assert "**0.25×** the error in **0.12×** the time" in line
