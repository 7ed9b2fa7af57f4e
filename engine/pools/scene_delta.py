"""A scene sent again to worker processes that hold the last one: the mesh arrays that did not
change stay out of the message.

A moved object of an animation (Persistent Data, engine/pools/kept.py) changes its vertices only;
its triangles, material ids, UVs and normals are the same arrays frame after frame.  The pool
(engine/pools/viewport.py) sends the scene with those fields set to None and their list; each
worker puts its own copies of the last scene's arrays back before it prepares the scene, so it
prepares exactly the scene it would have been sent (a 93k-triangle mesh: 4.1 MB -> 1.1 MB to
pickle, write and read per worker and frame).  Only for scenes the caller validated (`checked`):
a worker that validates a scene itself may change its arrays.
"""
from __future__ import annotations

import copy

import numpy as np

ARRAYS = ("vertices", "triangles", "material_ids", "uvs", "normals", "smooth", "tangents", "tangent_signs")


def _same(a, b) -> bool:
    """Equal arrays: the same object, or dtype, shape and every element (NaN is unequal)."""
    return (isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype
            and a.shape == b.shape and (a is b or bool(np.array_equal(a, b))))


def without_unchanged(scene, last, base: int):
    """(scene to send, kept): `scene` with the mesh arrays equal to those of the same mesh of
    `last` (by position and name) set to None, in copies (`scene` is not changed); kept is
    (base, [(mesh index, field), ...]) for with_unchanged, `base` naming `last`."""
    fields = []
    meshes = list(scene.meshes)
    for i, mesh in enumerate(meshes):
        before = last.meshes[i] if i < len(last.meshes) else None
        if before is None or before.name != mesh.name:
            continue
        same = [f for f in ARRAYS if _same(getattr(mesh, f), getattr(before, f))]
        if same:
            meshes[i] = copy.copy(mesh)
            for f in same:
                setattr(meshes[i], f, None)
            fields += [(i, f) for f in same]
    if not fields:
        return scene, (base, [])
    sent = copy.copy(scene)
    sent.meshes = meshes
    return sent, (base, fields)


def with_unchanged(scene, kept, last, last_number):
    """The scene without_unchanged left out of the message, from `last` (the scene of
    preparation `last_number` this worker holds); `scene` itself when nothing was left out."""
    base, fields = kept
    if not fields:
        return scene
    if last is None or base != last_number:
        raise RuntimeError(f"the scene refers to preparation {base}, this worker holds {last_number}")
    for i, f in fields:
        setattr(scene.meshes[i], f, getattr(last.meshes[i], f))
    return scene
