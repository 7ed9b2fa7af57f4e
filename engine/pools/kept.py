"""Persistent Data: worker processes and their prepared scene kept from one render to the next.

Blender's Render Properties > Performance > Final Render > Persistent Data (``use_persistent_data``,
as Cycles) keeps the render's data between frames of an animation and between F12 presses.
`KeptPool` does that for the tracer: it is a pool of engine/pools/protocol.py around a pool whose
prepare() may be called again (engine/pools/viewport.py ViewportPool, made by
``make_pool("viewport:PYTHON", n)``), and

* ``close()`` ends one render, not the workers: the frame side (engine/rendering/frame.py) closes its
  pool after every frame; ``shutdown()`` stops the workers (the add-on calls it when Persistent Data
  is turned off, a file is loaded or the add-on is disabled);
* ``prepare()`` of a scene whose content equals the last one's apart from the camera and resolution
  (`same_content`: the exporter makes new objects every frame) sends only the new view: the workers
  keep their geometry and BVH (a camera fly-through); any other change prepares the scene again in
  the same processes (no start-up, no imports).

The image does not depend on the pool (engine/pools/protocol.py), so a kept pool renders every frame
bit-identically to a fresh one.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from .protocol import Pool

DRAIN_SECONDS = 5.0     # a render that ended with units in flight: wait this long for their answers


def same_content(a, b) -> bool:
    """Whether `a` and `b` hold equal values: dataclasses field by field, arrays element by element
    (same shape and dtype; NaN equals NaN), sequences and dicts item by item."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and a.dtype == b.dtype and _same_array(a, b)
    if dataclasses.is_dataclass(a):
        return all(same_content(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same_content(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same_content(a[k], b[k]) for k in a)
    if isinstance(a, float) and a != a:
        return b != b
    return bool(a == b)


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    """Element by element, NaN equal to NaN (np.array_equal(a, b, equal_nan=True) for floats), but
    a moved mesh's vertices are told apart at their first difference: array_equal's NaN masks copied
    all of them (1.2 ms for 47k vertices, on every frame of an animation)."""
    equal = a == b
    if equal.all():
        return True
    if a.dtype.kind not in "fc":
        return False
    first = np.unravel_index(int(np.argmin(equal)), equal.shape)     # the first element that differs
    if not (np.isnan(a[first]) and np.isnan(b[first])):
        return False
    return bool((equal | (np.isnan(a) & np.isnan(b))).all())


def same_but_the_view(scene, other) -> bool:
    """`scene` equals `other` in everything but the camera and resolution."""
    if other is None or type(scene) is not type(other):
        return False
    # the meshes first: an animation's frames differ there, and all() stops at the first difference
    # (the materials' many fields compared first took 4 ms of a frame of a moving mesh)
    names = sorted((f.name for f in dataclasses.fields(scene) if f.name not in ("camera", "resolution")),
                   key=lambda name: name != "meshes")
    return all(same_content(getattr(scene, name), getattr(other, name)) for name in names)


class KeptPool(Pool):
    """A re-preparable pool kept across renders: close() ends a render, shutdown() the workers."""

    takes_rounds = True

    def __init__(self, inner, key=None, checked: bool = False, keep: bool = True):
        """checked: the caller validates every scene before it renders it (the add-on's final render,
        mcrt_addon/render_engine.py), so the workers do not validate it again.  keep=False: one
        render only, close() also shuts the workers down (a render given workers started ahead,
        mcrt_addon/warm.py, without Persistent Data)."""
        self.inner, self.key, self.checked, self.keep = inner, key, checked, keep
        self.scene = None               # the scene last prepared (its objects are what the workers hold)
        self.renders = 0                # renders prepared on this pool
        self.view_only = 0              # of them, how many sent only a new camera
        self.prepare_seconds = 0.0      # the last render's prepare(): until the first worker was ready
        self.is_shut = False
        self.describe = (f"{len(inner.workers)} worker process(es) ({inner.python}) "
                         + ("kept across renders (Persistent Data)" if keep else "started ahead"))

    @property
    def usable(self) -> bool:
        """Whether the next render may use the pool: not shut down and some worker alive."""
        return not self.is_shut and any(w.alive for w in self.inner.workers)

    def prepare(self, scene, settings):
        if same_but_the_view(scene, self.scene) and settings == self.inner.settings:
            # the workers' own objects with the new view: ViewportPool.prepare sends the camera only
            scene = dataclasses.replace(self.scene, camera=scene.camera, resolution=scene.resolution)
            self.view_only += 1
        start = time.perf_counter()
        facts = self.inner.prepare(scene, settings, checked=self.checked)
        self.prepare_seconds = time.perf_counter() - start      # sent, and the first worker ready
        self.scene = scene
        self.renders += 1
        return facts

    def start(self, units) -> None:
        self.inner.start(units)

    def next_result(self, timeout: float):
        return self.inner.next_result(timeout)

    @property
    def shares_photons(self) -> bool:
        return getattr(self.inner, "shares_photons", False)

    def share_photons(self, batch, stored) -> None:
        self.inner.share_photons(batch, stored)

    def forget_photons(self, batches) -> None:
        self.inner.forget_photons(batches)

    def cancel(self) -> None:
        self.inner.cancel()

    def close(self) -> None:
        """The render is over: a pool for one render (keep False) is shut down; a kept one drains the
        units the render left in flight (an exception in the frame side) and is shut down when it
        cannot drain them within DRAIN_SECONDS."""
        if not self.keep:                       # a pool for one render: nothing to keep, no drain,
            self.shutdown(wait=False)           # and no wait for the workers' ends (ViewportPool.close)
            return
        deadline = time.perf_counter() + DRAIN_SECONDS
        if self.inner.outstanding():
            self.inner.cancel()
        while self.inner.outstanding() and time.perf_counter() < deadline:
            self.inner.next_result(0.1)
        if self.inner.outstanding() or not self.keep:
            self.shutdown()

    def shutdown(self, wait: bool = True) -> None:
        if not self.is_shut:
            self.is_shut = True
            self.inner.close(wait=wait)

    def stats(self) -> dict:
        stats = dict(self.inner.stats())
        stats.update(persistent_data=self.keep, renders_on_pool=self.renders, renders_view_only=self.view_only,
                     prepare_seconds=self.prepare_seconds)
        return stats

    def warnings(self) -> list:
        return self.inner.warnings()
