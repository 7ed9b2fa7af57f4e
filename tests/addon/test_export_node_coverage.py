"""Every shader node of the running Blender is either modelled by the exporter or named in a warning
(mcrt_addon/export/unsupported.py node_warnings; the README promises a warning for every unmodelled
node).  Each node type (bpy.types.ShaderNode subclasses of bpy 5.0) is built into a material of
its own, wired where it takes effect in Cycles: shader outputs into the Material Output's Surface
(volume shaders into Volume), Displacement nodes into Displacement, Bump and Normal Map into a
Diffuse BSDF's Normal (both modelled: the BSDF's "normal" program), every other node into the Diffuse
BSDF's Color."""
import bpy
import pytest

from tests.addon.exporting import export

# Not nodes of a material's surface: outputs of other trees or of AOV passes, and node types that
# cannot be built without more (a custom group's Python class).
NOT_IN_A_MATERIAL = {"ShaderNodeOutputMaterial", "ShaderNodeOutputWorld", "ShaderNodeOutputLight",
                     "ShaderNodeOutputAOV", "ShaderNodeOutputLineStyle", "ShaderNodeCustomGroup"}
VOLUME = {"ShaderNodeVolumeAbsorption", "ShaderNodeVolumeScatter", "ShaderNodeVolumePrincipled",
          "ShaderNodeVolumeCoefficients"}
DISPLACEMENT = {"ShaderNodeDisplacement", "ShaderNodeVectorDisplacement"}
NORMAL = {"ShaderNodeBump", "ShaderNodeNormalMap"}


def shader_node_types():
    return sorted(name for name in dir(bpy.types)
                  if isinstance(getattr(bpy.types, name), type) and name != "ShaderNode"
                  and issubclass(getattr(bpy.types, name), bpy.types.ShaderNode) and name not in NOT_IN_A_MATERIAL)


def wired_material(ms, idname):
    """A material with one node of type `idname` wired where it takes effect; (material, node name,
    "Surface" for a shader on the Surface, else "other")."""
    mat, nodes, links, out = ms.empty_material(f"M {idname}")
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    node = nodes.new(idname)
    outputs = [s for s in node.outputs if s.enabled]
    shader = [s for s in outputs if s.bl_idname == "NodeSocketShader"]
    if idname in VOLUME:
        links.new(shader[0], out.inputs["Volume"])
    elif shader:
        links.new(shader[0], out.inputs["Surface"])
    elif idname in DISPLACEMENT:
        links.new(outputs[0], out.inputs["Displacement"])
    elif idname in NORMAL:
        links.new(outputs[0], diffuse.inputs["Normal"])
    elif outputs:
        links.new(outputs[0], diffuse.inputs["Color"])
    else:
        return mat, None, None                  # no output to wire (a Script node without a script)
    return mat, node.name, "Surface" if shader and idname not in VOLUME else "other"


