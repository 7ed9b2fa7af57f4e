"""Mesh export: evaluated mesh -> NumPy arrays (foreach_get on loop_triangles, no Python loops),
and the implicit-sphere test."""
import numpy as np


def mesh_arrays(me):
    """Local-space (vertices float32 (V,3), triangles int32 (T,3), material slot int32 (T,))."""
    me.calc_loop_triangles()
    nv, nt = len(me.vertices), len(me.loop_triangles)
    verts = np.empty(nv * 3, np.float32)
    me.vertices.foreach_get("co", verts)
    tris = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("vertices", tris)
    mats = np.empty(nt, np.int32)
    me.loop_triangles.foreach_get("material_index", mats)
    return verts.reshape(nv, 3), tris.reshape(nt, 3), mats


def corner_uvs(me, uv_map, label, warnings):
    """Per-triangle corner UVs float32 (T, 3, 2) of the UV map `uv_map` ('' = the active render
    map), read with foreach_get (loop_triangles' loops index the UV layer); None when `uv_map` is
    None (no texture needs UVs) or the mesh has no such map (with a warning: UVs are then 0)."""
    if uv_map is None:
        return None
    layers = me.uv_layers
    layer = layers.get(uv_map) if uv_map else next((lay for lay in layers if lay.active_render), None)
    nt = len(me.loop_triangles)
    if layer is None:
        what = f"UV map '{uv_map}'" if uv_map else "UV map"
        warnings.append(f"Object '{label}': no {what}; its textures are read at UV (0, 0)")
        return np.zeros((nt, 3, 2), np.float32)
    loops = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(len(me.loops) * 2, np.float32)
    if hasattr(layer, "uv"):                              # 3.5+: a FLOAT2 corner attribute
        layer.uv.foreach_get("vector", uv)
    else:                                                 # 3.4
        layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)


def has_smooth_faces(me):
    """True when any face is smooth-shaded (Cycles then interpolates vertex normals)."""
    n = len(me.polygons)
    if n == 0:
        return False
    flags = np.empty(n, dtype=bool)
    me.polygons.foreach_get("use_smooth", flags)
    return bool(flags.any())


def transform_points(points, matrix):
    m = np.asarray(matrix, dtype=np.float64)
    return points.astype(np.float64) @ m[:3, :3].T + m[:3, 3]


def uniform_scale(matrix, rtol=1e-5):
    """The scale factor when the 3x3 part is a rotation times a uniform scale, else None."""
    a = np.asarray(matrix, dtype=np.float64)[:3, :3]
    s = np.linalg.svd(a, compute_uv=False)
    if s[0] <= 0 or (s[0] - s[2]) > rtol * s[0]:
        return None
    return float(s.mean())


def is_closed(tris):
    """Every undirected edge is used by exactly two triangles (a closed 2-manifold)."""
    if len(tris) == 0:
        return False
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e.sort(axis=1)
    key = e[:, 0].astype(np.int64) * (int(tris.max()) + 1) + e[:, 1]
    _, counts = np.unique(key, return_counts=True)
    return bool((counts == 2).all())


def sphere_fit(verts, tris, mats, rtol=1e-4):
    """(centre, radius) in local space when the mesh is a closed, finely tessellated sphere
    (all vertices equidistant from the centre, triangle centroids close to the surface,
    one material), else None.  A cube or an octahedron has equidistant vertices but fails the
    centroid test; a hemisphere is not closed."""
    if len(verts) < 20 or len(tris) < 32 or len(np.unique(mats)) != 1:
        return None
    v = verts.astype(np.float64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    d = np.linalg.norm(v - centre, axis=1)
    radius = float(d.mean())
    if radius <= 0 or np.abs(d - radius).max() > rtol * radius:
        return None
    centroids = v[tris].mean(axis=1)
    if np.linalg.norm(centroids - centre, axis=1).min() < 0.95 * radius:
        return None
    if not is_closed(tris):
        return None
    return centre, radius


def bounding_sphere(verts):
    v = verts.astype(np.float64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    return centre, float(np.linalg.norm(v - centre, axis=1).max())
