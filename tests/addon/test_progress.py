"""Progress and summaries (mcrt_addon/render_engine.py, engine/rendering/stopping.py
progress_message) and the modal Estimate Render Time (mcrt_addon/estimate.py), in bpy 5.0:

* the stats line of a render reads "Sample n/N · Remaining mm:ss · est. error x %", the samples
  rise, the time left ends at 00:00, no work-unit counts;
* the last stats line after the render is the "Done ..." summary, and the Info log has it;
* `python -m mcrt_addon render` prints each progress line once (and so does Debian's Blender 3.4
  binary, which prints every stats line itself);
* the estimate at the default settings never says "nan" and says adaptive sampling is off; its
  --json is valid JSON; the modal operator stops on Esc.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import time
from types import SimpleNamespace

import bpy
import pytest

from conftest import REPO
from mcrt_addon import estimate as estimate_module
from rendering import open_blend, render_operator

PROGRESS = re.compile(r"Sample (\d+)/(\d+) · Remaining (\d\d):(\d\d)(?: · est\. error ([\d.]+) %)?$")


def no_nan(text):
    raise ValueError(f"NaN in JSON: {text}")


def stats_of_render(scene):
    """Every update_stats info string of one F12 render, and its RenderReport."""
    from mcrt_addon import render_engine
    with render_engine.capture_reports() as reports:
        render_operator(scene)
    return reports[-1].stats_lines, reports[-1]


def progress_lines(infos):
    return [PROGRESS.search(i.split(" | ", 1)[1]) for i in infos if " | Sample " in i]


@pytest.mark.parametrize("noise_target", [0.0, 0.05])
def test_render_progress_reads_sample_remaining_error(samples, noise_target):
    scene = open_blend(samples["cornell"], (32, 24))
    scene.render.engine = "TNCG15_MC"
    scene.tncg15.samples, scene.tncg15.tile_size = 64, 8
    scene.tncg15.use_noise_target, scene.tncg15.noise_target = noise_target > 0, noise_target or 0.01
    infos, report = stats_of_render(scene)
    assert not any("unit" in i for i in infos), infos
    lines = progress_lines(infos)
    assert len(lines) >= 2 and all(lines), infos
    done = [int(m.group(1)) for m in lines]
    remaining = [int(m.group(3)) * 60 + int(m.group(4)) for m in lines]
    assert done == sorted(done) and all(int(m.group(2)) == 64 for m in lines)
    assert remaining[-1] == 0 and remaining[0] >= remaining[-1]
    assert lines[-1].group(5) is not None               # every pixel has samples: an error
    # the summary is the last stats line, and the Info log has it
    assert infos[-1].startswith("TNCG15 MC | Done: ") and "est. error" in infos[-1], infos[-1]
    assert report.summary == infos[-1]


def cli_render(blend, tmp_path, *extra):
    return subprocess.run([sys.executable, "-m", "mcrt_addon", "render", blend, "-o", str(tmp_path / "out.png"),
                           "--resolution", "32", "24", "--tile-size", "8", *extra], cwd=REPO,
                          capture_output=True, text=True, timeout=600)


def assert_each_progress_line_once(stdout):
    texts = [line.split("TNCG15 MC | ", 1)[1] for line in stdout.splitlines() if "TNCG15 MC | Sample " in line]
    assert texts, stdout[-3000:]
    assert len(texts) == len(set(texts)), "\n".join(texts)
    return texts


def test_command_line_prints_each_progress_line_once(samples, tmp_path):
    r = cli_render(samples["cornell"], tmp_path, "--samples", "64")
    assert r.returncode == 0, r.stderr[-2000:]
    texts = assert_each_progress_line_once(r.stdout)
    assert PROGRESS.search(texts[-1]) and "Remaining 00:00" in texts[-1]


BLENDER = shutil.which("blender")


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
@pytest.mark.skipif(BLENDER is None, reason="no `blender` binary (apt-get install blender)")
def test_blender_binary_prints_each_progress_line_once(tmp_path):
    """Blender 3.4 prints every stats line ("Fra:1 Mem:... | TNCG15 MC | Sample ..."): the engine
    must not print a second copy of each."""
    site = sysconfig.get_paths()["purelib"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, site]))
    script = ("import mcrt_addon, bpy; mcrt_addon.register(); s = bpy.context.scene; "
              "s.render.engine = 'TNCG15_MC'; s.render.resolution_x, s.render.resolution_y = 32, 24; "
              "s.render.resolution_percentage = 100; s.tncg15.samples = 16; s.tncg15.tile_size = 8; "
              f"s.render.filepath = {str(tmp_path / 'out.png')!r}; bpy.ops.render.render(write_still=True)")
    r = subprocess.run([BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python-expr", script],
                       capture_output=True, text=True, timeout=600, env=env)
    assert (tmp_path / "out.png").exists(), r.stdout[-3000:] + r.stderr[-3000:]
    assert_each_progress_line_once(r.stdout)


def test_estimate_at_default_settings_says_adaptive_is_off_and_no_nan(samples):
    scene = open_blend(samples["cornell"], (32, 24))
    assert not scene.tncg15.use_noise_target
    result = estimate_module.estimate_scene(scene, bpy.context.evaluated_depsgraph_get())
    text = bridge_describe(result)
    assert "nan" not in text.lower(), text
    assert "adaptive sampling off" in text and not result["adaptive"], text
    json.loads(json.dumps(result), parse_constant=no_nan)


def bridge_describe(result):
    from mcrt_addon import bridge
    return bridge.module("rendering.estimate").describe(result)


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_estimate_json_has_no_nan(samples):
    r = subprocess.run([sys.executable, "-m", "mcrt_addon", "estimate", samples["cornell"], "--noise-target", "1e-9",
                        "--resolution", "32", "24", "--json"], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    text, line = r.stdout.strip().splitlines()[-2:]
    assert "nan" not in text.lower(), text
    json.loads(line, parse_constant=no_nan)


class FakeOperator:
    """The operator's modal methods on a plain object (bpy 5.0 in-process has no window to run a
    modal operator in)."""

    def __init__(self, job):
        self.job, self.timer, self.reports = job, None, []

    def __getattr__(self, name):        # modal, cancel and their helpers, bound to this object
        return getattr(estimate_module.TNCG15_OT_estimate_render_time, name).__get__(self)

    def report(self, kind, text):
        self.reports.append((set(kind), text))


def fake_context(scene):
    wm = SimpleNamespace(progress_update=lambda v: None, progress_end=lambda: None,
                         event_timer_remove=lambda t: None)
    return SimpleNamespace(scene=scene, window_manager=wm, workspace=None)


def drive(op, context, events, deadline=120.0):
    """Feed `events` (then timer events) to op.modal until it ends; its return value."""
    end = time.monotonic() + deadline
    queue = list(events)
    while time.monotonic() < end:
        event = queue.pop(0) if queue else SimpleNamespace(type="TIMER", value="NOTHING")
        state = op.modal(context, event)
        if state != {"RUNNING_MODAL"} and state != {"PASS_THROUGH"}:
            return state
        time.sleep(0.02)
    raise AssertionError("the estimate did not end")


@pytest.mark.parametrize("press_esc", [True, False])
def test_modal_estimate_cancels_on_esc(samples, press_esc):
    scene = open_blend(samples["cornell"], (32, 24))
    scene.tncg15.samples, scene.tncg15.estimate_text = 4096, ""
    prepared = estimate_module.prepare_estimate(scene, bpy.context.evaluated_depsgraph_get())
    op = FakeOperator(estimate_module.EstimateJob(prepared, pilot_samples=64).start())
    esc = [SimpleNamespace(type="ESC", value="PRESS")] if press_esc else []
    state = drive(op, fake_context(scene), esc)
    if press_esc:                       # the control: without Esc the same pilot finishes
        assert state == {"CANCELLED"} and scene.tncg15.estimate_text == ""
        assert ({"INFO"}, "TNCG15 MC: estimate cancelled") in op.reports
    else:
        assert state == {"FINISHED"} and scene.tncg15.estimate_text and "nan" not in scene.tncg15.estimate_text
