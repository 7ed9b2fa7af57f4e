"""Shader node graphs -> node programs (engine/scene/programs.py) for the BSDF sockets the tracer
reads per hit (engine/nodes/evaluator.py runs them).

`GraphCompiler.compile(mat, node, sock, type)` walks the nodes feeding ``sock`` (through reroutes and
muted nodes' internal links), depth first, and emits them in topological order:
* each node's own properties, captured generically from its RNA (enum identifiers, booleans,
  numbers, tuples; its image as an index into the scene's textures, a Texture Coordinate's From object
  as its inverse matrix); the node_props module's `special_props(node)` first (beside this module,
  when it is there: Color Ramp, curves);
* each input: a link to an earlier node, or the socket's default value; an unlinked Vector of a texture
  node gets Cycles' implicit coordinates (UV for Image Texture, Generated for the others), an unlinked
  Normal the shading normal (the kernel's own default);
* a node type without a kernel (engine/nodes/registry.py) or a node group: one warning naming the
  material and the node, and the input it feeds keeps its default value.
Constant sub-graphs fold here (evaluator.fold, n = 1): a graph of constants gives a constant."""
from .util import linked_from

GROUPS = ("ShaderNodeGroup", "NodeGroupInput", "NodeGroupOutput")
# Outputs Cycles gives that the tracer does not model (they read 0; Pointiness 0.5).
UNMODELLED_OUTPUTS = {("ShaderNodeTexCoord", "Window"), ("ShaderNodeNewGeometry", "Pointiness"),
                      ("ShaderNodeNewGeometry", "Tangent"), ("ShaderNodeNewGeometry", "Random Per Island"),
                      ("ShaderNodeNewGeometry", "Parametric"), ("ShaderNodeObjectInfo", "Color"),
                      ("ShaderNodeObjectInfo", "Alpha"), ("ShaderNodeObjectInfo", "Object Index"),
                      ("ShaderNodeObjectInfo", "Material Index")}
SOCKET_KINDS = {"VALUE": "VALUE", "RGBA": "RGBA", "VECTOR": "VECTOR", "INT": "INT", "BOOLEAN": "BOOLEAN"}
_BASE_PROPS = None


def _base_props():
    """The RNA properties every shader node has (name, location, ...): not a node's own."""
    global _BASE_PROPS
    if _BASE_PROPS is None:
        import bpy
        _BASE_PROPS = {p.identifier for p in bpy.types.ShaderNode.bl_rna.properties} | {"rna_type"}
    return _BASE_PROPS


def _special_props(node):
    """special_props(node) of the node_props module beside this one when it is there, else None."""
    import importlib
    try:
        node_props = importlib.import_module(__package__ + ".node_props")
    except ModuleNotFoundError:
        return None
    return node_props.special_props(node)


def _plain(value):
    if isinstance(value, (bool, int, float, str)):
        return value
    try:
        return tuple(_plain(v) for v in value)
    except TypeError:
        return None


def source_of(sock):
    """(node, output socket) feeding the input ``sock`` through reroutes and muted nodes (their
    internal links), or None when unlinked."""
    while sock is not None and sock.is_linked:
        node = linked_from(sock)              # records the node as read (unsupported.node_warnings)
        if node is None:
            return None
        link = sock.links[0]
        while link.from_node.bl_idname == "NodeReroute":
            link = link.from_node.inputs[0].links[0]
        out = link.from_socket
        if not node.mute:
            return node, out
        through = [lk for lk in node.internal_links if lk.to_socket == out]
        sock = through[0].from_socket if through else None
    return None


