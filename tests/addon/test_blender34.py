"""A real Blender binary (Debian's Blender 3.4.1, `apt-get install blender`, whose Python has no
numpy) renders a sample .blend with TNCG15 MC:

* from the legacy zip alone, installed the way a user does (Preferences > Add-ons > Install:
  addon_install + addon_enable), without PYTHONPATH: the zip's numpy serves the exporter, the
  render workers run Blender's Python with the zip's embreex, so the stats say Embree;
* from the repository the way the README tells a developer to:

  PYTHONPATH=<repo>:<venv site-packages> blender -b --python-use-system-env FILE.blend \\
      --python-expr "import mcrt_addon; mcrt_addon.register()" -E TNCG15_MC -o OUT_#### -F OPEN_EXR -f 1
"""
import json
import os
import shutil
import subprocess
import sysconfig

import numpy as np
import pytest

from conftest import REPO
from rendering import read_exr
from tests.load_tolerance import prompt_limit

BLENDER = os.environ.get("BLENDER_BIN") or shutil.which("blender")
# .ci/run installs Debian's blender: under CI a missing binary is a failure, not a skip.
pytestmark = pytest.mark.skipif(BLENDER is None and os.environ.get("CI") != "true",
                                reason="no `blender` binary (apt-get install blender)")


def blender(*args, env=None, timeout=600):
    return subprocess.run([BLENDER, *args], capture_output=True, text=True, timeout=timeout, env=env)


@pytest.fixture(scope="module")
def blend34(tmp_path_factory):
    out = tmp_path_factory.mktemp("b34")
    r = blender("-b", "--factory-startup", "--python", os.path.join(REPO, "sample_blends", "make_samples.py"),
                "--", "--outdir", str(out), "--only", "cornell", "textured", "--resolution", "24", "24")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return out / "cornell.blend"


INSTALL_AND_RENDER = r'''
import json, sys, time, bpy
zip_path, blend, out, stats_path = sys.argv[sys.argv.index("--") + 1:]
t0 = time.perf_counter()
bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
enabled = time.perf_counter() - t0
bpy.ops.wm.open_mainfile(filepath=blend)
import tncg15_mc.render_engine as engine
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
sc.tncg15.samples = 4
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.filepath = out
with engine.capture_reports() as reports:
    bpy.ops.render.render(write_still=True)
r = reports[-1]
json.dump({"error": r.error, "warnings": r.warnings, "stats": r.stats, "enable_seconds": enabled,
           "numpy": sys.modules["numpy"].__file__, "embreex_in_blender": "embreex" in sys.modules},
          open(stats_path, "w"), default=str)
'''


@pytest.fixture(scope="module")
def legacy_zip(built_zips):
    return built_zips["legacy"]


@pytest.mark.slow          # 13 s: the legacy zip is built and unpacked into a fresh Blender 3.4 profile
@pytest.mark.parametrize("name", ["cornell", "textured"])
def test_legacy_zip_alone_renders_with_embree_in_blender34(legacy_zip, blend34, tmp_path, name):
    """textured: the exporter reads packed images and UVs with the zip's numpy in Blender 3.4."""
    blend34 = blend34.parent / f"{name}.blend"
    script = tmp_path / "install.py"
    script.write_text(INSTALL_AND_RENDER)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"), BLENDER_USER_CONFIG=str(tmp_path / "config"))
    stats_path, out = tmp_path / "stats.json", tmp_path / "legacy.exr"
    r = blender("-b", "--factory-startup", "--python", str(script), "--", str(legacy_zip), str(blend34),
                str(out), str(stats_path), env=env, timeout=300)
    log = r.stdout[-3000:] + r.stderr[-3000:]
    assert r.returncode == 0 and stats_path.exists(), log
    assert "Traceback" not in r.stdout + r.stderr, log
    report = json.loads(stats_path.read_text())
    assert report["error"] is None, report["error"]
    stats = report["stats"]
    assert stats["accelerator"] == "embree", stats
    assert "worker process" in stats["parallelism"], stats["parallelism"]
    assert "/vendor/numpy/" in report["numpy"] and not report["embreex_in_blender"]
    img = read_exr(str(out))
    assert img.shape == (24, 24, 3) and np.isfinite(img).all() and img.mean() > 0.02
    if name == "textured":
        assert not [w for w in report["warnings"] if "image" in w or "UV" in w], report["warnings"]
        near_floor = img[-3:, 6:18]                  # the checker's near half: red and white squares
        assert near_floor[..., 0].mean() > 1.5 * near_floor[..., 2].mean(), near_floor.mean(axis=(0, 1))
    print(f"Blender 3.4 from the legacy zip: enable {report['enable_seconds']:.2f} s, first tile "
          f"{stats['first_tile_seconds']:.2f} s, render {stats['render_seconds']:.2f} s, {stats['parallelism']}")


