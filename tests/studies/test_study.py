"""`python -m engine study --quick`: every table, plot and error column is produced."""
import json
import os

import numpy as np
import pytest

from engine.studies.accuracy import run_study


@pytest.mark.slow   # the tables: tests/studies/test_report.py; the stopping study below; accelerators: test_accelerators
def test_quick_study_writes_tables_plots_and_sane_errors(tmp_path):
    study = run_study("quick", str(tmp_path), "python -m engine study --quick", log=lambda *a: None)
    doc = (tmp_path / "accuracy-vs-time.md").read_text()
    for title in ("Table 3.1", "Table 3.2", "Table 3.3", "Table 3.4", "§3.6", "Schlick against exact"):
        assert title in doc
    for png in ("error-vs-time.png", "error-vs-spp.png", "efficiency-vs-shadow-rays.png",
                "accelerator-time-vs-triangles.png", "fig-3-1-shadow-rays.png", "fig-3-2-depth.png",
                "fig-3-4-spp.png"):
        assert os.path.getsize(tmp_path / "accuracy" / png) > 1000
    rows = json.loads((tmp_path / "accuracy" / "rows.json").read_text())
    assert all(len(r["seconds"]) >= 2 and all(np.isfinite(r["mse"])) for r in rows)
    by_label = {r.label: r for r in study.rows}
    # Same seeds, same estimator: the three accelerators give the same error (Embree is float32).
    accel = [r.rmse for r in study.rows if r.table == "3.2" and r.extra["mesh"]]
    assert len(accel) == 3 and np.ptp(accel) < 1e-3 * accel[0]
    # Direct light only is biased; more samples lower the error.
    assert by_label["depth 0"].rel_bias2 > 0.01
    assert by_label["depth 0"].time_to_target() == float("inf")
    assert by_label["depth 0"].rel_bias2 > 10 * by_label["depth 0"].rel_bias2_se
    # An unbiased setting: its bias estimate is zero within noise, so a target time is given.
    unbiased = by_label["16 spp"]
    assert abs(unbiased.rel_bias2) < 4 * unbiased.rel_bias2_se + 1e-3
    assert np.isfinite(unbiased.time_to_target())
    assert by_label["16 spp"].rmse < by_label["1 spp"].rmse


@pytest.mark.slow          # the stopping rules' own tests cover the rounds; this is the study's tables
def test_quick_stopping_study_writes_both_tables(tmp_path):
    import json
    from engine.studies.stopping import run_stopping_study
    study = run_stopping_study("quick", str(tmp_path), "python -m engine study --stopping --quick",
                               log=lambda *a: None)
    text = (tmp_path / "accuracy-stopping.md").read_text()
    assert "## Calibration of the estimated relative error" in text and "## Adaptive against uniform" in text
    rows = json.loads((tmp_path / "accuracy-stopping.json").read_text())
    assert len(rows["calibration"]) == 1 and len(rows["adaptive"]) == 1
    cal = study.calibration_rows[0]
    assert cal["estimated"] > 0 and cal["actual"] > 0
    adaptive = study.adaptive_rows[0]
    assert adaptive["equal_error"]["adaptive"]["spp"] < adaptive["equal_error"]["uniform"]["spp"]
