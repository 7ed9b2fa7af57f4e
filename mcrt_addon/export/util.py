"""Small helpers shared by the exporters."""
import contextlib

_FOLLOWED = []       # sets of node names that linked_from returned, innermost last (following_links)


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
        if _FOLLOWED:
            _FOLLOWED[-1].add(node.name)
        return node
    return None


@contextlib.contextmanager
def following_links():
    """Yield the set of the names of the nodes that linked_from returns inside the block: the nodes an
    exporter read (modelled, or warned by the code that found them).  What feeds a material's output
    and is not among them is named by mcrt_addon/export/unsupported.py node_warnings."""
    found = set()
    _FOLLOWED.append(found)
    try:
        yield found
    finally:
        _FOLLOWED.pop()


def uses_nodes(id_block):
    """Whether Cycles reads the node tree.  Blender 5.0 always uses nodes (``use_nodes`` is
    deprecated there and removed from World); 3.x/4.x honour the flag."""
    import bpy
    if bpy.app.version >= (5, 0, 0):
        return id_block.node_tree is not None
    return bool(getattr(id_block, "use_nodes", True)) and id_block.node_tree is not None