INSTALL_AND_CANCEL = r'''
import json, os, sys, time, bpy
zip_path, blend, out, stats_path = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
bpy.ops.wm.open_mainfile(filepath=blend)
import tncg15_mc.render_engine as engine
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
sc.render.resolution_x = sc.render.resolution_y = 96
sc.tncg15.samples = 1024
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.filepath = out
state = {"cancel_at": None}
def fake_break(self):      # Esc cannot be pressed in -b: "pressed" once the first tile is in
    if state["cancel_at"] is None and getattr(self, "tiles_written", 0) > 0:
        state["cancel_at"] = time.perf_counter()
    return state["cancel_at"] is not None
engine.TNCG15RenderEngine._cancel_requested = fake_break
with engine.capture_reports() as reports:
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    stopped = time.perf_counter()
r = reports[-1]
json.dump({"cancelled": r.cancelled, "error": r.error, "stats": r.stats, "pid": os.getpid(),
           "stop_seconds": None if state["cancel_at"] is None else stopped - state["cancel_at"],
           "render_seconds": stopped - t0}, open(stats_path, "w"), default=str)
'''


def workers_of(pid):
    """Pids of render workers started by process `pid` (`python -m engine worker PID`) still alive."""
    found = []
    for entry in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as fh:
                argv = fh.read().split(b"\0")
        except OSError:
            continue
        if b"worker" in argv and argv[argv.index(b"worker") + 1:argv.index(b"worker") + 2] == [str(pid).encode()]:
            found.append(int(entry))
    return found


@pytest.mark.slow          # 4 s; Esc in bpy 5.0: tests/addon/test_render_blender.py
def test_esc_stops_a_blender34_render_within_a_second(legacy_zip, blend34, tmp_path):
    """Esc is fast in Blender 3.4 too (worker processes with Embree, legacy zip): the
    render stops within a second of the request and no worker process outlives it."""
    script = tmp_path / "cancel.py"
    script.write_text(INSTALL_AND_CANCEL)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"), BLENDER_USER_CONFIG=str(tmp_path / "config"))
    stats_path = tmp_path / "stats.json"
    proc = subprocess.Popen([BLENDER, "-b", "--factory-startup", "--python", str(script), "--", str(legacy_zip),
                             str(blend34), str(tmp_path / "cancel.exr"), str(stats_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    log = proc.communicate(timeout=300)[0]
    assert proc.returncode == 0 and stats_path.exists(), log[-3000:]
    report = json.loads(stats_path.read_text())
    assert report["error"] is None and report["cancelled"] is True, report
    assert report["stats"]["accelerator"] == "embree"
    assert report["stop_seconds"] is not None, report
    assert report["stop_seconds"] < prompt_limit(report["render_seconds"] - report["stop_seconds"]), report
    assert workers_of(report["pid"]) == []
    print(f"Blender 3.4: Esc after the first tile stopped the render in {report['stop_seconds']:.3f} s")


def user_env():
    site = sysconfig.get_paths()["purelib"]          # the venv's site-packages (numpy, embreex)
    return dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, site]))


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_blender_binary_renders_with_tncg15(blend34, tmp_path):
    version = blender("--version").stdout.splitlines()[0]
    r = blender("-b", "--python-use-system-env", str(blend34),
                "--python-expr", "import bpy, mcrt_addon; mcrt_addon.register(); bpy.context.scene.tncg15.samples = 4",
                "-E", "TNCG15_MC", "-o", str(tmp_path / "out_####"), "-F", "OPEN_EXR", "-f", "1",
                env=user_env())
    out = tmp_path / "out_0001.exr"
    assert r.returncode == 0 and out.exists(), f"{version}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    img = read_exr(str(out))
    assert img.shape == (24, 24, 3)
    assert np.isfinite(img).all() and img.mean() > 0.02, img.mean()
    assert "Error" not in r.stdout.split("Saved:")[0][-500:]


