"""Exporter: Image Texture nodes and UV maps (mcrt_addon/export/images.py, mesh.corner_uvs)."""
import bpy
import numpy as np
import pytest

from engine.integrators.effects import plan_effects
from engine.core.settings import RenderSettings
from engine.materials.textures import TextureSet
from mcrt_addon.export import export_scene
from rendering import export_blend


def export(resolution=(32, 32)):
    bpy.context.view_layer.update()
    return export_scene(bpy.context.evaluated_depsgraph_get(), resolution=resolution)


def by_name(items, name):
    return next(i for i in items if i.name == name)


def test_textured_sample_exports_images_slots_and_uvs(samples):
    result = export_blend(samples["textured"], (32, 32))
    scene = result.scene
    assert not [w for w in result.warnings if "image" in w or "UV" in w], result.warnings
    assert all(t.pixels.dtype == np.uint8 for t in scene.textures)                  # 8-bit: sent as bytes
    images = {t.name: (t.pixels.shape, t.colorspace) for t in scene.textures}        # packed: sent as pixels
    assert images == {"Checker": ((16, 16, 4), "sRGB"), "Tiles": ((2, 4, 4), "Non-Color"),
                      "Lamp colours": ((2, 2, 4), "sRGB")}
    index = {t.name: i for i, t in enumerate(scene.textures)}
    checker = scene.textures[index["Checker"]].pixels
    # row 0 is the bottom (v = 0, the near half): its dark squares are red, the top ones blue
    assert checker[0, 0, 0] > checker[0, 0, 2] and checker[15, 4, 2] > checker[15, 4, 0]
    floor = by_name(scene.materials, "Checker floor").color_texture
    assert (floor.texture, floor.interpolation, floor.extension) == (index["Checker"], "Linear", "REPEAT")
    wall = by_name(scene.materials, "Tiled wall").color_texture
    assert (wall.texture, wall.interpolation, wall.extension, wall.uv_map) == (index["Tiles"], "Closest", "EXTEND",
                                                                               "Second")
    lamp = by_name(scene.materials, "Textured lamp")
    assert lamp.emission_texture.scale == (12.0, 12.0, 12.0) and lamp.color_texture is None
    uvs = {m.name: m.uvs for m in scene.meshes}
    assert uvs["Floor"].shape == (2, 3, 2) and uvs["Floor"][..., 0].max() == pytest.approx(2.0)
    assert uvs["Back"][..., 0].min() == pytest.approx(-0.25)                      # the "Second" map
    assert uvs["Left"] is None and uvs["Box"] is None                             # no texture: no UVs
    plan = plan_effects(scene, RenderSettings())
    assert plan.textures and "Checker floor" in plan.reason["textures"]


def test_untextured_scene_exports_no_uvs(samples):
    scene = export_blend(samples["cornell"], (32, 32)).scene
    assert scene.textures == [] and all(m.uvs is None for m in scene.meshes)
    assert not plan_effects(scene, RenderSettings()).textures


