"""Triangles into an embreex scene's Embree buffers in one array copy, through Embree's C API.

embreex's TriangleMesh (embreex/mesh_construction.pyx) fills Embree's vertex buffer one Python
float at a time (`vertices[i*3 + j].x = tri_vertices[i, j, 0]` on an untyped array): 0.10 CPU s for
93k triangles, paid by every worker whenever a moved mesh is prepared again (docs/performance.md
"Animation and Persistent Data").  `attach_triangles` does what TriangleMesh does, with the same
Embree calls, buffers and values (float32 x, y, z of each corner, 16-byte stride; indices 3i, 3i+1,
3i+2), but copies the arrays with NumPy.

embreex keeps its RTCScene in a C field of EmbreeScene (`cdef RTCScene scene_i`, then `cdef public
int is_committed`: embreex/rtcore_scene.pxd) that Python cannot read.  `scene_handle` reads it
at the object's address after checking the layout through the public field (it writes a marker
into is_committed from Python and finds it where the layout puts it); when anything does not
check out (another embreex, no libembree4 beside it, not CPython) `available()` is False and the
caller uses TriangleMesh.
"""
from __future__ import annotations

import ctypes
import glob
import os
import platform

import numpy as np

RTC_GEOMETRY_TYPE_TRIANGLE = 0      # embree4/rtcore_geometry.h
RTC_BUFFER_TYPE_INDEX = 0           # embree4/rtcore_buffer.h
RTC_BUFFER_TYPE_VERTEX = 1
RTC_FORMAT_UINT3 = 0x5003           # embree4/rtcore_common.h
RTC_FORMAT_FLOAT3 = 0x9003
VERTEX_STRIDE = 16                  # bytes: embreex's Vertex (x, y, z, r), as TriangleMesh asks
MARKER = 0x5A17C0DE                 # written into is_committed to find it
# The embreex releases whose EmbreeScene layout (rtcore_scene.pxd: scene_i, then is_committed) and
# TriangleMesh buffers this module was checked against; any other falls back to TriangleMesh.
CHECKED_EMBREEX = ("4.4.0.post1",)

_state: dict = {}


def _library():
    """Embree's library as embreex loaded it (the wheel's embreex.libs), or None."""
    import embreex
    libs = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(embreex.__file__))), "embreex.libs")
    found = sorted(glob.glob(os.path.join(libs, "libembree4*.so*")))
    if not found:
        return None
    lib = ctypes.CDLL(found[0])              # already loaded by embreex: the same copy
    vp, u32, sz = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
    for name, res, args in (("rtcGetSceneDevice", vp, [vp]), ("rtcNewGeometry", vp, [vp, ctypes.c_int]),
                            ("rtcSetNewGeometryBuffer", vp, [vp, ctypes.c_int, u32, ctypes.c_int, sz, sz]),
                            ("rtcCommitGeometry", None, [vp]), ("rtcAttachGeometry", u32, [vp, vp]),
                            ("rtcReleaseGeometry", None, [vp]), ("rtcReleaseDevice", None, [vp])):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


def _layout():
    """The byte offset of scene_i in an EmbreeScene, checked through is_committed, or None."""
    from embreex.rtcore_scene import EmbreeScene
    if platform.python_implementation() != "CPython" or ctypes.sizeof(ctypes.c_void_p) != 8:
        return None
    scene = EmbreeScene(robust=True)
    offset = object.__basicsize__ + ctypes.sizeof(ctypes.c_void_p)        # after the header and scene_i
    if type(scene).__basicsize__ < offset + ctypes.sizeof(ctypes.c_int):
        return None
    scene.is_committed = MARKER
    seen = ctypes.c_int.from_address(id(scene) + offset).value
    scene.is_committed = 0
    if seen != MARKER or ctypes.c_int.from_address(id(scene) + offset).value != 0:
        return None
    return object.__basicsize__


def available() -> bool:
    """Whether attach_triangles can be used with this embreex (checked once per process)."""
    if "ok" not in _state:
        try:
            from importlib.metadata import version
            if version("embreex") not in CHECKED_EMBREEX:
                _state["ok"] = False
                return False
            _state["lib"], _state["offset"] = _library(), _layout()
            _state["ok"] = _state["lib"] is not None and _state["offset"] is not None
        except Exception:                   # noqa: BLE001 - anything unexpected: embreex's own TriangleMesh
            _state["ok"] = False
    return _state["ok"]


def function_address(name: str) -> int:
    """The address of Embree's C function `name` in the library embreex loaded (available() must be
    True): embree_jit.py calls rtcIntersect1 and rtcOccluded1 through it."""
    return ctypes.cast(getattr(_state["lib"], name), ctypes.c_void_p).value


def scene_handle(scene) -> int:
    """The RTCScene of an embreex EmbreeScene (available() must be True)."""
    return ctypes.c_void_p.from_address(id(scene) + _state["offset"]).value


def attach_triangles(scene, triangles: np.ndarray) -> None:
    """Add (n, 3, 3) float32 triangles to an embreex EmbreeScene as TriangleMesh(scene, triangles)
    does: one triangle geometry, each corner its own vertex."""
    lib = _state["lib"]
    handle = scene_handle(scene)
    n = len(triangles)
    device = lib.rtcGetSceneDevice(handle)      # retains the device
    geometry = lib.rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE)
    lib.rtcReleaseDevice(device)
    if not geometry:
        raise MemoryError(f"Embree could not make a geometry of {n} triangles")
    address = lib.rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                          VERTEX_STRIDE, 3 * n)
    if not address:
        lib.rtcReleaseGeometry(geometry)
        raise MemoryError(f"Embree could not allocate the vertex buffer of {n} triangles")
    vertices = np.ctypeslib.as_array((ctypes.c_float * (4 * 3 * n)).from_address(address)).reshape(3 * n, 4)
    corners = triangles.reshape(3 * n, 3)
    for k in range(3):              # a column at a time: 8 times faster than vertices[:, :3] = corners
        vertices[:, k] = corners[:, k]
    vertices[:, 3] = 0.0
    address = lib.rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, n)
    if not address:
        lib.rtcReleaseGeometry(geometry)
        raise MemoryError(f"Embree could not allocate the index buffer of {n} triangles")
    indices = np.ctypeslib.as_array((ctypes.c_uint32 * (3 * n)).from_address(address))
    indices[:] = np.arange(3 * n, dtype=np.uint32)
    lib.rtcCommitGeometry(geometry)
    lib.rtcAttachGeometry(handle, geometry)
    lib.rtcReleaseGeometry(geometry)
