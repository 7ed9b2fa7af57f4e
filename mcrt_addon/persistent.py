"""Persistent Data for final renders: the worker pool of one F12 / animation frame kept for the next.

With Render Properties > Performance > Final Render > Persistent Data on (Blender's own
``scene.render.use_persistent_data``, the checkbox Cycles uses), `render_pool` hands a render the pool
(engine/pools/kept.py KeptPool) the last render left: the same worker processes, and when only the
camera moved, the same prepared scene and BVH.  The pool is shut down when a render runs with
Persistent Data off or with other workers (Python, thread count), when a file is loaded, and when
the add-on is unregistered; the workers also exit by themselves when Blender does (they watch their
parent).
"""
import bpy

from . import bridge

_kept = []          # at most one KeptPool


def _key(python, threads, extra_paths):
    return (python, int(threads), tuple(extra_paths))


def render_pool(scene, python, threads, extra_paths, log=print):
    """The pool for a final render of `scene`: the kept one (started if there is none) when
    Persistent Data is on, else None (the caller starts a pool for this render alone and any kept
    pool is shut down)."""
    if not getattr(scene.render, "use_persistent_data", False):
        free()
        return None
    key = _key(python, threads, extra_paths)
    if _kept and (_kept[0].key != key or not _kept[0].usable):
        free()
    if not _kept:
        inner = bridge.module("api").make_pool(f"viewport:{python}", threads, log=log, extra_paths=extra_paths)
        _kept.append(bridge.module("pools.kept").KeptPool(inner, key))
    return _kept[0]


def kept():
    """The kept pool, or None (tests, diagnostics)."""
    return _kept[0] if _kept else None


@bpy.app.handlers.persistent
def free(*_args):
    """Shut the kept pool down (also a bpy.app.handlers.load_pre handler)."""
    while _kept:
        _kept.pop().shutdown()


def register():
    if free not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(free)


def unregister():
    if free in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(free)
    free()
