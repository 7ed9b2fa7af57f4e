"""engine/geometry/accel/embree.py's Embree queries compiled with numba: one loop over the rays of a
batch that calls Embree's rtcIntersect1 / rtcOccluded1 itself (through the C API, as
engine/geometry/accel/embree_buffers.py does for the buffers), on the (3, N) float64 rows the
wavefront keeps, instead of embreex's EmbreeScene.run on (N, 3) float32 copies of them.  Imported
only through engine/core/backend.py's choice (it imports numba).

embreex's `run` (embreex/rtcore_scene.pyx, release 4.4.0.post1) fills one RTCRayHit per ray (origin,
tnear 0, direction, time 0, tfar, mask 0xFFFFFFFF, flags 0, geomID, primID and instID[0] invalid),
calls rtcIntersect1(scene, &rayhit, NULL) or rtcOccluded1(scene, &rayhit.ray, NULL) and copies the
answer into new float32 and int32 arrays, which EmbreeAccelerator then casts to float64 and int64.
This loop fills the same struct with the same float32 values (each float64 coordinate rounded to
float32 as `astype` rounds it; tfar min(tmax, FLOAT32_FAR) rounded) and makes the same calls, then
writes the float64 and int64 answers directly: t (+inf on a miss), prim (-1), u and v (0 on a miss;
embreex leaves a miss's u, v as the last hit's, which no caller reads), or occluded (tfar < 0).
Embree answers the same call the same way, so the hits are the same bit for bit
(tests/geometry/test_embree_jit.py, on rays recorded from renders).

numba calls the two functions by name (`types.ExternalFunction`), resolved through llvmlite's symbol
table where `bind()` puts their addresses in the Embree library embreex loaded; with those names the
compiled code can be cached like every other twin's.  The RTCRayHit struct (embree4/rtcore_ray.h: 12
words of the ray, then Ng x y z, u, v, primID, geomID, instID at words 12-19, 16-byte aligned) is a
float32 buffer of 32 words (room for Embree 4's instPrimID) with a uint32 view of it.
"""
from __future__ import annotations

import numpy as np

from . import embree_buffers
from ...core.backend import numba_module

nb = numba_module()
jit = nb.njit(cache=True, error_model="numpy", nogil=True)

FLOAT32_FAR = 3.0e38            # embree.py FLOAT32_FAR: tfar is min(tmax, this), then float32
INVALID = 0xFFFFFFFF            # RTC_INVALID_GEOMETRY_ID
MASK_ALL = 0xFFFFFFFF           # the ray mask embreex sets: every geometry
# Words of RTCRayHit (embree4/rtcore_ray.h).
ORG, TNEAR, DIR, TIME, TFAR, MASK, FLAGS = 0, 3, 4, 7, 8, 9, 11
U, V, PRIM_ID, GEOM_ID, INST_ID = 15, 16, 17, 18, 19
WORDS = 32
SYMBOLS = {"tncg15_rtcIntersect1": "rtcIntersect1", "tncg15_rtcOccluded1": "rtcOccluded1"}

_rtc_intersect1 = nb.types.ExternalFunction("tncg15_rtcIntersect1", nb.types.void(nb.types.intp, nb.types.intp,
                                                                                  nb.types.intp))
_rtc_occluded1 = nb.types.ExternalFunction("tncg15_rtcOccluded1", nb.types.void(nb.types.intp, nb.types.intp,
                                                                                nb.types.intp))
_state: dict = {}


def bind() -> bool:
    """Put the addresses of Embree's rtcIntersect1 and rtcOccluded1 under the kernels' names into
    llvmlite's symbol table (once per process); False when embree_buffers cannot reach the library
    (then the kernels cannot be linked and embree.py's embreex path runs)."""
    if "bound" not in _state:
        _state["bound"] = False
        if embree_buffers.available():
            import llvmlite.binding as llvm
            for ours, theirs in SYMBOLS.items():
                llvm.add_symbol(ours, embree_buffers.function_address(theirs))
            _state["bound"] = True
    return _state["bound"]


@jit
def _fill_ray(ray, word, o, d, tmax, i):
    """RTCRayHit's ray part for ray i as embreex fills it; the hit's ids invalid."""
    ray[ORG], ray[ORG + 1], ray[ORG + 2] = np.float32(o[0, i]), np.float32(o[1, i]), np.float32(o[2, i])
    ray[TNEAR] = np.float32(0.0)
    ray[DIR], ray[DIR + 1], ray[DIR + 2] = np.float32(d[0, i]), np.float32(d[1, i]), np.float32(d[2, i])
    ray[TIME] = np.float32(0.0)
    far = tmax[i]
    if far > FLOAT32_FAR:                       # np.minimum(tmax, FLOAT32_FAR); NaN stays NaN
        far = FLOAT32_FAR
    ray[TFAR] = np.float32(far)
    word[MASK] = np.uint32(MASK_ALL)
    word[FLAGS] = np.uint32(0)
    word[PRIM_ID], word[GEOM_ID], word[INST_ID] = np.uint32(INVALID), np.uint32(INVALID), np.uint32(INVALID)


