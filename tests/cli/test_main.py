"""`python -m engine`: one-line errors with exit code 2, stats JSON with the agreed keys."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from engine.film.image_files import read_image

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(*args):
    return subprocess.run([sys.executable, "-m", "engine", *args], cwd=ROOT, capture_output=True, text=True)


def test_render_writes_exr_png_and_stats(tmp_path):
    out, png, stats = tmp_path / "o.exr", tmp_path / "o.png", tmp_path / "s.json"
    r = run("render", "-o", str(out), "--png", str(png), "--samples", "2", "--resolution", "40", "30",
            "--threads", "2", "--stats-json", str(stats), "--quiet")
    assert r.returncode == 0, r.stderr
    image = read_image(str(out))
    assert image.shape == (30, 40, 3) and np.isfinite(image).all() and image.mean() > 0.05
    data = json.loads(stats.read_text())
    for key in ("engine", "render_seconds", "samples", "resolution", "threads", "accelerator", "rays",
                "effects", "effects_reason", "nonfinite_samples", "seconds_in_intersection"):
        assert key in data
    assert data["resolution"] == [40, 30] and data["samples"] == 2 and data["threads"] == 2
    assert data["rays"]["camera"] == 40 * 30 * 2
    assert data["nonfinite_samples"] == 0
    assert png.stat().st_size > 0


@pytest.mark.parametrize("args, fragment", [
    (["render", "-o", "x.exr", "--samples", "0"], "--samples"),
    (["render", "-o", "x.exr", "--fresnel", "fancy"], "--fresnel"),
    (["render", "missing.json", "-o", "x.exr"], "missing.json"),
    (["render"], "-o"),
])
def test_bad_arguments_give_one_line_and_exit_2(args, fragment):
    r = run(*args)
    assert r.returncode == 2
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and fragment in lines[0], r.stderr