class GraphCompiler:
    def __init__(self, table, programs, evaluator, registry):
        """table: export/materials.py MaterialTable (its images and warnings); programs, evaluator,
        registry: the tracer's engine/scene/programs.py, engine/nodes/evaluator.py, registry.py."""
        self.table, self.P, self.evaluator = table, programs, evaluator
        self.kernels = registry.kernels()

    def warn(self, mat, node, text):
        self.table.warn(mat, node, text)

    def compile(self, mat, node, sock, target):
        """(Program or None, constant or None) for the input ``sock`` of ``node`` (target: "RGBA" or
        "VALUE"): (None, value) when the graph folds to a constant, (None, None) when nothing feeds it
        that the tracer models (warned)."""
        self.warned = False                   # the node feeding sock was named in a warning
        found = source_of(sock)
        if found is None:
            return None, None
        self.nodes, self.index, self.uv_maps, self.implicit = [], {}, [], {}
        self.mat = mat
        if not self.modelled(found[0]):
            return None, None                 # the caller names the socket's source as before
        root = self.emit(*found)
        if root is None:
            self.warned = True
            return None, None
        out_sock = found[1]
        program = self.P.Program(self.nodes, (root, out_sock.identifier, SOCKET_KINDS.get(out_sock.type, "RGBA")),
                                 target, sorted(set(self.uv_maps)))
        version = getattr(self.table, "version", (5, 0))
        folded, value = self.evaluator.fold(program, version)
        if folded is None:
            return None, value
        return folded, None

    def modelled(self, node):
        return node.bl_idname not in GROUPS and node.bl_idname in self.kernels

    def emit(self, node, out, consumer=None, sock=None):
        """The index of ``node`` in the program (emitted with what feeds it), None when unsupported
        (named in a warning with the input ``sock`` of ``consumer`` it feeds)."""
        key = node.as_pointer()
        outputs = {out.identifier}
        if key in self.index:
            i = self.index[key]
            if i is not None:
                self.nodes[i].props["_outputs"] = sorted(set(self.nodes[i].props["_outputs"]) | outputs)
                self._check_output(node, out)
            return i
        kind = node.bl_idname
        if not self.modelled(node):
            what = "node groups are not supported" if kind in GROUPS else f"{node.bl_label or kind} ({kind}) is not supported"
            where = f"input '{sock.name}' of '{consumer.name}'" if consumer is not None else "the input it feeds"
            # "linked from node": unsupported.node_warnings leaves what feeds this node unnamed with it
            self.warn(self.mat, node, f"{what}; {where} is linked from node '{node.name}' and uses its unlinked value")
            self.index[key] = None
            return None
        self._check_output(node, out)
        inputs = {}
        for sock in node.inputs:
            if not getattr(sock, "enabled", True) or sock.bl_idname == "NodeSocketShader":
                continue
            found = source_of(sock) if sock.is_linked else None
            if found is not None:
                j = self.emit(*found, node, sock)
                if j is not None:
                    inputs[sock.identifier] = self.P.Link(j, found[1].identifier,
                                                          SOCKET_KINDS.get(found[1].type, "RGBA"),
                                                          SOCKET_KINDS.get(sock.type, "RGBA"))
                    continue
            if sock.identifier == "Vector" and kind.startswith("ShaderNodeTex"):
                inputs[sock.identifier] = self.implicit_vector(kind)
                continue
            if not hasattr(sock, "default_value") or (getattr(sock, "hide_value", False) and sock.type == "VECTOR"):
                continue                          # e.g. a Normal: the kernel's default, the shading normal
            # (a colour or float without a value field, e.g. Gamma's Color, still gives Cycles its default_value)
            value = _plain(sock.default_value)
            if isinstance(value, tuple):
                value = value[:3]
            if value is not None and not isinstance(value, str):
                inputs[sock.identifier] = value
        props = self.props(node)
        props["_outputs"] = sorted(outputs)
        self.nodes.append(self.P.ProgramNode(kind, node.name, props, inputs))
        self.index[key] = len(self.nodes) - 1
        return self.index[key]

    def _check_output(self, node, out):
        if (node.bl_idname, out.identifier) in UNMODELLED_OUTPUTS:
            self.warn(self.mat, node, f"output '{out.name}' is not modelled (reads "
                                      f"{'0.5' if out.identifier == 'Pointiness' else '0'})")
        if node.bl_idname in ("ShaderNodeTexCoord", "ShaderNodeUVMap") and out.identifier == "UV":
            self.uv_maps.append(getattr(node, "uv_map", "") or "")
        if node.bl_idname == "ShaderNodeAttribute" and getattr(node, "attribute_type", "GEOMETRY") != "GEOMETRY":
            self.warn(self.mat, node, f"{node.attribute_type.lower()} attributes are not exported; the Attribute "
                                      "node reads 0")

    def implicit_vector(self, kind):
        """A link to Cycles' default coordinates of a texture node: UV (Image Texture) or Generated."""
        output = "UV" if kind == "ShaderNodeTexImage" else "Generated"
        if output not in self.implicit:
            self.nodes.append(self.P.ProgramNode("ShaderNodeTexCoord", "(implicit coordinates)",
                                                 {"_outputs": [output]}, {}))
            self.implicit[output] = len(self.nodes) - 1
            if output == "UV":
                self.uv_maps.append("")
        return self.P.Link(self.implicit[output], output, "VECTOR", "VECTOR")

    def props(self, node):
        special = _special_props(node)
        props = dict(special) if special else {}
        for prop in node.bl_rna.properties:
            name = prop.identifier
            if name in _base_props() or name in props:
                continue
            if prop.type == "POINTER":
                self.pointer_prop(node, name, props)
                continue
            if prop.type == "COLLECTION":
                continue
            try:
                value = getattr(node, name)
            except AttributeError:
                continue
            if prop.type == "ENUM" and getattr(prop, "is_enum_flag", False):
                value = sorted(value)
            value = _plain(value)
            if value is not None:
                props[name] = value
        if node.bl_idname == "ShaderNodeValue":
            props["value"] = float(node.outputs[0].default_value)
        elif node.bl_idname == "ShaderNodeRGB":
            props["color"] = tuple(float(c) for c in node.outputs[0].default_value)[:3]
        return props

    def pointer_prop(self, node, name, props):
        import numpy as np
        value = getattr(node, name, None)
        if name == "image" and node.bl_idname == "ShaderNodeTexImage":
            images = self.table.images
            index = None
            if value is not None and images is not None:
                index = images.texture_index(self.mat, node, value)
            elif value is None:
                self.warn(self.mat, node, "has no image; it reads Cycles' missing-image magenta")
            props["texture"] = -1 if index is None else int(index)
            if getattr(node, "projection", "FLAT") not in ("FLAT", "BOX", "SPHERE", "TUBE"):
                self.warn(self.mat, node, f"projection {node.projection} is not modelled (flat)")
        elif name == "object" and node.bl_idname == "ShaderNodeTexCoord" and value is not None:
            props["object_matrix_inverse"] = tuple(tuple(float(c) for c in row)
                                                   for row in np.linalg.inv(np.array(value.matrix_world)))


