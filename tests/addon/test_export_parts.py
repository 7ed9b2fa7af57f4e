"""The exporter's parts on their own (test_export.py checks them through export_scene): mesh
geometry helpers, the world colour, the warnings for unmodelled features, the material table and
the image table."""
import bpy
import numpy as np
import pytest

from engine.scene import textures as scene_textures
from engine.scene import model
from engine.scene.model import DIFFUSE, GLASS, MIRROR
from mcrt_addon.export.images import ImageTable, image_node
from mcrt_addon.export.materials import DEFAULT_GREY, MaterialTable
from mcrt_addon.export.mesh import (bounding_sphere, is_closed, mesh_arrays, sphere_fit, transform_points,
                                    uniform_scale)
from mcrt_addon.export.unsupported import object_warnings, scene_warnings
from mcrt_addon.export.world import export_world


# ------------------------------------------------------------------------------------------ mesh
def icosphere_arrays(radius=1.0):
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=radius)
    ob = bpy.context.active_object
    return mesh_arrays(ob.data)


def test_mesh_arrays_are_triangles_of_the_mesh(empty_scene):
    bpy.ops.mesh.primitive_cube_add(size=2)
    verts, tris, mats = mesh_arrays(bpy.context.active_object.data)[:3]
    assert verts.shape == (8, 3) and tris.shape == (12, 3) and (mats == 0).all()
    assert np.allclose(np.abs(verts), 1) and is_closed(tris)
    assert not is_closed(tris[:-1]) and not is_closed(np.zeros((0, 3), np.int64))


def test_sphere_fit_finds_a_tessellated_sphere_only(empty_scene):
    verts, tris, mats = icosphere_arrays(radius=0.5)[:3]
    centre, radius = sphere_fit(verts + [1, 2, 3], tris, mats)
    np.testing.assert_allclose(centre, [1, 2, 3], atol=1e-6)
    assert radius == pytest.approx(0.5, rel=1e-4)
    assert sphere_fit(verts, tris, np.r_[mats[:-1], 1]) is None          # two materials
    assert sphere_fit(verts, tris[: len(tris) // 2], mats[: len(tris) // 2]) is None     # open
    squashed = verts * [1, 1, 0.9]
    assert sphere_fit(squashed, tris, mats) is None
    centre, r = bounding_sphere(squashed)
    assert np.linalg.norm(squashed - centre, axis=1).max() == pytest.approx(r)


def test_transforms_and_uniform_scale():
    m = np.eye(4)
    m[:3, :3] = 2.0 * np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])     # rotation by 90 deg, scale 2
    m[:3, 3] = [1, 0, 0]
    np.testing.assert_allclose(transform_points(np.array([[1.0, 0, 0]]), m), [[1, 2, 0]])
    assert uniform_scale(m) == pytest.approx(2.0)
    m[2, 2] = 3.0
    assert uniform_scale(m) is None


# ----------------------------------------------------------------------------------------- world
def test_world_is_background_colour_times_strength(empty_scene):
    warnings = []
    assert export_world(None, warnings) == ((0.0, 0.0, 0.0), None)
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    background.inputs["Strength"].default_value = 2.0
    assert export_world(world, warnings)[0] == pytest.approx((1.0, 0.5, 2.0)) and warnings == []
    sky = world.node_tree.nodes.new("ShaderNodeTexSky")
    world.node_tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    assert export_world(world, warnings) == (pytest.approx((1.0, 0.5, 2.0)), None)
    assert len(warnings) == 1 and "World 'Sky'" in warnings[0] and "Color linked" in warnings[0]


# ----------------------------------------------------------------------------------- unsupported
def test_unmodelled_scene_and_object_features_are_named(empty_scene):
    assert scene_warnings(empty_scene) == []
    empty_scene.render.use_motion_blur = True
    empty_scene.render.film_transparent = True            # rendered: no warning
    assert [w.split(" ")[0] for w in scene_warnings(empty_scene)] == ["Motion"]
    empty_scene.cycles.film_transparent_glass = True
    assert [w.split(" ")[0] for w in scene_warnings(empty_scene)] == ["Motion", "Film"]
    bpy.ops.mesh.primitive_cube_add()
    ob = bpy.context.active_object
    assert object_warnings(ob, "Cube") == []
    ob.visible_shadow = False
    ob.is_holdout = True
    warnings = object_warnings(ob, "Cube")
    assert len(warnings) == 2 and "Object 'Cube': holdout" in warnings[0] and "(shadow off)" in warnings[1]


# ------------------------------------------------------------------------------------- materials
def node_material(name, bsdf, **inputs):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    node = tree.nodes.new(bsdf)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat, node


def test_material_table_converts_each_blender_material_once(empty_scene):
    warnings = []
    table = MaterialTable(model, warnings)
    red, _ = node_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    mirror, _ = node_material("Mirror", "ShaderNodeBsdfGlossy", Roughness=0.0)
    glass, _ = node_material("Glass", "ShaderNodeBsdfGlass", IOR=1.45)
    other, _ = node_material("Toon", "ShaderNodeBsdfToon")
    indices = [table.index(m) for m in (red, mirror, red, None, glass, other, None)]
    assert indices == [0, 1, 0, 2, 3, 4, 2]
    kinds = [(m.name, m.kind) for m in table.materials]
    assert kinds == [("Red", DIFFUSE), ("Mirror", MIRROR), ("(default surface)", DIFFUSE), ("Glass", GLASS),
                     ("Toon", DIFFUSE)]
    assert table.materials[0].color == pytest.approx((0.8, 0.1, 0.1))
    assert table.materials[2].color == DEFAULT_GREY and table.materials[3].ior == pytest.approx(1.45)
    assert len(warnings) == 1 and "'Toon'" in warnings[0]


# ---------------------------------------------------------------------------------------- images
def test_image_table_exports_each_image_once_and_finds_its_node(empty_scene):
    image = bpy.data.images.new("Checker", 4, 2)
    image.pixels.foreach_set(np.linspace(0, 1, 4 * 2 * 4, dtype=np.float32))
    mat, bsdf = node_material("Textured", "ShaderNodeBsdfDiffuse")
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = image, "Closest", "EXTEND"
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    assert image_node(bsdf.inputs["Color"]) == tex and image_node(bsdf.inputs["Roughness"]) is None
    warnings = []
    table = ImageTable(scene_textures, warnings)
    a, b = table.slot(mat, tex), table.slot(mat, tex, scale=(2.0, 2.0, 2.0))
    assert a.texture == b.texture == 0 and len(table.textures) == 1
    assert (a.interpolation, a.extension, b.scale) == ("Closest", "EXTEND", (2.0, 2.0, 2.0))
    assert table.textures[0].name == "Checker" and table.textures[0].pixels.shape[:2] == (2, 4)
    tex.image = None
    assert table.slot(mat, tex) is None and "has no image" in warnings[-1]