@jit
def _intersect(scene, o, d, tmax, ray, t, prim, u, v):
    word = ray.view(np.uint32)
    address = ray.ctypes.data
    for i in range(o.shape[1]):
        _fill_ray(ray, word, o, d, tmax, i)
        _rtc_intersect1(scene, address, 0)
        if word[PRIM_ID] == np.uint32(INVALID):
            t[i], prim[i], u[i], v[i] = np.inf, -1, 0.0, 0.0
        else:
            t[i], prim[i] = np.float64(ray[TFAR]), np.int64(word[PRIM_ID])
            u[i], v[i] = np.float64(ray[U]), np.float64(ray[V])


@jit
def _nearest(scene, o, d, t, ray, kind, prim, u, v):
    """_intersect's hits folded into SceneGeometry.intersect's nearest so far, in place: where the
    triangle's t is below t, t, kind 1 (TRIANGLE) and prim take it (NumPy: closer = tt < t and its
    np.where's); u and v are the hit's wherever Embree hit (as intersect's arrays)."""
    word = ray.view(np.uint32)
    address = ray.ctypes.data
    for i in range(o.shape[1]):
        _fill_ray(ray, word, o, d, t, i)
        _rtc_intersect1(scene, address, 0)
        if word[PRIM_ID] == np.uint32(INVALID):
            kind[i], prim[i], u[i], v[i] = 0, -1, 0.0, 0.0
        else:
            tt = np.float64(ray[TFAR])
            u[i], v[i] = np.float64(ray[U]), np.float64(ray[V])
            if tt < t[i]:
                t[i], kind[i], prim[i] = tt, 1, np.int64(word[PRIM_ID])
            else:
                kind[i], prim[i] = 0, -1


@jit
def _occluded(scene, o, d, tmax, ray, blocked):
    word = ray.view(np.uint32)
    address = ray.ctypes.data
    for i in range(o.shape[1]):
        _fill_ray(ray, word, o, d, tmax, i)
        _rtc_occluded1(scene, address, 0)
        blocked[i] = ray[TFAR] < np.float32(0.0)         # Embree 4 marks an occluded ray with tfar -inf


def _ray_buffer() -> np.ndarray:
    """A float32 RTCRayHit of WORDS words at a 64-byte boundary (Embree asks for 16)."""
    raw = np.zeros(WORDS + 16, np.float32)
    start = (-raw.ctypes.data % 64) // 4
    return raw[start:start + WORDS]


def _c(a):
    return np.ascontiguousarray(a, dtype=np.float64)


def intersect(handle: int, o, d, tmax):
    """(t, prim, u, v) of EmbreeAccelerator.intersect for the rays (rows o, d) up to tmax (N,), with
    handle the RTCScene (embree_buffers.scene_handle); bind() must have been True."""
    n = o.shape[1]
    t, prim, u, v = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _intersect(handle, _c(o), _c(d), _c(tmax), _ray_buffer(), t, prim, u, v)
    return t, prim, u, v


def nearest(handle: int, o, d, t):
    """(t, kind, prim, u, v) of SceneGeometry.intersect after its triangles: t (a float64 array of
    the rays' bounds, written in place) lowered to the triangle hits nearer than it, kind int8 1 there
    else 0, prim the triangle there else -1."""
    n = o.shape[1]
    kind, prim, u, v = np.empty(n, np.int8), np.empty(n, np.int64), np.empty(n), np.empty(n)
    _nearest(handle, _c(o), _c(d), t, _ray_buffer(), kind, prim, u, v)
    return t, kind, prim, u, v


def occluded(handle: int, o, d, tmax):
    """EmbreeAccelerator.occluded for the rays (rows o, d) up to tmax (N,)."""
    blocked = np.empty(o.shape[1], np.bool_)
    _occluded(handle, _c(o), _c(d), _c(tmax), _ray_buffer(), blocked)
    return blocked


def warm_up() -> None:
    """Compile (or load) the kernels for the types a render passes, on a one-triangle scene; nothing
    when Embree's library cannot be reached (the kernels are never called then)."""
    if not bind():
        return
    from .embree import EmbreeAccelerator
    accelerator = EmbreeAccelerator(np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]]))
    handle = embree_buffers.scene_handle(accelerator.scene)
    rows = np.zeros((3, 2))
    d = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, -1.0]])
    intersect(handle, rows, d, np.full(2, np.inf))
    nearest(handle, rows, d, np.full(2, np.inf))
    occluded(handle, rows, d, np.full(2, 2.0))
