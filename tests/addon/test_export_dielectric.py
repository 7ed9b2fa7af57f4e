"""Exporter: Glass, Refraction, Transparent and Translucent BSDF nodes -> the scene model's dielectric
kinds (mcrt_addon/export/dielectric_nodes.py), in bpy 5.0's node vocabulary here; Blender 3.4's
(Beckmann glass by default, SHARP) through /usr/bin/blender in the slow test at the end."""
import json
import os
import shutil
import subprocess

import pytest

from tests.addon.exporting import export as export_at
from tests.addon.test_export_materials import named, only, plate


def export():
    return export_at((16, 16))


def node(mat):
    return next(n for n in mat.node_tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial")


@pytest.mark.parametrize("menu, distribution", [("GGX", "ggx"), ("MULTI_GGX", "multi_ggx"), ("BECKMANN", "beckmann")])
def test_rough_glass_keeps_roughness_distribution_and_ior(scene, ms, menu, distribution):
    mat = ms.node_material("Frosted", "ShaderNodeBsdfGlass", Color=(0.9, 0.95, 1.0, 1), Roughness=0.3, IOR=1.33)
    node(mat).distribution = menu
    plate(ms, scene, "P", mat)
    res = export()
    m = only(res, "Frosted")
    assert m.kind == "glass" and m.distribution == distribution and m.ior == pytest.approx(1.33)
    assert m.roughness == pytest.approx(0.3) and m.color == pytest.approx((0.9, 0.95, 1.0))
    assert not named(res, "Frosted", "roughness"), res.warnings           # no more "treated as 0"


def test_every_distribution_menu_entry_is_mapped():
    from mcrt_addon.export.dielectric_nodes import GLASS_DISTRIBUTIONS
    from engine.scene.model import DIELECTRIC_DISTRIBUTIONS
    assert set(GLASS_DISTRIBUTIONS) == {"SHARP", "BECKMANN", "GGX", "MULTI_GGX"}       # 3.4's menu; 4.x/5.0 drop SHARP
    assert set(GLASS_DISTRIBUTIONS.values()) <= set(DIELECTRIC_DISTRIBUTIONS)


def test_smooth_glass_stays_smooth(scene, ms):
    plate(ms, scene, "P", ms.glass("Clear", ior=1.5))
    m = only(export(), "Clear")
    assert m.kind == "glass" and m.roughness == 0.0


@pytest.mark.parametrize("roughness", [0.0, 0.4])
def test_refraction_node(scene, ms, roughness):
    mat = ms.node_material("Lens", "ShaderNodeBsdfRefraction", Roughness=roughness)
    node(mat).distribution = "GGX"
    plate(ms, scene, "P", mat)
    m = only(export(), "Lens")
    assert m.kind == "refraction" and m.roughness == pytest.approx(roughness) and m.ior == pytest.approx(1.45)
    assert m.distribution == "ggx"


def test_transparent_node_is_named_for_its_shadows(scene, ms):
    plate(ms, scene, "P", ms.node_material("Veil", "ShaderNodeBsdfTransparent", Color=(0.5, 0.6, 0.7, 1)))
    res = export()
    m = only(res, "Veil")
    assert m.kind == "transparent" and m.color == pytest.approx((0.5, 0.6, 0.7))
    assert named(res, "Veil", "transparent shadows are not modelled"), res.warnings


def test_translucent_node(scene, ms):
    plate(ms, scene, "P", ms.node_material("Paper", "ShaderNodeBsdfTranslucent", Color=(0.8, 0.7, 0.6, 1)))
    res = export()
    m = only(res, "Paper")
    assert m.kind == "translucent" and m.color == pytest.approx((0.8, 0.7, 0.6)) and res.warnings == []


def test_glass_thin_film_and_linked_normal_are_named(scene, ms):
    import bpy
    mat = ms.node_material("Film", "ShaderNodeBsdfGlass", Roughness=0.2)
    if "Thin Film Thickness" not in node(mat).inputs:
        pytest.skip("no thin film on this Blender's Glass BSDF")
    node(mat).inputs["Thin Film Thickness"].default_value = 300.0
    bump = mat.node_tree.nodes.new("ShaderNodeBump")
    mat.node_tree.links.new(bump.outputs[0], node(mat).inputs["Normal"])
    plate(ms, scene, "P", mat)
    res = export()
    assert named(res, "Film", "'Thin Film Thickness' 300 is not modelled"), res.warnings
    assert named(res, "Film", "input 'Normal' is linked"), res.warnings
    assert bpy.app.version >= (5, 0)


BLENDER = os.environ.get("BLENDER_BIN") or shutil.which("blender")
EXPORT_34 = r'''
import json, sys, bpy, mcrt_addon
mcrt_addon.register()
from mcrt_addon.export import export_scene
out = sys.argv[sys.argv.index("--") + 1]
res = export_scene(bpy.context.evaluated_depsgraph_get(), resolution=(16, 16))
json.dump({"materials": {m.name: [m.kind, m.roughness, m.distribution, m.ior, m.sharp_closure]
                         for m in res.scene.materials},
           "warnings": res.warnings}, open(out, "w"))
'''
MAKE_34 = r'''
import sys, bpy
sys.path.insert(0, sys.argv[sys.argv.index("--") + 1])
import importlib.util
spec = importlib.util.spec_from_file_location("ms", sys.argv[-2])
ms = importlib.util.module_from_spec(spec); spec.loader.exec_module(ms)
scene = ms.reset()
ms.camera(scene)
default = ms.node_material("Default glass", "ShaderNodeBsdfGlass", Roughness=0.25)     # 3.4: Beckmann, IOR 1.45
multi = ms.node_material("Multi", "ShaderNodeBsdfGlass", Roughness=0.25)
next(n for n in multi.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfGlass").distribution = "MULTI_GGX"
sharp = ms.node_material("Sharp", "ShaderNodeBsdfRefraction", Roughness=0.5)
next(n for n in sharp.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfRefraction").distribution = "SHARP"
sharp_mirror = ms.node_material("Sharp mirror", "ShaderNodeBsdfGlossy", Roughness=0.0)
next(n for n in sharp_mirror.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfGlossy").distribution = "SHARP"
ggx_mirror = ms.node_material("GGX mirror", "ShaderNodeBsdfGlossy", Roughness=0.0)
next(n for n in ggx_mirror.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfGlossy").distribution = "BECKMANN"
for k, mat in enumerate((default, multi, sharp, sharp_mirror, ggx_mirror)):
    ms.plane(scene, f"P{k}", [(k, 0, 0), (k + 1, 0, 0), (k + 1, 1, 0), (k, 1, 0)], mat)
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
'''


@pytest.mark.slow
@pytest.mark.skipif(BLENDER is None and os.environ.get("CI") != "true", reason="no `blender` binary")
def test_blender34_glass_vocabulary(tmp_path):
    """Blender 3.4: the Glass BSDF defaults to Beckmann and IOR 1.45; SHARP is smooth (and a Sharp closure,
    as a Sharp Glossy's mirror; a Beckmann Glossy at roughness 0 is none); MULTI_GGX (a random walk in
    3.x) is named as approximated."""
    import sysconfig
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([repo, sysconfig.get_paths()["purelib"]]))
    (tmp_path / "make.py").write_text(MAKE_34)
    (tmp_path / "export.py").write_text(EXPORT_34)
    blend = tmp_path / "d.blend"
    r = subprocess.run([BLENDER, "-b", "--factory-startup", "--python", str(tmp_path / "make.py"), "--", repo,
                        os.path.join(repo, "sample_blends", "make_samples.py"), str(blend)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and blend.exists(), r.stdout[-2000:] + r.stderr[-2000:]
    r = subprocess.run([BLENDER, "-b", "--python-use-system-env", str(blend), "--python", str(tmp_path / "export.py"),
                        "--", str(tmp_path / "out.json")], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    data = json.loads((tmp_path / "out.json").read_text())
    mats = data["materials"]
    assert mats["Default glass"][0] == "glass" and mats["Default glass"][2] == "beckmann"
    assert mats["Default glass"][1] == pytest.approx(0.25) and mats["Default glass"][3] == pytest.approx(1.45)
    assert mats["Multi"][2] == "multi_ggx"
    assert mats["Sharp"][0] == "refraction" and mats["Sharp"][1] == 0.0
    # Filter Glossy (engine/integrators/delta_blur.py): 3.4 leaves the Sharp closures sharp, blurs the others
    assert mats["Sharp"][4] and not mats["Default glass"][4]
    assert mats["Sharp mirror"][0] == mats["GGX mirror"][0] == "mirror"
    assert mats["Sharp mirror"][4] and not mats["GGX mirror"][4] and mats["GGX mirror"][2] == "beckmann"
    assert any("Material 'Multi'" in w and "random walk" in w for w in data["warnings"]), data["warnings"]
