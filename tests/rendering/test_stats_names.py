"""The stats keep one meaning per name: `passes` is the render passes, the stopping rules count
`rounds` and log `round_log` (engine/rendering/stopping.py).  Until the rename, the stopping
rules wrote their count over the render passes: with --noise-target 0.5 --passes albedo,depth
the stats JSON said "passes": 1."""
import json
import os
import subprocess
import sys

from engine import RenderSettings, render
from engine.scene.builtin import cornell_scene

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
QUIET = dict(log=lambda *a: None)


def test_the_stopping_rules_keep_the_render_passes_in_the_stats():
    r = render(cornell_scene((24, 24)), RenderSettings(samples=64, noise_target=0.5, passes=("albedo", "depth"),
                                                      seed=1), **QUIET)
    st = r.stats
    assert st["stopped_by"] == "noise target"
    assert st["passes"] == ["albedo", "depth"] and set(r.passes) == {"albedo", "depth"}
    assert isinstance(st["rounds"], int) and st["rounds"] >= 1 and len(st["round_log"]) == st["rounds"]
    assert "pass_log" not in st


def test_the_stats_json_of_the_command_line_names_the_render_passes(tmp_path):
    stats = tmp_path / "stats.json"
    p = subprocess.run([sys.executable, "-m", "engine", "render", "--resolution", "24", "24", "--samples", "64",
                        "--noise-target", "0.5", "--passes", "albedo,depth", "--quiet", "-o", str(tmp_path / "o.exr"),
                        "--stats-json", str(stats)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    st = json.loads(stats.read_text())
    assert st["passes"] == ["albedo", "depth"], st["passes"]
    assert st["rounds"] >= 1 and len(st["round_log"]) == st["rounds"]


def test_without_stopping_rules_there_are_no_rounds():
    st = render(cornell_scene((16, 16)), RenderSettings(samples=4, passes=("depth",)), **QUIET).stats
    assert st["passes"] == ["depth"] and "rounds" not in st and "round_log" not in st
