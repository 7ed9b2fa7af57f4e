"""World export: a constant background colour (Background node Color x Strength, or world.color)."""
from .util import linked_from, socket, uses_nodes


def export_world(world, warnings):
    if world is None:
        return (0.0, 0.0, 0.0)
    tree = world.node_tree if uses_nodes(world) else None
    if tree is None:
        # 3.x without nodes uses world.color; 5.0 has no use_nodes and always a node tree
        return tuple(max(float(c), 0.0) for c in world.color[:3])
    output = tree.get_output_node("CYCLES")
    node = linked_from(output.inputs.get("Surface")) if output is not None else None
    if node is None:
        return (0.0, 0.0, 0.0)
    if node.bl_idname != "ShaderNodeBackground":
        warnings.append(f"World '{world.name}': node '{node.name}' ({node.bl_idname}) is not supported; "
                        "background is black")
        return (0.0, 0.0, 0.0)
    color_sock = socket(node, "Color")
    strength_sock = socket(node, "Strength")
    for sock in (color_sock, strength_sock):
        if sock is not None and sock.is_linked:
            warnings.append(f"World '{world.name}': input '{sock.name}' of node '{node.name}' is linked "
                            "(only a constant colour is supported); its unlinked value is used")
    color = tuple(float(c) for c in color_sock.default_value[:3])
    strength = float(strength_sock.default_value)
    return tuple(max(c * strength, 0.0) for c in color)
