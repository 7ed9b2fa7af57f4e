"""Sampling > Viewport > Denoise in a real Blender window: Debian's Blender 3.4 under Xvfb with the
legacy zip (which bundles pyoidn) installed as a user installs it
(tests/addon/viewport_denoise_gui_script.py drives Blender).  The Rendered viewport reaches Max
Samples and draws its denoised picture, made at 1, 2 and 4 samples only (not at every sample);
turning Denoise off shows the noisy picture of the same samples at the next redraw; the
denoised screenshot is smoother than the noisy one (the control: the same measure of the noisy
screenshot) and as bright."""
import json
import os
import subprocess

import numpy as np
import pytest

from conftest import REPO
from test_blender34 import legacy_zip  # noqa: F401 - the module fixture builds the zip
from test_viewport_blender34 import BLENDER, XVFB, read_png

pytestmark = [pytest.mark.skipif((BLENDER is None or XVFB is None) and os.environ.get("CI") != "true",
                                 reason="needs `blender` and `xvfb-run` (apt-get install blender xvfb)"),
              pytest.mark.slow]
SCRIPT = os.path.join(REPO, "tests", "addon", "viewport_denoise_gui_script.py")
SIZE = (1000, 700)


def roughness(img):
    """Mean absolute difference of horizontal neighbours: pixel noise, in linear units."""
    return float(np.abs(np.diff(img, axis=1)).mean())


def test_the_viewport_denoises_in_blender34(legacy_zip, tmp_path):  # noqa: F811
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"), BLENDER_USER_CONFIG=str(tmp_path / "config"))
    out = tmp_path / "out"
    out.mkdir()
    r = subprocess.run([XVFB, "-a", "-s", f"-screen 0 {SIZE[0]}x{SIZE[1]}x24", BLENDER, "--factory-startup",
                        "-p", "0", "0", str(SIZE[0]), str(SIZE[1]), "--python", SCRIPT, "--", str(legacy_zip),
                        os.path.join(REPO, "sample_blends", "cornell.blend"), str(out)],
                       capture_output=True, text=True, timeout=600, env=env)
    report_path = out / "gui.json"
    assert report_path.exists(), r.stdout[-3000:] + r.stderr[-3000:]
    report = json.loads(report_path.read_text())
    assert report["error"] is None, report["error"]
    assert report["denoise_count"] <= 3, report             # 1, 2, 4 samples: not at every sample
    denoised, noisy = read_png(out / "viewport_denoised.png"), read_png(out / "viewport_noisy.png")
    h, w = denoised.shape[:2]
    box = (slice(h // 5, 4 * h // 5), slice(w // 4, 3 * w // 4))   # inside the camera frame
    d, n = denoised[box], noisy[box]
    print(f"Blender 3.4 viewport {report['resolution']}: denoised picture drawn after {report['denoised_seconds']:.1f} s "
          f"({report['denoise_count']} denoises); roughness "
          f"{roughness(n):.4f} noisy, {roughness(d):.4f} denoised; mean {n.mean():.3f} / {d.mean():.3f}")
    assert roughness(d) < 0.6 * roughness(n)
    assert abs(d.mean() - n.mean()) < 0.1 * n.mean()
