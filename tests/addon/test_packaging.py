"""`python scripts/build_extension.py` builds a valid extension zip that Blender (bpy 5.0) installs,
enables and renders with, using the tracer copy bundled inside the zip; plus the legacy zip."""
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from rendering import read_exr


INSTALL_AND_RENDER = r'''
import sys, bpy
zip_path, blend, out = sys.argv[1:4]
r = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
assert r == {"FINISHED"}, r
bpy.ops.wm.open_mainfile(filepath=blend)
sc = bpy.context.scene
sc.render.engine = "TNCG15_MC"
sc.tncg15.samples = 4
sc.tncg15.use_denoising = True              # with the extension's pyoidn wheel, in the worker Python
sc.render.resolution_x = sc.render.resolution_y = 24
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.filepath = out
engine = sys.modules[next(m for m in sys.modules if m.endswith("tncg15_mc.render_engine"))]
with engine.capture_reports() as reports:
    bpy.ops.render.render(write_still=True)
tracers = [m for m in sys.modules if m.endswith(".tracer.scene.model")]
print("TRACER", tracers)
print("DENOISED", reports[-1].stats.get("denoised"), reports[-1].warnings)
'''


@pytest.fixture(scope="module")
def built(built_zips):
    return built_zips


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_extension_zip_contents(built):
    with zipfile.ZipFile(built["extension"]) as zf:
        names = set(zf.namelist())
        manifest = zf.read("blender_manifest.toml").decode()
    assert {"blender_manifest.toml", "__init__.py", "render_engine.py", "properties.py", "ui.py",
            "export/__init__.py", "tracer/__init__.py", "tracer/api.py", "tracer/scene/model.py",
            "docs/user-guide.md", "docs/settings.md"} <= names
    wheels = [n for n in names if n.startswith("wheels/") and n.endswith(".whl")]
    assert any("embreex" in w for w in wheels) and any("openimageio" in w.lower() for w in wheels)
    assert not any(os.path.basename(w).startswith("numpy") for w in wheels)
    assert not any("__pycache__" in n for n in names)
    for w in wheels:
        assert f'"./{w}"' in manifest
    for pkg in ("pyoidn", "cffi", "pycparser"):                  # the denoiser, bundled by default
        assert any(os.path.basename(w).startswith(pkg + "-") for w in wheels), (pkg, wheels)
    for pkg in ("numba", "llvmlite"):                            # the compiled kernels (engine/core/backend.py)
        assert any(os.path.basename(w).startswith(pkg + "-") for w in wheels), (pkg, wheels)


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_blender_ext_validates(built):
    import glob
    import sysconfig
    cli = glob.glob(os.path.join(sysconfig.get_paths()["purelib"], "bpy", "*", "scripts", "addons_core", "bl_pkg",
                                 "cli", "blender_ext.py"))[0]
    r = subprocess.run([sys.executable, cli, "validate", str(built["extension"])], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_extension_installs_and_renders_in_blender_5(built, samples, tmp_path):
    script = tmp_path / "install.py"
    script.write_text(INSTALL_AND_RENDER)
    out = tmp_path / "ext.exr"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    env.pop("PYTHONPATH", None)                 # the repo must not be importable: use the zip's copy
    r = subprocess.run([sys.executable, str(script), str(built["extension"]), samples["cornell"], str(out)],
                       capture_output=True, text=True, timeout=600, env=env, cwd=str(tmp_path))
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "bl_ext.user_default.tncg15_mc.tracer.scene.model" in r.stdout
    site = tmp_path / "user" / "extensions" / ".local" / "lib" / "python3.11" / "site-packages"
    assert (site / "embreex").is_dir(), "the embreex wheel was not installed by Blender"
    assert (site / "pyoidn").is_dir() and "DENOISED True []" in r.stdout, r.stdout[-2000:]
    img = read_exr(str(out))
    assert img.shape == (24, 24, 3) and np.isfinite(img).all() and img.mean() > 0.02


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_legacy_zip_is_a_3x_addon_folder(built):
    with zipfile.ZipFile(built["legacy"]) as zf:
        names = set(zf.namelist())
        init = zf.read("tncg15_mc/__init__.py").decode()
    assert "bl_info" in init
    assert {"tncg15_mc/render_engine.py", "tncg15_mc/tracer/api.py", "tncg15_mc/export/mesh.py",
            "tncg15_mc/docs/user-guide.md"} <= names
    assert not any(n.endswith(".whl") for n in names)            # wheels unpacked: importable as they are
    assert "tncg15_mc/vendor/numpy/numpy/__init__.py" in names
    assert "tncg15_mc/vendor/worker/embreex/__init__.py" in names
    assert not any(n.startswith("tncg15_mc/vendor/numpy/embreex") for n in names)   # never in Blender's process
    for path in ("pyoidn/__init__.py", "cffi/__init__.py", "pycparser/__init__.py",     # the denoiser: the workers'
                 "numba/__init__.py", "llvmlite/__init__.py"):                          # and the compiled kernels
        assert f"tncg15_mc/vendor/worker/{path}" in names, path
        assert f"tncg15_mc/vendor/numpy/{path}" not in names
