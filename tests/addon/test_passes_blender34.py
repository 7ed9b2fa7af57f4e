"""Debian's Blender 3.4 (its own binary, the add-on from the repository) writes Cycles' passes with
3.4's names (IndexOB, IndexMA, Emit, Env, DiffDir ... : mcrt_addon/passes.py LEGACY_NAMES), and its
first-hit passes agree with 3.4's Cycles on tests/addon/test_passes_cycles.py's scene."""
import json
import os
import shutil
import subprocess
import sysconfig

import numpy as np
import pytest

from conftest import REPO
from mcrt_addon import passes as addon_passes
from test_passes_cycles import CRYPTO, MIN_SHARE, PASSES, TOLERANCE, share_within

BLENDER = os.environ.get("BLENDER_BIN") or shutil.which("blender")
pytestmark = pytest.mark.skipif(BLENDER is None and os.environ.get("CI") != "true",
                                reason="no `blender` binary (apt-get install blender)")

SCRIPT = r'''
import json, sys, bpy
out_dir = sys.argv[sys.argv.index("--") + 1]
import mcrt_addon
mcrt_addon.register()
sys.path.insert(0, sys.argv[sys.argv.index("--") + 2])
import test_passes_cycles as t
from mcrt_addon import passes as addon_passes
scene = t.build_scene()
for name in ("diffuse_direct", "diffuse_indirect", "diffuse_color", "glossy_direct", "glossy_indirect",
             "glossy_color", "transmission_direct", "transmission_indirect", "transmission_color"):
    setattr(scene.view_layers[0], addon_passes.TOGGLES[name], True)
for engine in ("CYCLES", "TNCG15_MC"):
    addon_passes.set_multilayer_output(scene)
    if engine == "CYCLES":
        c = scene.cycles
        scene.render.engine = "CYCLES"
        c.device, c.samples, c.use_denoising, c.seed = "CPU", t.SPP, False, 3
        c.use_adaptive_sampling, c.pixel_filter_type, c.filter_width, c.max_bounces = False, "BOX", 1.0, 4
    else:
        scene.render.engine = "TNCG15_MC"
        p = scene.tncg15
        p.samples, p.seed, p.max_depth, p.pixel_filter_type, p.filter_width = t.SPP, 3, 4, "BOX", 1.0
    scene.render.filepath, scene.render.use_file_extension = f"{out_dir}/{engine}.exr", False
    scene.render.use_compositing = False
    bpy.ops.render.render(write_still=True)
json.dump({"version": list(bpy.app.version)}, open(f"{out_dir}/done.json", "w"))
'''


def legacy(name):
    pass_name = addon_passes.BLENDER_PASSES[name][0]
    return addon_passes.LEGACY_NAMES.get(pass_name, pass_name)


def layer(channels, name):
    chans = addon_passes.BLENDER_PASSES[name][2]
    return np.stack([channels[f"ViewLayer.{legacy(name)}.{c}"] for c in chans], axis=-1)


@pytest.mark.slow          # ~15 s: Blender 3.4 starts, renders Cycles and TNCG15 MC
def test_blender34_writes_cycles_passes_with_its_names(tmp_path):
    script = tmp_path / "passes34.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, sysconfig.get_paths()["purelib"]]))
    r = subprocess.run([BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python", str(script),
                        "--", str(tmp_path), os.path.join(REPO, "tests", "addon")],
                       capture_output=True, text=True, timeout=600, env=env)
    assert (tmp_path / "done.json").exists(), r.stdout[-3000:] + r.stderr[-3000:]
    assert json.loads((tmp_path / "done.json").read_text())["version"][:2] == [3, 4]
    from engine.film.passes import read_multilayer_exr
    cycles, ours = (read_multilayer_exr(tmp_path / f"{e}.exr") for e in ("CYCLES", "TNCG15_MC"))
    for name in ("IndexOB", "IndexMA", "Emit", "Env", "DiffDir", "GlossInd", "TransCol", "Mist", "UV"):
        assert any(k.startswith(f"ViewLayer.{name}.") for k in ours), (name, sorted(ours))
    for name in CRYPTO:                     # Cryptomatte: rank 0's ids bit for bit (any channel case)
        def ids(channels):
            key = next(k for k in channels if k.lower() == f"viewlayer.{legacy(name).lower()}00.r")
            return channels[key].view(np.uint32)
        assert (ids(ours) == ids(cycles)).mean() >= MIN_SHARE - 0.02, name
    for name in [n for n in PASSES if n not in CRYPTO]:
        share = share_within(layer(ours, name), layer(cycles, name),
                             TOLERANCE[name] if name != "position" else 0.3)
        assert share >= MIN_SHARE - 0.02, (name, share)
    # Cycles' identity in 3.4 too: Combined = Emit + Env + sum of Col x (Dir + Ind)
    combined = np.stack([ours[f"ViewLayer.Combined.{c}"] for c in "RGB"], axis=-1)
    total = layer(ours, "emission") + layer(ours, "environment") + sum(
        layer(ours, f"{k}_color") * (layer(ours, f"{k}_direct") + layer(ours, f"{k}_indirect"))
        for k in ("diffuse", "glossy", "transmission"))
    assert np.allclose(total, combined, rtol=1e-4, atol=1e-4)
