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
* node groups are entered: a group's nodes are inlined once per use (a node's `path`: the group nodes
  around it), as Cycles' group proxies (its blender/shader.cpp add_nodes, scene/shader_graph.cpp
  remove_proxy_nodes): a Group Input output is the group node's input socket (its link, else its
  value), a group node's output the active Group Output's input socket (its link, else its value).
  A value reaches the socket converted as a link; before Blender 5.0 (Cycles' proxies) a hidden-value
  Vector (a texture's coordinates, a Normal) keeps its implicit link instead, and a colour or vector
  through a Float group socket becomes a float there (luminance, average);
* a node type without a kernel (engine/nodes/registry.py), a group without a node tree or one that
  contains itself: one warning naming the material and the node (and the group it is in), and the
  input it feeds keeps its default value.
Constant sub-graphs fold here (evaluator.fold, n = 1): a graph of constants gives a constant."""
from typing import NamedTuple

from .util import linked_from

GROUPS = ("ShaderNodeGroup", "NodeGroupInput", "NodeGroupOutput")
# Outputs Cycles gives that the tracer does not model (they read 0; Pointiness 0.5).
UNMODELLED_OUTPUTS = {("ShaderNodeNewGeometry", "Pointiness"),
                      ("ShaderNodeNewGeometry", "Tangent"), ("ShaderNodeNewGeometry", "Random Per Island"),
                      ("ShaderNodeNewGeometry", "Parametric"), ("ShaderNodeObjectInfo", "Color"),
                      ("ShaderNodeObjectInfo", "Alpha"), ("ShaderNodeObjectInfo", "Object Index"),
                      ("ShaderNodeObjectInfo", "Material Index")}
SOCKET_KINDS = {"VALUE": "VALUE", "RGBA": "RGBA", "VECTOR": "VECTOR", "INT": "INT", "BOOLEAN": "BOOLEAN"}
_BASE_PROPS = None


class Feed(NamedTuple):
    """A node output feeding an input: `node` inside the group nodes `path` (outermost first);
    `narrow`: it crossed a Float group socket while a colour or vector (the input sees a float)."""
    node: object
    out: object
    path: tuple = ()
    narrow: bool = False


BLOCKED = "blocked"      # resolve(): a group that cannot be entered (warned): the input keeps its value


class Constant(NamedTuple):
    """A group socket's value feeding an input (`type`: the socket type it has, e.g. "RGBA")."""
    value: object
    type: str


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
    internal links), or None when unlinked.  A group node or a Group Input node is returned as any
    node (GraphCompiler.resolve goes through them)."""
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


def _matching(sockets, sock):
    """The socket of ``sockets`` with the identifier of ``sock`` (Blender and Cycles pair a group
    node's sockets with its Group Input / Group Output sockets so, in 3.x and 4.x alike), or None."""
    for s in sockets:
        if s.identifier == sock.identifier:
            return s
    return None


def _read_upstream(node):
    """Record every node upstream of ``node`` as read (util.linked_from): what feeds a group node's
    inputs that its used outputs do not read is irrelevant, not "unmodelled"
    (unsupported.node_warnings); what they do read is compiled and named by emit when unsupported."""
    seen, stack = set(), [node]
    while stack:
        for sock in stack.pop().inputs:
            source = linked_from(sock) if sock.is_linked else None
            if source is not None and source.as_pointer() not in seen:
                seen.add(source.as_pointer())
                stack.append(source)


def active_group_output(tree):
    """The Group Output node of a node group's tree that Cycles reads (the active one), or None."""
    outputs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    active = [n for n in outputs if getattr(n, "is_active_output", False)]
    return (active or outputs or [None])[0]


def _socket_value(sock):
    """A group socket's value as a program constant (a float or 3 floats), or None."""
    value = _plain(getattr(sock, "default_value", None))
    if isinstance(value, tuple):
        value = value[:3]
    if value is None or isinstance(value, str):
        return None
    return float(value) if isinstance(value, (bool, int)) else value


class GraphCompiler:
    def __init__(self, table, programs, evaluator, registry):
        """table: export/materials.py MaterialTable (its images and warnings); programs, evaluator,
        registry: the tracer's engine/scene/programs.py, engine/nodes/evaluator.py, registry.py."""
        self.table, self.P, self.evaluator = table, programs, evaluator
        self.kernels = registry.kernels()

    def warn(self, mat, node, text, path=()):
        if path:
            text = f"{text} (inside node group '{path[-1].node_tree.name}')"
        self.table.warn(mat, node, text)

    def compile(self, mat, node, sock, target, path=()):
        """(Program or None, constant or None) for the input ``sock`` of ``node`` inside the group
        nodes ``path`` (a BSDF in a group: its Group Input sockets are the group node's inputs; target:
        "RGBA" or "VALUE"): (None, value) when the graph folds to a constant, (None, None) when
        nothing feeds it that the tracer models (warned)."""
        self.warned = False                   # the node feeding sock was named in a warning
        self.nodes, self.index, self.uv_maps, self.implicit = [], {}, [], {}
        self.mat = mat
        found = source_of(sock)
        if found is None:
            return None, None
        if found[0].bl_idname not in GROUPS and not self.modelled(found[0]):
            return None, None                 # the caller names the socket's source as before
        feed = self.resolve(sock, path)
        if isinstance(feed, Constant):            # a group socket's value, converted as a link is
            return None, self._constant_as(feed, target)
        if feed is None or feed is BLOCKED:
            return None, None
        root = self.emit(feed.node, feed.out, path=feed.path)
        if root is None:
            self.warned = True
            return None, None
        output = (root, feed.out.identifier, SOCKET_KINDS.get(feed.out.type, "RGBA"))
        if feed.narrow:
            output = self._narrowed(output, sock)
        program = self.P.Program(self.nodes, output, target, sorted(set(self.uv_maps)))
        version = getattr(self.table, "version", (5, 0))
        folded, value = self.evaluator.fold(program, version)
        if folded is None:
            return None, value
        return folded, None

    def modelled(self, node):
        return node.bl_idname not in GROUPS and node.bl_idname in self.kernels

    # -- node groups -------------------------------------------------------------------------------
    def resolve(self, sock, path=()):
        """What feeds the input ``sock`` of a node inside the group nodes ``path``: a Feed (a node
        output, through any groups), a Constant (a group socket's value), None (unlinked) or BLOCKED (a
        group that cannot be entered: warned)."""
        found = source_of(sock)
        if found is None:
            return None
        node, out = found
        if node.bl_idname == "NodeGroupInput":
            if not path:
                return None                       # a Group Input outside any group: nothing feeds it
            outer = _matching(path[-1].inputs, out)
            if outer is None:
                return None
            return self._across(self.resolve(outer, path[:-1]) if outer.is_linked else None, outer)
        if node.bl_idname == "ShaderNodeGroup":
            tree = node.node_tree
            if tree is None:
                self.warned = True
                self.warn(self.mat, node, "is a node group without a node tree; the input it feeds uses its "
                                          "unlinked value", path)
                return BLOCKED
            if any(g.node_tree == tree for g in path):
                self.warned = True
                self.warn(self.mat, node, f"node group '{tree.name}' contains itself; the input it feeds uses "
                                          "its unlinked value", path)
                return BLOCKED
            if not path:
                _read_upstream(node)
            output = active_group_output(tree)
            inner = _matching(output.inputs, out) if output is not None else None
            if inner is None:
                return None
            inside = path + (node,)
            return self._across(self.resolve(inner, inside) if inner.is_linked else None, inner)
        return Feed(node, out, path)

    def _across(self, feed, boundary):
        """``feed`` (what feeds the group socket ``boundary``) as seen past that socket.  Before 5.0
        Cycles' group proxies convert there (a colour or vector through a Float socket becomes a
        float); Blender 5.0 inlines the groups first and converts only at the node that reads it
        (both measured: tests/nodes/test_node_groups_cycles.py)."""
        if feed is BLOCKED:
            return feed
        if feed is None:                          # unlinked: the socket's own value
            value = _socket_value(boundary)
            return None if value is None else Constant(value, boundary.type)
        if not self.group_proxies():
            return feed
        if isinstance(feed, Constant):
            return Constant(self._constant_as(feed, boundary.type), boundary.type)
        if boundary.type == "VALUE" and feed.out.type in ("RGBA", "VECTOR"):
            return feed._replace(narrow=True)
        return feed

    def shader_feed(self, mat, sock, path=()):
        """The node feeding the shader socket ``sock`` of a node inside the group nodes ``path``
        (the Material Output's Surface, a Mix or Add Shader input), through reroutes, muted nodes
        and groups as resolve(): (node, path) of that shader node, or None (unlinked: no closure;
        a group that cannot be entered: warned)."""
        self.mat, self.warned = mat, False
        feed = self.resolve(sock, path)
        return (feed.node, feed.path) if isinstance(feed, Feed) else None

    def group_proxies(self):
        """Whether Cycles sees the groups through its proxies (before Blender 5.0), not inlined."""
        return tuple(getattr(self.table, "version", (5, 0)))[:2] < (5, 0)

    def _constant_as(self, const, target):
        """A group constant as a value of socket type ``target`` (as the evaluator converts links)."""
        value = const.value
        three = isinstance(value, tuple)
        if target in ("RGBA", "VECTOR"):
            return value if three else (float(value),) * 3
        if not three:
            return float(value)
        if const.type == "RGBA":
            import numpy as np
            weights = self.evaluator.luminance(getattr(self.table, "version", (5, 0)))
            return float(np.dot(weights, np.asarray(value[:3], dtype=np.float64)))
        return float(sum(value[:3]) / 3.0)

    def _narrowed(self, output, sock):
        """A node turning ``output`` (node, identifier, type) into a float, as a colour or vector
        through a Float group socket (Cycles' conversion there: luminance or average); the new output."""
        i, identifier, kind = output
        self.nodes.append(self.P.ProgramNode("ShaderNodeMath", f"(float group socket before '{sock.name}')",
                                             {"operation": "ADD", "use_clamp": False, "_outputs": ["Value"]},
                                             {"Value": self.P.Link(i, identifier, kind, "VALUE"), "Value_001": 0.0}))
        return len(self.nodes) - 1, "Value", "VALUE"

    # -- nodes -------------------------------------------------------------------------------------
    def emit(self, node, out, consumer=None, sock=None, path=()):
        """The index of ``node`` (inside the group nodes ``path``) in the program (emitted with what
        feeds it), None when unsupported (named in a warning with the input ``sock`` of ``consumer``
        it feeds)."""
        key = (tuple(g.as_pointer() for g in path), node.as_pointer())
        outputs = {out.identifier}
        if key in self.index:
            i = self.index[key]
            if i is not None:
                self.nodes[i].props["_outputs"] = sorted(set(self.nodes[i].props["_outputs"]) | outputs)
                self._check_output(node, out, path)
            return i
        kind = node.bl_idname
        if not self.modelled(node):
            what = f"{node.bl_label or kind} ({kind}) is not supported"
            where = f"input '{sock.name}' of '{consumer.name}'" if consumer is not None else "the input it feeds"
            # "linked from node": unsupported.node_warnings leaves what feeds this node unnamed with it
            self.warn(self.mat, node, f"{what}; {where} is linked from node '{node.name}' and uses its unlinked value",
                      path)
            self.index[key] = None
            return None
        self._check_output(node, out, path)
        inputs = {}
        for sock in node.inputs:
            if not getattr(sock, "enabled", True) or sock.bl_idname == "NodeSocketShader":
                continue
            feed = self.resolve(sock, path) if sock.is_linked else None
            if isinstance(feed, Feed):
                j = self.emit(feed.node, feed.out, node, sock, feed.path)
                if j is not None:
                    source = (j, feed.out.identifier, SOCKET_KINDS.get(feed.out.type, "RGBA"))
                    if feed.narrow:
                        source = self._narrowed(source, sock)
                    inputs[sock.identifier] = self.P.Link(source[0], source[1], source[2],
                                                          SOCKET_KINDS.get(sock.type, "RGBA"))
                    continue
            hidden_vector = getattr(sock, "hide_value", False) and sock.type == "VECTOR"
            if isinstance(feed, Constant) and not (hidden_vector and self.group_proxies()):
                inputs[sock.identifier] = self._constant_as(feed, SOCKET_KINDS.get(sock.type, "VALUE"))
                continue                          # a group socket's value (before 5.0 a hidden Vector keeps its implicit link)
            if sock.identifier == "Vector" and kind.startswith("ShaderNodeTex"):
                inputs[sock.identifier] = self.implicit_vector(kind)
                continue
            if not hasattr(sock, "default_value") or hidden_vector:
                continue                          # e.g. a Normal: the kernel's default, the shading normal
            # (a colour or float without a value field, e.g. Gamma's Color, still gives Cycles its default_value)
            value = _plain(sock.default_value)
            if isinstance(value, tuple):
                value = value[:3]
            if value is not None and not isinstance(value, str):
                inputs[sock.identifier] = value
        props = self.props(node)
        props["_outputs"] = sorted(outputs)
        name = node.name if not path else "/".join([g.name for g in path] + [node.name])
        self.nodes.append(self.P.ProgramNode(kind, name, props, inputs))
        self.index[key] = len(self.nodes) - 1
        return self.index[key]

    def _check_output(self, node, out, path=()):
        if (node.bl_idname, out.identifier) in UNMODELLED_OUTPUTS:
            self.warn(self.mat, node, f"output '{out.name}' is not modelled (reads "
                                      f"{'0.5' if out.identifier == 'Pointiness' else '0'})", path)
        if node.bl_idname in ("ShaderNodeTexCoord", "ShaderNodeUVMap") and out.identifier == "UV":
            self.uv_maps.append(getattr(node, "uv_map", "") or "")
        if node.bl_idname == "ShaderNodeAttribute" and getattr(node, "attribute_type", "GEOMETRY") != "GEOMETRY":
            self.warn(self.mat, node, f"{node.attribute_type.lower()} attributes are not exported; the Attribute "
                                      "node reads 0", path)

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
