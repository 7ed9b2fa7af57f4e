"""The stopping rules in Blender: Sampling panel properties, the estimate operator, both CLI verbs."""
import json
import re

import bpy
import pytest

from conftest import REPO  # noqa: F401
from test_cli import run_cli

import mcrt_addon  # noqa: F401


def test_stopping_properties_convert_to_settings(empty_scene):
    from mcrt_addon import bridge
    props = empty_scene.tncg15
    s = props.to_settings(bridge.settings_class())
    assert (s.noise_target, s.time_limit, s.min_samples) == (0.0, 0.0, 0)       # off by default
    props.use_noise_target, props.noise_target, props.min_samples = True, 0.02, 9999
    props.time_limit, props.adaptive, props.samples = 12.5, False, 64
    s = props.to_settings(bridge.settings_class())
    assert (s.noise_target, s.time_limit, s.adaptive) == (pytest.approx(0.02), 12.5, False)
    assert s.min_samples == 64                     # clamped to the cap, as Cycles
    s.validate()


def test_estimate_operator_is_registered(empty_scene):
    assert hasattr(bpy.types, "TNCG15_OT_estimate_render_time")
    assert bpy.ops.tncg15.estimate_render_time.poll()


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_cli_noise_target_stats_and_exr_metadata(tmp_path):
    import OpenImageIO as oiio
    out, stats = tmp_path / "o.exr", tmp_path / "s.json"
    r = run_cli("render", f"{REPO}/sample_blends/cornell.blend", "-o", out, "--resolution", "32", "32",
                "--samples", "512", "--noise-target", "0.15", "--stats-json", stats)
    assert r.returncode == 0, r.stderr
    st = json.loads(stats.read_text())
    assert st["stopped_by"] == "noise target" and st["estimated_rel_error"] <= 0.15
    assert st["seconds_to_target"] > 0 and st["noise_target"] == pytest.approx(0.15)
    spec = oiio.ImageInput.open(str(out)).spec()
    assert spec.getattribute("tncg15:estimated_rel_error") == pytest.approx(st["estimated_rel_error"], rel=1e-6)


@pytest.mark.slow          # 2-5 s (renders, subprocesses): make test-slow, which .ci/run runs too
def test_cli_estimate_prints_a_prediction(tmp_path):
    r = run_cli("estimate", f"{REPO}/sample_blends/cornell.blend", "--noise-target", "0.05",
                "--resolution", "32", "32", "--samples", "1024", "--json")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert "to 5 %" in lines[-2] or "cap of" in lines[-2]
    e = json.loads(lines[-1])
    # the pilot is the real render's passes up to the first pass end at or past 64 samples
    assert e["seconds"] > 0 and 64 <= e["pilot_samples"] < 96 and e["resolution"] == [32, 32]


@pytest.mark.parametrize("args,fragment", [
    (["--noise-target", "0"], "--noise-target must be above 0"),
    (["--noise-target", "5"], "must be from 0 to 1"),
])
def test_cli_estimate_bad_input_one_line(tmp_path, args, fragment):
    r = run_cli("estimate", f"{REPO}/sample_blends/cornell.blend", *args)
    assert r.returncode == 2 and fragment in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow          # two Blender 3.4 starts: `make test-all`
def test_blender34_binary_shows_the_error_in_the_stats_line(tmp_path):
    """Debian's Blender 3.4 from the repository (as test_blender34.py): the noise target set on the
    scene stops the render, and the stats line carries the estimate."""
    import test_blender34 as b34
    if b34.BLENDER is None:
        pytest.skip("no `blender` binary")
    out = tmp_path / "b34"
    r = b34.blender("-b", "--factory-startup", "--python", f"{REPO}/sample_blends/make_samples.py", "--",
                    "--outdir", str(out), "--only", "cornell", "--resolution", "24", "24")
    assert r.returncode == 0, r.stderr[-2000:]
    r = b34.blender("-b", "--python-use-system-env", str(out / "cornell.blend"), "--python-expr",
                    "import bpy, mcrt_addon; mcrt_addon.register(); p = bpy.context.scene.tncg15; "
                    "p.samples = 512; p.use_noise_target = True; p.noise_target = 0.2",
                    "-E", "TNCG15_MC", "-o", str(tmp_path / "out_####"), "-F", "OPEN_EXR", "-f", "1",
                    env=b34.user_env())
    assert r.returncode == 0 and (tmp_path / "out_0001.exr").exists(), r.stdout[-3000:] + r.stderr[-3000:]
    assert re.search(r"Sample \d+/512 · Remaining [0-9:-]+ · est\. error", r.stdout), r.stdout[-3000:]
    assert "(stopped by noise target)" in r.stdout and "Traceback" not in r.stdout + r.stderr
