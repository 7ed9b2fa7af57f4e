"""The exporter reads a BSDF's Normal input as its "normal" program (mcrt_addon/export/materials.py
_normal_program) and gives a mesh with a tangent-space Normal Map its UV map's tangents and bitangent
signs (export/mesh.py corner_bitangent_signs); a Normal input inside a Mix Shader is named."""
import numpy as np

from tests.addon.exporting import export


def _uv_quad(ms, scene, name, mat):
    ob = ms.mesh_object(scene, name, lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), mat)
    if not ob.data.uv_layers:
        ob.data.uv_layers.new(name="UVMap")
    return ob


def test_normal_map_into_principled_exports_a_normal_program_with_tangents(scene, ms):
    mat = ms.node_material("Mapped", "ShaderNodeBsdfPrincipled")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    normal_map = nodes.new("ShaderNodeNormalMap")
    normal_map.inputs["Color"].default_value = (0.7, 0.5, 1.0, 1.0)
    links.new(nodes.new("ShaderNodeTexCoord").outputs["UV"], normal_map.inputs["Color"])
    links.new(normal_map.outputs[0], nodes["Principled BSDF"].inputs["Normal"])
    _uv_quad(ms, scene, "Q", mat)
    res = export((8, 8))
    assert not [w for w in res.warnings if "Mapped" in w], res.warnings
    m = next(m for m in res.scene.materials if m.name == "Mapped")
    assert sorted(m.programs) == ["normal"] and m.programs["normal"].type == "VECTOR"
    assert [n.kind for n in m.programs["normal"].nodes][-1] == "ShaderNodeNormalMap"
    mesh = res.scene.meshes[0]
    assert mesh.tangents is not None and mesh.tangent_signs is not None
    assert mesh.tangent_signs.shape == (len(mesh.triangles), 3) and set(np.unique(mesh.tangent_signs)) <= {-1.0, 1.0}


def test_a_normal_input_inside_a_mix_shader_is_named(scene, ms):
    mat = ms.node_material("Mixed", "ShaderNodeMixShader", Factor=0.5)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    diffuse, glossy = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeBsdfGlossy")
    links.new(diffuse.outputs[0], nodes["Mix Shader"].inputs[1])
    links.new(glossy.outputs[0], nodes["Mix Shader"].inputs[2])
    bump = nodes.new("ShaderNodeBump")
    links.new(nodes.new("ShaderNodeTexCoord").outputs["Generated"], bump.inputs["Height"])
    links.new(bump.outputs[0], diffuse.inputs["Normal"])
    _uv_quad(ms, scene, "Q", mat)
    warnings = [w for w in export((8, 8)).warnings if w.startswith("Material 'Mixed'")]
    assert len(warnings) == 1 and "Normal input of a shader inside this mix" in warnings[0], warnings
