"""Persistent Data for final renders: the worker pool of one F12 / animation frame kept for the next.

With Render Properties > Performance > Final Render > Persistent Data on (Blender's own
``scene.render.use_persistent_data``, the checkbox Cycles uses), `render_pool` hands a render the pool
(engine/pools/kept.py KeptPool) the last render left: the same worker processes, and when only the
camera moved, the same prepared scene and BVH.  The pool is shut down when a render runs with
Persistent Data off or with other workers (Python, thread count), when a file is loaded, and when
the add-on is unregistered; the workers also exit by themselves when Blender does (they watch their
parent).

`mesh_cache` keeps the exporter's mesh arrays (mcrt_addon/export/__init__.py export_scene's
mesh_cache) from one frame to the next while Blender keeps the render's depsgraph (it does with
Persistent Data on, in 3.4 and 5.0): arrays of the objects and meshes whose geometry the depsgraph
reports as updated are read again, the others (an object that only moved) are not.
"""
import bpy

from . import bridge, warm
from .viewport import classify, forget_meshes

_kept = []          # at most one KeptPool
_meshes = {}        # "depsgraph": pointer of the depsgraph the arrays were read from; "arrays": the cache


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
        # the viewport workers started ahead when they are the same (mcrt_addon/warm.py)
        inner = warm.take(python, threads, extra_paths)
        if inner is not None:
            inner.log = log
        else:
            inner = bridge.module("api").make_pool(f"viewport:{python}", threads, log=log, extra_paths=extra_paths)
        # checked: render_engine validates every exported scene before rendering it
        _kept.append(bridge.module("pools.kept").KeptPool(inner, key, checked=True))
        kept_pool = _kept[0]
        warm.hold(key, lambda: bool(kept_pool.usable) and bool(_kept) and _kept[0] is kept_pool)
    return _kept[0]


def mesh_cache(scene, depsgraph):
    """The mesh arrays kept for a final render of `scene` from `depsgraph`: None when Persistent
    Data is off; else the dict of the last render of the same depsgraph less the objects and meshes
    whose geometry its updates report as changed, or an empty one for another depsgraph."""
    if not getattr(scene.render, "use_persistent_data", False):
        _meshes.clear()
        return None
    pointer = depsgraph.as_pointer()
    if _meshes.get("depsgraph") != pointer:
        _meshes.update(depsgraph=pointer, arrays={})
    else:
        forget_meshes(_meshes["arrays"], classify(depsgraph.updates)[1])
    return _meshes["arrays"]


def kept():
    """The kept pool, or None (tests, diagnostics)."""
    return _kept[0] if _kept else None


@bpy.app.handlers.persistent
def free(*_args):
    """Shut the kept pool down (also a bpy.app.handlers.load_pre handler)."""
    _meshes.clear()
    warm.hold(None, None)
    while _kept:
        _kept.pop().shutdown()


def register():
    if free not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(free)


def unregister():
    if free in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(free)
    free()
