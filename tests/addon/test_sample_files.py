"""The committed sample files (sample_blends/*.blend, made by `make samples`: sample_blends/make_samples.py
in Debian's Blender 3.4): every scene of make_samples.SCENES is there, each opens in Blender 3.4 and in
Blender 5.0 (the bpy module) with TNCG15 MC as its render engine, and was saved by 3.4."""
import glob
import json
import os
import shutil
import subprocess
import sys

import pytest

from conftest import REPO

BLENDER = os.environ.get("BLENDER_BIN") or shutil.which("blender")
SAMPLES = sorted(glob.glob(os.path.join(REPO, "sample_blends", "*.blend")))

# Run in each Blender: register the add-on of the repository, open every file, report its engine.
OPEN_EACH = r'''
import json, sys, bpy
out, files = sys.argv[sys.argv.index("--") + 1], sys.argv[sys.argv.index("--") + 2:]
import mcrt_addon
from mcrt_addon.headless import ensure_registered
ensure_registered(mcrt_addon)
seen = {}
for path in files:
    try:
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    except RuntimeError as exc:
        seen[path] = {"error": str(exc)}
        continue
    seen[path] = {"engine": bpy.context.scene.render.engine, "saved_by": list(bpy.data.version)}
json.dump({"blender": list(bpy.app.version), "files": seen}, open(out, "w"))
'''


def open_each(command, tmp_path, env=None):
    script, out = tmp_path / "open_each.py", tmp_path / "opened.json"
    script.write_text(OPEN_EACH)
    r = subprocess.run([*command, str(script), "--", str(out), *SAMPLES], capture_output=True, text=True,
                       timeout=600, env=env, cwd=REPO)
    assert r.returncode == 0 and out.exists(), r.stdout[-2000:] + r.stderr[-2000:]
    return json.loads(out.read_text())


def problems(opened):
    return [f"{os.path.basename(path)}: {info}" for path, info in opened["files"].items()
            if info.get("engine") != "TNCG15_MC" or tuple(info.get("saved_by", ())[:2]) != (3, 4)]


def test_every_scene_is_committed(make_samples_module):
    assert sorted(os.path.basename(p)[:-6] for p in SAMPLES) == sorted(make_samples_module.SCENES)


@pytest.mark.slow
@pytest.mark.skipif(BLENDER is None, reason="no `blender` binary (apt-get install blender)")
def test_samples_open_in_blender34_with_tncg15(tmp_path):
    env = dict(os.environ, PYTHONPATH=REPO)
    opened = open_each([BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python"], tmp_path, env)
    assert tuple(opened["blender"][:2]) == (3, 4)
    assert problems(opened) == []


@pytest.mark.slow
def test_samples_open_in_blender50_with_tncg15(tmp_path):
    """The bpy module in a subprocess (opening files here would replace the test session's data)."""
    runner = "import runpy, sys; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
    opened = open_each([sys.executable, "-c", runner], tmp_path, dict(os.environ, PYTHONPATH=REPO))
    assert tuple(opened["blender"][:1]) == (5,)
    assert problems(opened) == []
