"""TNCG15 MC agrees with Cycles of the running Blender on rough dielectrics (the rough_glass sample:
a Beckmann rough glass pane before a lit window, a multiscatter-GGX rough glass ball, a translucent
sheet lit from behind; engine/materials/dielectric.py, translucent.py), and the comparison catches
the old export (rough glass rendered smooth) and the single-scatter glass in place of Cycles'
compensated one.

Method and settings as tests/addon/test_agreement.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each,
8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.  Each test renders
Cycles (once per session) and K tracer runs: several seconds, so `make test-slow`.  The same scene
made and rendered by Blender 3.4's binary (its Cycles, its export) agrees within TAU_34.
"""
import copy
import os
import shutil
import subprocess
import sysconfig

import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

TAU = 0.02
pytestmark = pytest.mark.slow


def run(samples, scene, first_seed):
    result = compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(samples["rough_glass"],
                                                                                     "rough_glass"), tau=TAU)
    return result


def exported(samples):
    return copy.deepcopy(export_blend(samples["rough_glass"], RES).scene)


def test_rough_glass_agrees_with_cycles(samples):
    scene = exported(samples)
    kinds = {m.name: (m.kind, m.roughness, m.distribution) for m in scene.materials}
    assert kinds["Frosted"][0] == "glass" and kinds["Frosted"][2] == "multi_ggx" and kinds["Frosted"][1] > 0
    assert kinds["Ground glass"][2] == "beckmann" and kinds["Paper"][0] == "translucent"
    result = run(samples, scene, 1000)
    print(f"rough_glass: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_rough_glass_as_smooth(samples):
    """Control: the glass exported as before (roughness treated as 0: smooth glass)."""
    scene = exported(samples)
    for m in scene.materials:
        if m.kind == "glass":
            m.roughness = 0.0
    result = run(samples, scene, 2000)
    print(f"rough_glass as smooth: {result.summary()}")
    assert not result.passed, result.summary()


def test_comparison_catches_single_scatter_glass(samples):
    """Control: the multiscatter GGX ball rendered without Cycles 4.x's energy compensation."""
    scene = exported(samples)
    for m in scene.materials:
        if m.distribution == "multi_ggx":
            m.distribution = "ggx"
    result = run(samples, scene, 3000)
    print(f"rough_glass single scatter: {result.summary()}")
    assert not result.passed, result.summary()


# -- Blender 3.4 (Debian's binary): its own Cycles and its node vocabulary (Beckmann glass by default) --
BLENDER = os.environ.get("BLENDER_BIN") or shutil.which("blender")
TAU_34 = 0.05       # 3.x's Multiscatter GGX glass is a random walk; the tracer's is 4.x's albedo scaling
CYCLES_34 = r'''
import sys, bpy, mcrt_addon
from mcrt_addon.reference import setup_cycles_reference
out = sys.argv[sys.argv.index("--") + 1]
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = RES
scene.render.resolution_percentage = 100
scene.render.image_settings.file_format = "OPEN_EXR"
for seed in range(1, K + 1):
    setup_cycles_reference(scene, samples=SPP, max_depth=DEPTH, seed=seed)
    scene.render.filepath = f"{out}/cycles{seed}.exr"
    bpy.ops.render.render(write_still=True)
mcrt_addon.register()
from mcrt_addon.export import export_scene
from engine.scene.files import save_scene
save_scene(export_scene(bpy.context.evaluated_depsgraph_get(), resolution=RES).scene, f"{out}/scene.json")
'''


@pytest.fixture(scope="module")
def blender34_run(tmp_path_factory):
    """Cycles 3.4's K runs of the rough_glass sample made by Blender 3.4, and its export."""
    if BLENDER is None and os.environ.get("CI") != "true":
        pytest.skip("no `blender` binary (apt-get install blender)")
    import numpy as np
    from rendering import DEPTH, K, SPP, read_exr
    out = tmp_path_factory.mktemp("rough_glass_34")
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([repo, sysconfig.get_paths()["purelib"]]))
    r = subprocess.run([BLENDER, "-b", "--factory-startup", "--python", os.path.join(repo, "sample_blends", "make_samples.py"),
                        "--", "--outdir", str(out), "--only", "rough_glass"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    script = out / "cycles.py"
    script.write_text(f"RES, K, SPP, DEPTH = {tuple(RES)}, {K}, {SPP}, {DEPTH}\n" + CYCLES_34)
    r = subprocess.run([BLENDER, "-b", "--python-use-system-env", str(out / "rough_glass.blend"), "--python", str(script),
                        "--", str(out)], capture_output=True, text=True, timeout=900, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    from engine.scene.files import load_scene
    return load_scene(str(out / "scene.json")), np.stack([read_exr(str(out / f"cycles{s}.exr")) for s in range(1, K + 1)])


def test_rough_glass_agrees_with_cycles_34(blender34_run):
    scene, ref = blender34_run
    assert tuple(scene.cycles_version) == (3, 4)
    result = compare_runs(tncg15_agreement_runs(scene, 1000), ref, tau=TAU_34)
    print(f"rough_glass (3.4): {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_rough_glass_as_smooth_34(blender34_run):
    scene, ref = blender34_run
    scene = copy.deepcopy(scene)
    for m in scene.materials:
        if m.kind == "glass":
            m.roughness = 0.0
    result = compare_runs(tncg15_agreement_runs(scene, 2000), ref, tau=TAU_34)
    print(f"rough_glass as smooth (3.4): {result.summary()}")
    assert not result.passed, result.summary()