def test_blender_binary_cycles_reference_runs(blend34, tmp_path):
    """The same file through the binary's own Cycles (denoising must be switched off in 3.4)."""
    expr = ("import bpy, mcrt_addon; from mcrt_addon.reference import setup_cycles_reference; "
            "setup_cycles_reference(bpy.context.scene, samples=8, max_depth=4, seed=1)")
    r = blender("-b", "--python-use-system-env", str(blend34), "--python-expr", expr,
                "-o", str(tmp_path / "cyc_####"), "-F", "OPEN_EXR", "-f", "1", env=user_env())
    out = tmp_path / "cyc_0001.exr"
    assert r.returncode == 0 and out.exists(), r.stdout[-3000:] + r.stderr[-3000:]
    img = read_exr(str(out))
    assert np.isfinite(img).all() and img.mean() > 0.02


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_blender34_fills_passes_and_denoises(blend34, tmp_path):
    """Blender 3.4: the registered passes (Z, Denoising Data, Sample Count, Variance) land in its
    multi-layer EXR, and Denoise runs OIDN in a process of the worker Python (never in Blender's,
    where OIDN aborts 3.4) and keeps the Noisy Image pass."""
    from engine.film.passes import read_multilayer_exr
    expr = ("import bpy, mcrt_addon; mcrt_addon.register(); sc = bpy.context.scene; sc.tncg15.samples = 4; "
            "sc.tncg15.use_denoising = True; vl = sc.view_layers[0]; vl.use_pass_z = True; "
            "vl.tncg15.denoising_store_passes = True; vl.tncg15.pass_sample_count = True; "
            "vl.tncg15.pass_variance = True")
    r = blender("-b", "--python-use-system-env", str(blend34), "--python-expr", expr, "-E", "TNCG15_MC",
                "-o", str(tmp_path / "ml_####"), "-F", "OPEN_EXR_MULTILAYER", "-f", "1", env=user_env())
    out = tmp_path / "ml_0001.exr"
    assert r.returncode == 0 and out.exists(), r.stdout[-3000:] + r.stderr[-3000:]
    assert "Denoise skipped" not in r.stdout + r.stderr, r.stdout[-2000:]
    ch = read_multilayer_exr(out)
    for name in ("Combined.R", "Depth.Z", "Denoising Albedo.R", "Denoising Normal.Z", "Debug Sample Count.X",
                 "Variance.G", "Noisy Image.R"):
        assert f"ViewLayer.{name}" in ch, sorted(ch)
    assert np.all(ch["ViewLayer.Debug Sample Count.X"] == 4.0)
    albedo = ch["ViewLayer.Denoising Albedo.G"]
    assert albedo.min() >= 0.0 and np.median(albedo) <= 1.0 and np.isfinite(albedo).all()
    assert not np.array_equal(ch["ViewLayer.Noisy Image.R"], ch["ViewLayer.Combined.R"])


