"""Fixtures for the Blender add-on tests (bpy 5.0.1 module, in-process)."""
import importlib.util
import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
for p in (REPO, HERE):
    if p not in sys.path:
        sys.path.insert(0, p)

import bpy  # noqa: E402  (requirements.txt installs the bpy module: a missing one is a failure)


@pytest.fixture(scope="session")
def addon():
    import mcrt_addon
    from mcrt_addon.headless import ensure_registered
    ensure_registered(mcrt_addon)
    return mcrt_addon


@pytest.fixture(scope="session")
def make_samples_module():
    spec = importlib.util.spec_from_file_location("make_samples", os.path.join(REPO, "sample_blends",
                                                                                "make_samples.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def samples(tmp_path_factory, make_samples_module, addon):
    """Freshly generated sample .blend files (so the generator script itself is tested)."""
    outdir = tmp_path_factory.mktemp("sample_blends")
    paths = {name: make_samples_module.make(name, str(outdir)) for name in make_samples_module.SCENES}
    return paths


@pytest.fixture
def empty_scene(addon):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene



@pytest.fixture
def ms(make_samples_module):
    """sample_blends/make_samples.py: its builders (camera, mesh_object, materials) for scenes made in a test."""
    return make_samples_module


@pytest.fixture
def scene(empty_scene, ms):
    """An empty scene with the sample scenes' camera."""
    ms.camera(empty_scene)
    return empty_scene


@pytest.fixture(scope="session")
def built_zips(tmp_path_factory):
    """{"extension": zip, "legacy": zip} from scripts/build_extension.py, built once per test run
    (tests/addon/test_packaging.py, test_blender34.py and test_viewport_blender34.py read them)."""
    out = tmp_path_factory.mktemp("dist")
    r = subprocess.run([sys.executable, os.path.join(REPO, "scripts", "build_extension.py"), "--output-dir", str(out)],
                       capture_output=True, text=True, timeout=900, cwd=REPO)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    zips = sorted(p for p in out.iterdir() if p.suffix == ".zip")
    return {("legacy" if "legacy" in p.name else "extension"): p for p in zips}
