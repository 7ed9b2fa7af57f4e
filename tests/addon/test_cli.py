"""python -m mcrt_addon: argument handling and real headless renders (subprocesses)."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO
from mcrt_addon.cli import build_parser, main
from rendering import read_exr


def run_cli(*args, timeout=300):
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "mcrt_addon", *map(str, args)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


def test_parser_accepts_the_documented_options():
    args = build_parser().parse_args(
        ["render", "f.blend", "-o", "o.exr", "--engine", "cycles", "--samples", "4", "--shadow-rays", "2",
         "--max-depth", "3", "--accelerator", "EMBREE", "--fresnel", "exact", "--threads", "1", "--seed", "9",
         "--resolution", "32", "24", "--stats-json", "s.json"])
    assert args.engine == "CYCLES" and args.samples == 4 and args.shadow_rays == 2 and args.max_depth == 3
    assert args.accelerator == "embree" and args.fresnel == "exact" and args.threads == 1 and args.seed == 9
    assert args.resolution == [32, 24] and args.stats_json == "s.json"


@pytest.mark.parametrize("bad", [["--samples", "0"], ["--max-depth", "-1"], ["--engine", "EEVEE"],
                                 ["--fresnel", "fast"], ["--resolution", "0", "10"]])
def test_parser_rejects_bad_values(bad):
    with pytest.raises(SystemExit) as exc:
        main(["render", "f.blend", "-o", "o.exr", *bad])
    assert exc.value.code == 2


def test_missing_file_is_an_error(tmp_path):
    r = run_cli("render", tmp_path / "nope.blend", "-o", tmp_path / "o.exr")
    assert r.returncode == 2 and "no such file" in r.stderr


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_cli_renders_both_engines(samples, tmp_path):
    for engine in ("TNCG15_MC", "CYCLES"):
        out, stats_path = tmp_path / f"{engine}.exr", tmp_path / f"{engine}.json"
        r = run_cli("render", samples["cornell"], "-o", out, "--engine", engine, "--samples", "4",
                    "--max-depth", "2", "--resolution", "32", "24", "--seed", "5", "--fresnel", "exact",
                    "--stats-json", stats_path)
        assert r.returncode == 0, r.stderr[-2000:]
        img = read_exr(str(out))
        assert img.shape == (24, 32, 3) and np.isfinite(img).all() and img.mean() > 0.01
        stats = json.loads(stats_path.read_text())
        assert stats["render_seconds"] > 0 and stats["resolution"] == [32, 24]
        if engine == "TNCG15_MC":
            assert stats["samples"] == 4 and stats["max_depth"] == 2 and stats["fresnel"] == "exact"
            assert stats["seed"] == 5 and stats["effects"]["glass"] and stats["rays"]["camera"] > 0
        else:
            assert stats["engine"] == "CYCLES" and stats["samples"] == 4 and stats["max_bounces"] == 2


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_cli_reports_scene_errors(tmp_path, empty_scene, make_samples_module):
    import bpy
    ms = make_samples_module
    ms.camera(empty_scene)
    ms.mesh_object(empty_scene, "Lamp", lambda bm: ms.quad(bm, [(0, 0, 1), (1, 0, 1), (2, 0, 1), (3, 0, 1)]),
                   ms.emission("E", (1, 1, 1), 5.0))
    path = str(tmp_path / "bad.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    r = run_cli("render", path, "-o", tmp_path / "o.exr", "--resolution", "8", "8")
    assert r.returncode == 1
    assert "Object 'Lamp': emitter has zero area" in r.stderr
    assert "Traceback" not in r.stderr


def test_bench_export_prints_figures():
    r = run_cli("bench-export", "--triangles", "20000", "--instances", "5")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "export_scene" in r.stdout and "triangles" in r.stdout