SMOOTH_EXPORT = r'''
import json, sys, bpy, numpy as np, mcrt_addon
mcrt_addon.register()
from mcrt_addon.export import export_scene
out = sys.argv[sys.argv.index("--") + 1]
result = export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(24, 24))
meshes = {}
for m in result.scene.meshes:
    if m.normals is not None:
        v = m.vertices[m.triangles]
        g = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        g /= np.linalg.norm(g, axis=1)[:, None]
        n = m.normals / np.linalg.norm(m.normals, axis=2)[..., None]
        cos = (n * g[:, None]).sum(-1)
        meshes[m.name] = [len(m.triangles), float(cos.min()), float(cos.mean())]
json.dump({"meshes": meshes, "warnings": result.warnings}, open(out, "w"))
'''


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_blender34_exports_split_normals(tmp_path):
    """Blender 3.4 has no corner_normals: the exporter calls calc_normals_split() and reads
    loop_triangles.split_normals; the smooth sample's normals arrive, on the outside."""
    r = blender("-b", "--factory-startup", "--python", os.path.join(REPO, "sample_blends", "make_samples.py"),
                "--", "--outdir", str(tmp_path), "--only", "smooth", "--resolution", "24", "24")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    r = blender("-b", "--python-use-system-env", str(tmp_path / "smooth.blend"), "--python-expr", SMOOTH_EXPORT,
                "--", str(tmp_path / "out.json"), env=user_env())
    assert r.returncode == 0 and (tmp_path / "out.json").exists(), r.stdout[-3000:] + r.stderr[-3000:]
    data = json.loads((tmp_path / "out.json").read_text())
    assert set(data["meshes"]) == {"Suzanne", "LowPolyBall", "LowPolyMirror"}, data
    assert data["meshes"]["Suzanne"][0] == 15744                      # Subdivision level 2 evaluated
    for name, (_, cos_min, cos_mean) in data["meshes"].items():
        assert cos_min > 0.5 and 0.9 < cos_mean < 1.0, (name, cos_min, cos_mean)   # smooth, not flat
    assert not any("smooth" in w for w in data["warnings"]), data["warnings"]


INSTALL_AND_DENOISE = r'''
import json, sys, bpy
zip_path, blend, out, stats_path = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="tncg15_mc")
bpy.ops.wm.open_mainfile(filepath=blend)
import tncg15_mc.render_engine as engine
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
sc.tncg15.samples = 4
sc.tncg15.use_denoising = True
sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
sc.render.filepath = out
with engine.capture_reports() as reports:
    bpy.ops.render.render(write_still=True)
r = reports[-1]
json.dump({"error": r.error, "warnings": r.warnings, "stats": r.stats, "passes": r.passes,
           "pyoidn_in_blender": "pyoidn" in sys.modules}, open(stats_path, "w"), default=str)
'''


@pytest.mark.slow
def test_legacy_zip_denoises_in_blender34(legacy_zip, blend34, tmp_path):
    """The legacy zip alone brings the denoiser (vendor/worker/pyoidn): Denoise in Debian's Blender
    3.4 gives a denoised Combined and the Noisy Image, OIDN never loaded into Blender's process."""
    from engine.film.passes import read_multilayer_exr
    script = tmp_path / "denoise.py"
    script.write_text(INSTALL_AND_DENOISE)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"), BLENDER_USER_CONFIG=str(tmp_path / "config"))
    stats_path, out = tmp_path / "stats.json", tmp_path / "denoised.exr"
    r = blender("-b", "--factory-startup", "--python", str(script), "--", str(legacy_zip), str(blend34),
                str(out), str(stats_path), env=env, timeout=300)
    log = r.stdout[-3000:] + r.stderr[-3000:]
    assert r.returncode == 0 and stats_path.exists(), log
    report = json.loads(stats_path.read_text())
    assert report["error"] is None and not [w for w in report["warnings"] if "Denoise" in w], report
    assert report["stats"].get("denoised") is True and not report["pyoidn_in_blender"], report
    assert "Noisy Image" in report["passes"], report["passes"]
    ch = read_multilayer_exr(out)
    noisy, combined = ch["ViewLayer.Noisy Image.G"], ch["ViewLayer.Combined.G"]
    assert np.isfinite(combined).all() and combined.mean() > 0.02
    assert np.abs(np.diff(combined, axis=1)).mean() < 0.8 * np.abs(np.diff(noisy, axis=1)).mean()
    print(f"Blender 3.4 legacy zip: denoised in {report['stats']['denoise_seconds']:.2f} s")