def textured_plane(ms, scene, image):
    mat = ms.image_material("Wood floor", "ShaderNodeBsdfDiffuse", "Color", image, Color=(0.2, 0.5, 0.1, 1.0))
    ob = ms.plane(scene, "Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], mat)
    ms.set_uvs(ob, {"UVMap": [(0, 0), (1, 0), (1, 1), (0, 1)]})
    return mat


def test_missing_image_file_warns_and_keeps_the_unlinked_colour(empty_scene, make_samples_module, tmp_path):
    ms = make_samples_module
    ms.camera(empty_scene)
    image = bpy.data.images.new("wood", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "gone" / "wood.png")
    textured_plane(ms, empty_scene, image)
    result = export()
    warning = [w for w in result.warnings if "wood.png" in w]
    assert warning and "Material 'Wood floor'" in warning[0] and "image 'wood'" in warning[0], result.warnings
    material = by_name(result.scene.materials, "Wood floor")
    assert material.color_texture is None and material.color == pytest.approx((0.2, 0.5, 0.1))
    assert result.scene.textures == [] and all(m.uvs is None for m in result.scene.meshes)


def test_image_file_is_sent_as_a_path_and_read_as_blender_reads_it(empty_scene, make_samples_module, tmp_path):
    """A file image goes to the worker as its path; OpenImageIO's rows, flipped, are Blender's pixels."""
    import OpenImageIO as oiio
    ms = make_samples_module
    ms.camera(empty_scene)
    rng = np.random.default_rng(5)
    pixels = rng.integers(0, 256, size=(3, 5, 3), dtype=np.uint8)
    path = str(tmp_path / "random.png")
    assert oiio.ImageBuf(pixels).write(path)
    image = bpy.data.images.load(path)
    textured_plane(ms, empty_scene, image)
    scene = export().scene
    assert scene.textures[0].path == path and scene.textures[0].pixels is None
    loaded = TextureSet(scene).loaded[0].pixels
    blender = np.empty(5 * 3 * image.channels, np.float32)
    image.pixels.foreach_get(blender)
    blender = blender.reshape(3, 5, image.channels)[:, :, :3]
    np.testing.assert_allclose(loaded[:, :, :3], blender, atol=1e-6)
    assert not np.allclose(loaded[::-1, :, :3], blender, atol=1e-6)   # negative control: unflipped rows


def test_an_image_used_by_two_materials_is_exported_once(empty_scene, make_samples_module):
    ms = make_samples_module
    ms.camera(empty_scene)
    image = ms.packed_image("Shared", 2, 2, lambda x, y: (0.2 * x, 0.5, 0.7 * y))
    for k, (kind, socket) in enumerate((("ShaderNodeBsdfDiffuse", "Color"), ("ShaderNodeEmission", "Color"))):
        mat = ms.image_material(f"User {k}", kind, socket, image, **({"Strength": 3.0} if k else {}))
        ob = ms.plane(empty_scene, f"Card {k}", [(k, 0, 0), (k + 1, 0, 0), (k + 1, 0, 1), (k, 0, 1)], mat)
        ms.set_uvs(ob, {"UVMap": [(0, 0), (1, 0), (1, 1), (0, 1)]})
    scene = export().scene
    assert [t.name for t in scene.textures] == ["Shared"]
    users = {m.name: m for m in scene.materials}
    assert users["User 0"].color_texture.texture == 0 and users["User 1"].emission_texture.texture == 0
    assert users["User 1"].emission_texture.scale == (3.0, 3.0, 3.0)


def test_principled_emission_colour_texture_and_uv_warnings(empty_scene, make_samples_module):
    ms = make_samples_module
    ms.camera(empty_scene)
    image = ms.packed_image("Glow", 2, 1, lambda x, y: (x, 0.5, 0.25))
    socket = "Emission Color" if bpy.app.version >= (4, 0, 0) else "Emission"
    mat = ms.image_material("Glowing", "ShaderNodeBsdfPrincipled", socket, image, uv_map="Missing",
                            **{"Emission Strength": 5.0})
    ob = ms.plane(empty_scene, "Sign", [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)], mat)
    ms.set_uvs(ob, {"UVMap": [(0, 0), (1, 0), (1, 1), (0, 1)]})
    result = export()
    glowing = by_name(result.scene.materials, "Glowing")
    assert glowing.emission_texture is not None and glowing.emission_texture.scale == (5.0, 5.0, 5.0)
    assert any("Object 'Sign': no UV map 'Missing'" in w for w in result.warnings), result.warnings
    assert np.array_equal(result.scene.meshes[0].uvs, np.zeros((2, 3, 2)))
    # a Mapping node between the UVs and the image: a node program (mcrt_addon/export/node_graph.py),
    # radiance = the image at the mapped coordinates x strength, no warning
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = next(n for n in nodes if n.bl_idname == "ShaderNodeTexImage")
    mapping = nodes.new("ShaderNodeMapping")
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    result = export()
    assert not any("Material 'Glowing'" in w and "Mapping" in w for w in result.warnings), result.warnings
    glowing = by_name(result.scene.materials, "Glowing")
    assert glowing.emission_texture is None
    assert [n.kind for n in glowing.programs["emission"].nodes] == ["ShaderNodeTexImage", "TNCG15Scale"]
