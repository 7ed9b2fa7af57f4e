"""TNCG15 MC agrees with Cycles of the running Blender on Blender's own factory startup file: the
default cube (a Principled BSDF at the node's defaults: roughness 0.5, IOR 1.5 / specular 0.5), its
point light and camera, made by Blender (`read_factory_settings`) rather than by our sample builder.
The comparison catches the cube rendered as the Lambertian of its base colour (what the tracer did
before it modelled the Principled BSDF) and the other version's Principled model.

Method and settings as tests/addon/test_agreement.py: 64 x 64, 32 spp, max depth 8, K = 4 seeds each,
8 x 8 block means and the image mean within the Sidak-corrected z bound plus tau.  The cube covers
about a fifth of the image, so the controls are judged on its blocks too (the image mean alone
moves little).  Blender 3.4's startup file: tests/addon/test_agreement_blender34.py.
"""
import copy
import os
import subprocess
import sys

import pytest

from imagecompare import compare_runs
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

TAU = 0.02
pytestmark = pytest.mark.slow

MAKE_STARTUP = ("import bpy, sys; bpy.ops.wm.read_factory_settings(use_empty=False); "
                "bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])")


@pytest.fixture(scope="module")
def startup_blend(tmp_path_factory, addon):
    """Blender's factory startup file, saved by a separate bpy process (reading factory settings
    in this process would reset the add-ons of the other tests)."""
    path = str(tmp_path_factory.mktemp("startup") / "startup.blend")
    r = subprocess.run([sys.executable, "-c", MAKE_STARTUP, path], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and os.path.exists(path), r.stdout[-2000:] + r.stderr[-2000:]
    return path


def exported(startup_blend):
    return copy.deepcopy(export_blend(startup_blend, RES).scene)


def compare(scene, startup_blend, first_seed):
    return compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(startup_blend, "startup"), tau=TAU)


def test_the_default_cube_agrees_with_cycles(startup_blend):
    scene = exported(startup_blend)
    cube = [m for m in scene.materials if m.kind == "principled"]
    assert len(cube) == 1, [(m.name, m.kind) for m in scene.materials]
    result = compare(scene, startup_blend, 1000)
    print(f"startup cube: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_the_default_cube_as_lambert(startup_blend):
    """Control: the cube's Principled BSDF as the Lambertian of its base colour (the old export)."""
    scene = exported(startup_blend)
    for m in scene.materials:
        if m.kind == "principled":
            m.kind, m.principled = "diffuse", None
    result = compare(scene, startup_blend, 2000)
    print(f"startup cube as Lambert: {result.summary()}")
    assert not result.passed, result.summary()


def test_comparison_catches_the_default_cube_with_the_3x_model(startup_blend):
    """Control: the cube's Principled BSDF as Blender 3.x's (v1) model with the same inputs."""
    from engine.scene.model import PrincipledV1
    scene = exported(startup_blend)
    for m in scene.materials:
        if m.kind == "principled":
            m.principled = PrincipledV1(metallic=m.principled.metallic if m.principled else 0.0)
    result = compare(scene, startup_blend, 3000)
    print(f"startup cube as v1: {result.summary()}")
    assert not result.passed, result.summary()
