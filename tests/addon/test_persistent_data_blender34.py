"""Persistent Data in Debian's Blender 3.4 (`blender -b`): an animation's frames rendered by kept
workers are bit for bit those of fresh workers (tests/addon/test_persistent_data.py does the same in
bpy 5.0)."""
import json
import os
import subprocess

import numpy as np
import pytest

from blender34 import BLENDER34, REPO, blender_environment

# Runs in Blender 3.4: suzanne_100k.blend's Suzanne moves on frames 1-3, rendered with Persistent
# Data off and then on (OpenEXR, float32), the frames read back as arrays.
SCRIPT = r'''
import json, sys, bpy, numpy as np
out = sys.argv[sys.argv.index("--") + 1]
import mcrt_addon.render_engine as tncg
reports = []
tncg.REPORT_LISTENERS.append(lambda r: reports.append({"read": (r.export or {}).get("meshes_read"),
                                                       "pids": list(r.stats.get("worker_pids") or []),
                                                       "renders": r.stats.get("renders_on_pool")}))
sc = bpy.context.scene
ob = sorted((o for o in sc.objects if o.type == "MESH"), key=lambda o: o.name)[-1]
for f in (1, 2, 3):
    ob.location.x = 0.05 * f
    ob.rotation_euler.z = 0.1 * f
    ob.keyframe_insert("location", frame=f)
    ob.keyframe_insert("rotation_euler", frame=f)
sc.frame_start, sc.frame_end = 1, 3
sc.render.engine = "TNCG15_MC"
sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 40, 32, 100
sc.tncg15.samples = 2
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.image_settings.color_depth = "32"
frames = {}
for persistent in (False, True):
    sc.render.use_persistent_data = persistent
    sc.render.filepath = f"{out}/pd{int(persistent)}_"
    bpy.ops.render.render(animation=True)
    for f in (1, 2, 3):
        image = bpy.data.images.load(f"{out}/pd{int(persistent)}_{f:04d}.exr")
        frames[f"pd{int(persistent)}_{f}"] = np.array(image.pixels[:], np.float32)
np.savez(f"{out}/frames.npz", **frames)
json.dump(reports, open(f"{out}/reports.json", "w"))
'''


@pytest.mark.slow          # about 20 s: two 3-frame animations in Blender 3.4
def test_blender34_animation_with_persistent_data_renders_each_frame_as_fresh_workers(tmp_path):
    script = tmp_path / "animate.py"
    script.write_text(SCRIPT)
    r = subprocess.run([BLENDER34, "-b", os.path.join(REPO, "sample_blends", "suzanne_100k.blend"), "--factory-startup",
                        "--python-use-system-env", "--addons", "mcrt_addon", "--python", str(script), "--", str(tmp_path)],
                       env=blender_environment(), capture_output=True, text=True, timeout=600)
    assert (tmp_path / "frames.npz").exists(), r.stdout[-2000:] + r.stderr[-2000:]
    frames = np.load(tmp_path / "frames.npz")
    reports = json.loads((tmp_path / "reports.json").read_text())
    off, on = reports[:3], reports[3:]
    assert [x["read"] for x in off] == [7, 7, 7] and not any(x["renders"] for x in off)
    # kept: one pool, the moved Suzanne never read again, every frame prepared on it
    assert [x["read"] for x in on] == [7, 0, 0] and len({tuple(x["pids"]) for x in on}) == 1 and on[0]["pids"]
    assert [x["renders"] for x in on] == [1, 2, 3]
    for f in (1, 2, 3):
        np.testing.assert_array_equal(frames[f"pd1_{f}"], frames[f"pd0_{f}"])
    assert not np.array_equal(frames["pd1_2"], frames["pd1_3"])              # the frames differ
