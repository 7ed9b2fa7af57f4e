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


def corner_colors(me, names, label, warnings):
    """{name: linear corner colours float64 (T, 3, 3)} of the colour attributes `names` (Attribute nodes
    of node programs, mcrt_addon/export/node_graph.py attribute_names) on a mesh whose loop triangles
    are computed: point or corner domain, read with foreach_get ("color": scene linear); a name the
    mesh lacks is left out (Cycles reads 0 there)."""
    out = {}
    if not names:
        return out
    attributes = getattr(me, "color_attributes", None)
    nt = len(me.loop_triangles)
    loops = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", loops)
    for name in names:
        attr = attributes.get(name) if attributes is not None else None
        if attr is None or attr.domain not in ("POINT", "CORNER"):
            continue
        values = np.empty(len(attr.data) * 4, np.float32)
        attr.data.foreach_get("color", values)
        values = values.reshape(-1, 4)[:, :3].astype(np.float64)
        if attr.domain == "POINT":
            corner_vertex = np.empty(len(me.loops), np.int32)
            me.loops.foreach_get("vertex_index", corner_vertex)
            values = values[corner_vertex]
        out[name] = values[loops].reshape(nt, 3, 3)
    return out


def _texture_space(me, verts):
    """(centre, half size) of the mesh's texture space (Blender's auto texture space: the bounding
    box), each zero size made 1 as Blender does; from the bounding box of `verts` if unreadable."""
    try:
        loc = np.array(me.texspace_location, dtype=np.float64)
        size = np.array(me.texspace_size, dtype=np.float64)
    except (AttributeError, TypeError):
        v = verts.astype(np.float64)
        loc, size = 0.5 * (v.min(axis=0) + v.max(axis=0)), 0.5 * (v.max(axis=0) - v.min(axis=0))
    return loc, np.where(size == 0.0, 1.0, size)


def corner_bitangent_signs(me, need):
    """The corner bitangent signs float64 (T, 3) of the UV map's MikkTSpace tangents (after
    corner_tangents computed them for ("uv", name)), for Normal Map nodes; None otherwise."""
    if need is None or need == "radial" or not len(me.loops):
        return None
    nt = len(me.loop_triangles)
    loops = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", loops)
    sign = np.empty(len(me.loops), np.float32)
    me.loops.foreach_get("bitangent_sign", sign)
    return sign[loops].reshape(nt, 3).astype(np.float64)


def corner_tangents(me, need, verts, tris, label, warnings):
    """Local-space corner tangents float64 (T, 3, 3) of a mesh whose loop triangles are computed, for
    anisotropic materials (export/materials.py tangent_need): None for need None; "radial": Cycles'
    default, primitive_tangent's (-(g_y - 1/2), g_x - 1/2, 0) of the generated coordinates
    g = (P - centre) / (2 half size) + 1/2 (linear in P: exact at every point when interpolated);
    ("uv", name): the UV map's MikkTSpace tangents (Mesh.calc_tangents, as Cycles' mikk_compute_tangents
    for the Tangent node's UV Map mode).  The world transform (export/__init__.py) is the normals'
    (Cycles' object_normal_transform)."""
    if need is None:
        return None
    if need != "radial":
        name = need[1]
        layers = me.uv_layers
        layer = layers.get(name) if name else next((lay for lay in layers if lay.active_render), None)
        try:
            if layer is None:
                raise RuntimeError(f"no UV map '{name}'" if name else "no UV map")
            me.calc_tangents(uvmap=layer.name)
            nt = len(me.loop_triangles)
            loops = np.empty(nt * 3, np.int32)
            me.loop_triangles.foreach_get("loops", loops)
            tangent = np.empty(len(me.loops) * 3, np.float32)
            me.loops.foreach_get("tangent", tangent)
            return tangent.reshape(-1, 3)[loops].reshape(nt, 3, 3).astype(np.float64)
        except RuntimeError as exc:
            warnings.append(f"Object '{label}': UV tangents cannot be computed ({exc}); "
                            "Cycles' default radial tangent is used")
    centre, size = _texture_space(me, verts)
    p = verts.astype(np.float64)[tris]                              # (T, 3, 3) corner positions
    g = (p - centre) / (2.0 * size)                                 # generated coordinates - 1/2
    return np.stack([-g[..., 1], g[..., 0], np.zeros(g.shape[:2])], axis=-1)


def mesh_normals(me):
    """Smooth shading of a mesh whose loop triangles are computed (mesh_arrays): (corner normals
    float32 (T, 3, 3), smooth (T,) bool or None when every face is smooth), or None when no face
    is smooth (flat shading: nothing to read).

    The corner normals are Blender's split normals, as Cycles uses them: vertex normals on smooth
    faces, custom normals where the mesh has them, sharp edges split.  Blender 4.1+ computes them
    on demand; 3.4-4.0 need calc_normals_split() first (it fills the evaluated mesh's runtime
    normals layer, as calc_loop_triangles() fills its triangles; the user's data is untouched).
    One foreach_get each, no Python loop over vertices."""
    n = len(me.polygons)
    nt = len(me.loop_triangles)
    if n == 0 or nt == 0:
        return None
    flags = np.empty(n, dtype=bool)
    me.polygons.foreach_get("use_smooth", flags)
    if not flags.any():
        return None
    if hasattr(me, "calc_normals_split"):            # Blender < 4.1
        me.calc_normals_split()
    corners = np.empty(nt * 9, np.float32)
    me.loop_triangles.foreach_get("split_normals", corners)
    smooth = None
    if not flags.all():
        poly = np.empty(nt, np.int32)
        me.loop_triangles.foreach_get("polygon_index", poly)
        smooth = flags[poly]
    return corners.reshape(nt, 3, 3), smooth


def transform_normals(normals, matrix):
    """Corner normals (..., 3) to world space: the inverse transpose of the 3x3 part (unnormalised;
    the scene normalises them and replaces bad ones)."""
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    try:
        inv = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(m)
    return normals.astype(np.float64) @ inv          # rows: n^T M^-1 = (M^-T n)^T


def terminator_offsets(ob):
    """(Shadow Terminator > Geometry Offset, [names of the other, unmodelled offsets that are not 0])
    of an object, read from the original: on the Object in 4.x/5.0, on ob.cycles in 3.x."""
    original = ob.original if getattr(ob, "original", None) is not None else ob
    holders = [original, getattr(original, "cycles", None)]
    geometry, others = 0.1, []
    for holder in holders:
        if holder is not None and hasattr(holder, "shadow_terminator_geometry_offset"):
            geometry = float(holder.shadow_terminator_geometry_offset)
            for attr, label in (("shadow_terminator_shading_offset", "shading offset"),
                                ("shadow_terminator_offset", "shading offset"),
                                ("shadow_terminator_normal_offset", "normal offset")):
                if float(getattr(holder, attr, 0.0) or 0.0) != 0.0:
                    others.append(label)
            break
    return min(max(geometry, 0.0), 1.0), others


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
