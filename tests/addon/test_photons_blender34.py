"""Caustic photons in Debian's Blender 3.4.1 (`blender -b`, the legacy zip installed as a user
does, as tests/addon/test_blender34.py): its render workers run Blender's own Python, which has no
scipy, so the gather takes photon_map.py's NumPy grid; each photon batch is traced once and shared
with both workers (engine/rendering/photon_passes.py)."""
import json
import os

import numpy as np
import pytest

from conftest import REPO
from rendering import read_exr
from test_blender34 import BLENDER, blender

pytestmark = [pytest.mark.slow,       # 15-30 s: a zip installed into a fresh Blender 3.4 profile
              pytest.mark.skipif(BLENDER is None and os.environ.get("CI") != "true",
                                 reason="no `blender` binary (apt-get install blender)")]

RENDER_WITH_PHOTONS = r'''
import json, sys, bpy
zip_path, blend, out, stats_path = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
bpy.ops.wm.open_mainfile(filepath=blend)
import tncg15_mc.render_engine as engine
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
p = sc.tncg15
p.samples, p.caustics_method, p.photons_per_pass, p.threads = 12, "PHOTONS", 3000, 2
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.filepath = out
with engine.capture_reports() as reports:
    bpy.ops.render.render(write_still=True)
r = reports[-1]
json.dump({"error": r.error, "warnings": r.warnings, "stats": r.stats}, open(stats_path, "w"), default=str)
'''


@pytest.fixture(scope="module")
def caustic34(tmp_path_factory):
    out = tmp_path_factory.mktemp("caustic34")
    r = blender("-b", "--factory-startup", "--python", os.path.join(REPO, "sample_blends", "make_samples.py"),
                "--", "--outdir", str(out), "--only", "caustic", "--resolution", "32", "24")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return out / "caustic.blend"


def test_blender34_renders_photon_caustics_from_the_legacy_zip(built_zips, caustic34, tmp_path):
    script = tmp_path / "photons.py"
    script.write_text(RENDER_WITH_PHOTONS)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"), BLENDER_USER_CONFIG=str(tmp_path / "config"))
    stats_path, out = tmp_path / "stats.json", tmp_path / "photons.exr"
    r = blender("-b", "--factory-startup", "--python", str(script), "--", str(built_zips["legacy"]), str(caustic34),
                str(out), str(stats_path), env=env, timeout=300)
    log = r.stdout[-3000:] + r.stderr[-3000:]
    assert r.returncode == 0 and stats_path.exists(), log
    report = json.loads(stats_path.read_text())
    assert report["error"] is None, report["error"]
    st = report["stats"]
    assert "worker process" in st["parallelism"] and st["effects"]["photon_caustics"], st["effects_reason"]
    ph = st["photons"]
    assert ph["distribution"] == "shared" and ph["photon_passes_traced"] == 16 and ph["photons_stored"] > 0, ph
    img = read_exr(str(out))
    assert img.shape == (24, 32, 3) and np.isfinite(img).all() and img.mean() > 0.02
    print(f"Blender 3.4, legacy zip: {ph['photon_passes_traced']} photon passes traced once, "
          f"{ph['photons_stored']} stored, render {st['render_seconds']:.2f} s, {st['parallelism']}")