def attribute_names(materials):
    """The colour attribute names the Attribute nodes of these tracer materials' programs read (their
    mix leaves' and factors' too), sorted, as a tuple (a cache key of export/__init__.py)."""
    programs = []
    for m in materials:
        programs += list((getattr(m, "programs", None) or {}).values())
        if getattr(m, "mix", None) is not None:
            for leaf in m.mix.leaves:
                programs += list((leaf.material.programs or {}).values())
                programs += [f.program for f in leaf.factors if f.kind == "program"]
    return tuple(sorted({n.props.get("attribute_name", "") for p in programs for n in p.nodes
                         if n.kind == "ShaderNodeAttribute" and n.props.get("attribute_type", "GEOMETRY") == "GEOMETRY"}))


def scaled(graph, colour, strength, colour_value, strength_value):
    """The emission program radiance = colour x strength, of a colour program (or the constant
    ``colour_value``) and a strength program (or ``strength_value``): both programs' nodes, then the
    tracer's own TNCG15Scale node (engine/nodes/inputs.py)."""
    P = graph.P
    nodes, inputs = [], {}
    for key, program, value, kind in (("Color", colour, tuple(colour_value), "RGBA"),
                                      ("Strength", strength, float(strength_value), "VALUE")):
        if program is None:
            inputs[key] = value
            continue
        base = len(nodes)
        for node in program.nodes:
            nodes.append(P.ProgramNode(node.kind, node.name, node.props, {
                k: (P.Link(v.node + base, v.output, v.source, v.target) if isinstance(v, P.Link) else v)
                for k, v in node.inputs.items()}))
        i, output, source = program.output
        inputs[key] = P.Link(i + base, output, source, kind)
    nodes.append(P.ProgramNode("TNCG15Scale", "(colour x strength)", {}, inputs))
    uv_maps = sorted(set((colour.uv_maps if colour else []) + (strength.uv_maps if strength else [])))
    return P.Program(nodes, (len(nodes) - 1, "Color", "RGBA"), "RGBA", uv_maps)
