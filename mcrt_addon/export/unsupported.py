"""Blender features the tracer does not model, each named in a warning instead of being ignored
silently: holdout (object or collection), ray visibility, motion blur, Film > Transparent Glass
(Film > Transparent itself is rendered: engine/integrators/path_tracer.py misses).
(Transparent and Holdout shader nodes and Principled alpha are named by materials.py.)"""

RAY_VISIBILITY = (("visible_camera", "camera"), ("visible_diffuse", "diffuse"), ("visible_glossy", "glossy"),
                  ("visible_transmission", "transmission"), ("visible_volume_scatter", "volume scatter"),
                  ("visible_shadow", "shadow"))


def scene_warnings(scene, view_layer=None):
    warnings = []
    render = scene.render
    if getattr(render, "use_motion_blur", False):
        warnings.append("Motion blur is not rendered: every object is shown at the frame's instant")
    cycles = getattr(scene, "cycles", None)         # Cycles' own option, there when its add-on is
    if getattr(render, "film_transparent", False) and getattr(cycles, "film_transparent_glass", False):
        warnings.append("Film > Transparent Glass is not supported: glass is opaque in the alpha (the "
                        "background seen through it is rendered)")
    if view_layer is not None:
        stack = [view_layer.layer_collection]
        while stack:
            layer = stack.pop()
            if getattr(layer, "holdout", False):
                warnings.append(f"Collection '{layer.name}': holdout is not supported; its objects are "
                                "rendered as ordinary objects")
            stack.extend(layer.children)
    return warnings


def object_warnings(ob, label):
    """Warnings for one object (read from the original: the evaluated copy may lag)."""
    original = ob.original if getattr(ob, "original", None) is not None else ob
    warnings = []
    if getattr(original, "is_holdout", False):
        warnings.append(f"Object '{label}': holdout is not supported; rendered as an ordinary object")
    # Lights: Area lights export their ray visibility (export/lights.py); others are ignored.
    hidden = [] if ob.type == "LIGHT" else [name for attr, name in RAY_VISIBILITY if not getattr(original, attr, True)]
    if hidden:
        warnings.append(f"Object '{label}': ray visibility is not supported ({', '.join(hidden)} off); "
                        "the object is seen by every ray")
    return warnings


# -- shader nodes: every node feeding a material's output that the exporter did not read (Bump, Normal
# Map, Displacement, a Volume output, a texture into a Normal input, ...) is named (node_warnings).
def _source(sock):
    """(node, output socket) feeding ``sock`` through reroutes; None when unlinked or muted."""
    while sock is not None and sock.is_linked:
        link = sock.links[0]
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            return None
        if link.from_node.bl_idname == "NodeReroute":
            sock = link.from_node.inputs[0]
            continue
        return link.from_node
    return None


def _weighted_inputs(node):
    """The linked inputs of ``node`` that carry weight in Cycles: a Mix Shader with a constant factor
    of 0 or 1 is folded away with its other side (Cycles' constant folding; shader_mix.py reads
    that side alone)."""
    inputs = [sock for sock in node.inputs if sock.is_linked]
    if node.bl_idname == "ShaderNodeMixShader":
        fac = node.inputs.get("Factor") or node.inputs.get("Fac")
        shaders = [sock for sock in node.inputs if sock.bl_idname == "NodeSocketShader"][:2]
        if fac is not None and not fac.is_linked and len(shaders) == 2 and not 0.0 < fac.default_value < 1.0:
            unweighted = shaders[1] if fac.default_value <= 0.0 else shaders[0]
            inputs = [sock for sock in inputs if sock != unweighted]
    return inputs


def node_warnings(mat, evaluated, warnings):
    """Warnings for the nodes of material ``mat`` that feed its active Material Output but that the
    exporter did not read (``evaluated``: the names of the nodes the conversion found through
    util.linked_from: modelled, or warned by the code that found them) and that no warning names yet
    (``warnings``: those so far; a warning names a node as "node 'NAME'").  The walk starts at the output (Surface, Volume,
    Displacement, ...) and goes upstream through evaluated nodes only: a node that is not evaluated is
    named once, with the input it feeds, and what feeds it is ignored with it; so is what feeds a node
    whose output a warning says is ignored ("... is linked from node 'NAME' ...")."""
    from .util import uses_nodes
    tree = mat.node_tree if uses_nodes(mat) else None
    output = tree.get_output_node("CYCLES") if tree is not None else None
    if output is None:
        return []
    prefix = f"Material '{mat.name}'"
    named = [w for w in warnings if w.startswith(prefix)]
    found, seen, stack = [], {output.name}, [output]
    while stack:
        node = stack.pop()
        for sock in _weighted_inputs(node):
            source = _source(sock)
            if source is None or source.name in seen:
                continue
            seen.add(source.name)
            if source.name in evaluated:
                if not any(f"from node '{source.name}'" in w for w in named):   # read, and its output ignored
                    stack.append(source)
            elif not any(f"node '{source.name}'" in w for w in named):
                label = getattr(source, "bl_label", "") or source.bl_idname
                found.append(f"{prefix}, node '{source.name}': {label} ({source.bl_idname}) is not modelled; "
                             f"input '{sock.name}' of '{node.name}' is rendered as if unlinked")
    return found