@pytest.fixture
def wired(scene, ms):
    """Every node type on a plate of its own: {idname: (material name, node name, where)}."""
    built = {}
    for i, idname in enumerate(shader_node_types()):
        mat, node, where = wired_material(ms, idname)
        if node is None:
            continue
        x = (i % 12) * 0.1
        y = (i // 12) * 0.1
        ms.mesh_object(scene, f"P{i}", lambda bm, x=x, y=y: ms.quad(bm, [(x, y, 0), (x + 0.05, y, 0),
                                                                       (x + 0.05, y + 0.05, 0), (x, y + 0.05, 0)]),
                       mat)
        built[idname] = (mat.name, node, where)
    return built


def export_reading(monkeypatch):
    """The export's result, and per material the names of the nodes its conversion read
    (mcrt_addon/export/util.py following_links, as handed to node_warnings)."""
    from mcrt_addon.export import materials
    read, real = {}, getattr(materials, "node_warnings", None)          # None: an exporter without the walk

    def recording(mat, evaluated, warnings):
        read[mat.name] = set(evaluated)
        return real(mat, evaluated, warnings)
    if real is not None:
        monkeypatch.setattr(materials, "node_warnings", recording)
    return export((8, 8)), read


def named(warnings, material, node):
    return any(w.startswith(f"Material '{material}',") and f"node '{node}'" in w for w in warnings)


def unaccounted(wired, warnings, read):
    """Node types neither named in a warning of their material nor modelled: a shader on the Surface
    that the exporter read (materials.py dispatches it, or names it "not supported").  Every other
    node here feeds a socket the exporter does not model (a Diffuse BSDF's Color and Normal, the
    output's Volume and Displacement), so it must be named."""
    from engine.nodes.registry import supported           # node programs (mcrt_addon/export/node_graph.py)
    return [idname for idname, (material, node, where) in wired.items()
            if not named(warnings, material, node) and not (where == "Surface" and node in read.get(material, ()))
            and not (where == "other" and supported(idname) and node in read.get(material, ()))]


def test_every_shader_node_is_modelled_or_named(wired, monkeypatch):
    res, read = export_reading(monkeypatch)
    assert len(wired) > 80                       # bpy 5.0: 93 node types wired
    assert unaccounted(wired, res.warnings, read) == []
    for idname in ("ShaderNodeDisplacement", "ShaderNodeVolumePrincipled"):
        material, node, _ = wired[idname]
        text = [w for w in res.warnings if w.startswith(f"Material '{material}', node '{node}'")]
        assert text and "is not modelled" in text[0], res.warnings
    for idname in ("ShaderNodeBump", "ShaderNodeNormalMap"):      # a BSDF's "normal" program (node_graph.py)
        material, node, _ = wired[idname]
        assert node in read[material] and not named(res.warnings, material, node), res.warnings


def test_modelled_nodes_get_no_warning_of_the_walk(wired, monkeypatch):
    """The walk names only what the exporter did not read: no shader on the Surface is 'not modelled'."""
    res, read = export_reading(monkeypatch)
    for idname, (material, node, where) in wired.items():
        if where == "Surface":
            assert node in read[material]
            assert not [w for w in res.warnings if w.startswith(f"Material '{material}',") and "is not modelled" in w]


def test_the_walk_names_only_what_the_exporter_did_not_read(scene, ms):
    """A Principled BSDF textured through a UV Map node is read whole; a Mix Shader of factor 0 is
    folded away with its second side, as Cycles does; a Bump behind a Mix Shader's Diffuse is read (its
    "normal" program) and a Sky Texture into that Diffuse's Color is named."""
    mat = ms.node_material("Textured", "ShaderNodeBsdfPrincipled")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    image = nodes.new("ShaderNodeTexImage")
    image.image = bpy.data.images.new("Checker", 4, 4, alpha=False, float_buffer=False)
    image.image.generated_type = "COLOR_GRID"
    uv = nodes.new("ShaderNodeUVMap")
    links.new(uv.outputs["UV"], image.inputs["Vector"])
    links.new(image.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    folded = ms.node_material("Folded", "ShaderNodeMixShader", Factor=0.0)
    nodes, links = folded.node_tree.nodes, folded.node_tree.links
    diffuse, toon = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeBsdfToon")
    links.new(diffuse.outputs[0], nodes["Mix Shader"].inputs[1])
    links.new(toon.outputs[0], nodes["Mix Shader"].inputs[2])
    bump = nodes.new("ShaderNodeBump")
    links.new(bump.outputs[0], diffuse.inputs["Normal"])
    links.new(nodes.new("ShaderNodeTexSky").outputs[0], diffuse.inputs["Color"])
    for i, m in enumerate((mat, folded)):
        ms.mesh_object(scene, f"P{i}", lambda bm, i=i: ms.quad(bm, [(i, 0, 0), (i + 1, 0, 0), (i + 1, 1, 0), (i, 1, 0)]), m)
    res = export((8, 8))
    assert not [w for w in res.warnings if w.startswith("Material 'Textured',")], res.warnings
    folded_warnings = [w for w in res.warnings if w.startswith("Material 'Folded',")]
    assert len(folded_warnings) == 1 and "'Sky Texture'" in folded_warnings[0], res.warnings


def test_what_feeds_an_ignored_node_is_not_named_again(scene, ms):
    """A Sky Texture (not modelled in materials) into Base Color is named by the compiler's warning
    ("linked from node 'Sky Texture'"), the Mapping behind it is ignored with it; a Normal Map into
    Normal is modelled (no warning)."""
    mat = ms.node_material("Chain", "ShaderNodeBsdfPrincipled")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    sky, mapping = nodes.new("ShaderNodeTexSky"), nodes.new("ShaderNodeMapping")
    links.new(mapping.outputs[0], sky.inputs[0])
    links.new(sky.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    normal_map = nodes.new("ShaderNodeNormalMap")
    links.new(normal_map.outputs[0], nodes["Principled BSDF"].inputs["Normal"])
    ms.mesh_object(scene, "P", lambda bm: ms.quad(bm, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), mat)
    warnings = [w for w in export((8, 8)).warnings if w.startswith("Material 'Chain',")]
    assert any("is linked from node 'Sky Texture'" in w for w in warnings), warnings
    assert not [w for w in warnings if "Normal Map" in w or "Mapping" in w], warnings
    assert len(warnings) == 1, warnings


def test_control_without_the_walk_bump_and_normal_map_go_unnamed(wired, monkeypatch):
    """CONTROL: without node_warnings the Bump, Normal Map, Displacement and Volume nodes are silent."""
    from mcrt_addon.export import materials
    monkeypatch.setattr(materials, "node_warnings", lambda *a: [])
    missing = unaccounted(wired, export((8, 8)).warnings, {})
    assert {"ShaderNodeBump", "ShaderNodeNormalMap", "ShaderNodeDisplacement",
            "ShaderNodeVolumePrincipled"} <= set(missing), missing
