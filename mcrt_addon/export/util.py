"""Small helpers shared by the exporters."""


class ExportError(Exception):
    """A problem with the user's scene; the message names the object.  Shown via report({'ERROR'})."""


def socket(node, *names):
    """The first input socket of ``node`` called one of ``names`` (new name first, then old), or None.

    Principled BSDF sockets were renamed in 4.0 ('Transmission' -> 'Transmission Weight', ...);
    never index sockets by position (4.0 added hidden 'Weight' inputs).
    """
    for name in names:
        sock = node.inputs.get(name)
        if sock is not None:
            return sock
    return None


def linked_from(sock):
    """The node feeding ``sock``, skipping reroutes; None when unlinked."""
    while sock is not None and sock.is_linked:
        link = sock.links[0]
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            sock = node.inputs[0]
            continue
        return node
    return None


def uses_nodes(id_block):
    """Whether Cycles reads the node tree.  Blender 5.0 always uses nodes (``use_nodes`` is
    deprecated there and removed from World); 3.x/4.x honour the flag."""
    import bpy
    if bpy.app.version >= (5, 0, 0):
        return id_block.node_tree is not None
    return bool(getattr(id_block, "use_nodes", True)) and id_block.node_tree is not None
