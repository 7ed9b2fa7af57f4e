"""TNCG15 MC agrees with Cycles of the running Blender at the silhouettes of smooth-shaded microfacet
surfaces: there the interpolated shading normal faces away from the viewer, and Cycles bends the
closure normal of its Glossy, Glass and Refraction BSDFs towards the geometric normal
(maybe_ensure_valid_specular_reflection; engine/materials/specular.py specular_normal_at).  The
scene is the case of a real file (the Ignis renderer's evaluation scene flipped-prim.blend): a
smooth 32-sided rough glass cylinder mirrored by the object scale (1, 1, -1), before a uniform
grey world; beside it a smooth rough metal (Glossy BSDF) cylinder.  The control renders the
lobes on the raw shading normal (the tracer before): the silhouettes go dark and the comparison
fails.

Method and settings as tests/addon/test_agreement.py (tests/addon/rendering.py): 64 x 64, 32 spp,
max depth 8, K = 4 seeds, 8 x 8 block means and the image mean within the Sidak-corrected z bound
plus tau.  Several seconds: `make test-slow`.
"""
import bpy
import bmesh
import pytest

from imagecompare import compare_runs
from mcrt_addon import bridge
from rendering import RES, cycles_reference, export_blend, tncg15_agreement_runs

TAU = 0.02
pytestmark = pytest.mark.slow


def cylinder(bm):
    bmesh.ops.create_cone(bm, cap_ends=True, segments=32, radius1=0.42, radius2=0.42, depth=1.3)


@pytest.fixture(scope="module")
def blend(tmp_path_factory, make_samples_module, addon):
    ms = make_samples_module
    scene = ms.reset()
    ms.world_colour(scene, (0.8, 0.8, 0.8))
    ms.mesh_object(scene, "GlassCylinder", cylinder, ms.dielectric("Rough glass", "ShaderNodeBsdfGlass", (1, 1, 1),
                                                                   0.175, "MULTI_GGX", ior=1.55),
                   location=(-0.48, 0.0, 1.0), scale=(1.0, 1.0, -1.0), smooth=True)
    ms.mesh_object(scene, "MetalCylinder", cylinder, ms.glossy("Rough metal", (0.9, 0.9, 0.9), 0.3, "GGX"),
                   location=(0.48, 0.0, 1.0), smooth=True)
    ms.camera(scene)
    ms.settings(scene, RES)
    path = str(tmp_path_factory.mktemp("silhouette") / "silhouette.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return path


def run(blend, first_seed):
    scene = export_blend(blend, RES).scene
    assert all(m.normals is not None for m in scene.meshes)        # smooth, tessellated (no implicit spheres)
    return compare_runs(tncg15_agreement_runs(scene, first_seed), cycles_reference(blend, "silhouette"), tau=TAU)


def test_smooth_silhouettes_agree_with_cycles(blend):
    result = run(blend, 1000)
    print(f"silhouette: {result.summary()}")
    assert result.passed, result.summary()


def test_comparison_catches_lobes_on_the_raw_shading_normal(blend, monkeypatch):
    """Control: the microfacet lobes built on the raw shading normal (dot(wo, n) < 0 at the
    silhouettes: every sample there lost)."""
    for name in ("materials.dielectric", "materials.glossy", "materials.principled_glass"):
        monkeypatch.setattr(bridge.module(name), "specular_normal_at", lambda si: si.n)
    result = run(blend, 2000)
    print(f"silhouette on the raw shading normal: {result.summary()}")
    assert not result.passed, result.summary()
