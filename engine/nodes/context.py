"""NodeContext: what the kernels of one program run see besides their inputs: the number of points
`n`, the running Blender's `cycles_version` (3.4's and 4.x/5.0's nodes differ), the images
(`images`: an object with `sample(texture, u, v, interpolation, extension) -> (rgb rows (3, N),
alpha (N,))`, engine/materials/textures.py TextureSet) and the hit attributes the input nodes read.

Attributes are given as arrays or as functions of no arguments (computed on first use and kept), so a
program pays only for what its nodes read.  Names (rows (3, N) unless noted), as Cycles' ShaderData:

  position        P, world space
  normal          N, the shading normal, flipped to the viewer's side on back faces (Cycles flips N
                  and Ng of back-facing hits)
  true_normal     Ng, the geometric normal, on the viewer's side
  incoming        I = the direction towards the viewer (-ray direction)
  backfacing      (N,) 1.0 where the ray hit the back face
  uv              (u, v, 0) of the mesh's UV map (one UV map per mesh: engine/scene/model.py uvs)
  generated       the object-space position mapped to its texture space: (P_obj - centre) / (2 half size) + 1/2
  object          P in object space (the inverse of the object's matrix)
  object_normal   normalize(M^T N), N in object space (Cycles' object_inverse_normal_transform)
  object_location the object's origin in world space
  object_random   (N,) Object Info's Random (Cycles' random_id / 0xFFFFFFFF)
  camera          P in Cycles' camera space (x right, y up, z forward; the camera's scale cleared)
  ray_depth       (N,) the bounce the hit was found on (0: the camera ray)
  ray_kind        (N,) int: 0 camera, 1 diffuse, 2 glossy, 3 transmission (the ray that found the hit),
                  4 a light sample (a shadow ray)
  ray_length      (N,) the distance from the ray origin
  color:NAME      a colour attribute's linear corner colours interpolated at the hit
  tangent         the UV map's interpolated (unnormalised) corner tangent, world space (Normal Map)
  tangent_sign    (N,) the interpolated corner bitangent sign; has_tangent (N,) bool: the hit has both
  tangent_base    the outward base normal of the tangent frame: the smooth normal, or Ng on flat faces
  tangent_corners a TangentCorners: what tangent and tangent_sign are interpolated from (the compiled
                  Normal Map makes them per hit itself: engine/nodes/normals_jit.py corner_normal_map)
  object_to_world_normal  a function: rows (3, N) in object space -> normalised world normals
  camera_pixel    (right, up, forward) rows (3, 1) of the camera and one pixel's size at unit distance
                  (the image centre's), for Bump's footprint (engine/nodes/normals.py bump_offsets)
  object_to_world (N, 3, 4) the hit's object matrix (identity off meshes); world_to_object its inverse
  world_to_camera (4, 4) world -> Cycles' camera space; camera_to_world its inverse (Vector Transform)
  _object, _one_object  (internal) the triangle hits' object ids, made when an object attribute first
                  reads them, and whether they are all one object
  window          Texture Coordinate's Window: (x, y, 0), the point's place in the camera's frame, 0..1
                  from the bottom left (Cycles' camera_world_to_ndc; `camera_window`)
`ctx.shifted(offset)` (None without hits) is the context of the same hits moved by offset rows (3, N)
along their surface: position, UV, Generated, ... there, the normals of the hits (Bump's heights).
When folding constants (n = 1, no hits) every attribute raises `Varying`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


SHADOW_RAY = 4        # ray_kind at light samples (engine/nodes/inputs.py Light Path: Is Shadow Ray)


class TangentCorners(NamedTuple):
    """The hits' kind, prim, b1, b2 (N,) and the scene's corner tangents (T, 3, 3) and bitangent signs
    (T, 3) (None, None: no mesh has tangents): a triangle hit's (kind == triangle_kind) tangent is its
    corners' tangents weighted by (1 - b1 - b2, b1, b2), its sign likewise; other hits have none."""
    kind: np.ndarray
    prim: np.ndarray
    b1: np.ndarray
    b2: np.ndarray
    triangle_kind: int
    tangents: np.ndarray | None
    signs: np.ndarray | None


class Varying(LookupError):
    """A kernel read a hit attribute (or an image) where none is given: its output is not constant."""


class NodeContext:
    def __init__(self, n: int, cycles_version=(5, 0), attributes=None, images=None):
        self.n = int(n)
        self.cycles_version = tuple(cycles_version)[:2]
        self.images = images
        self._attributes = dict(attributes or {})
        self._values: dict = {}                # the attributes read so far, lazy ones made
        self.folding = attributes is None      # evaluator.fold's context: no hits at all
        self.shifted = None                    # offset rows (3, N) -> NodeContext (SceneAttributes)
        self.warnings: list[str] = []

    def has(self, name: str) -> bool:
        return name in self._attributes

    def attr(self, name: str) -> np.ndarray:
        """The attribute `name` (see the module doc); Varying when the context has none."""
        if name not in self._attributes:
            raise Varying(name)
        if name in self._values:
            return self._values[name]
        value = self._attributes[name]
        if callable(value):             # a lazy attribute: made on its first read, kept
            value = value()
        self._values[name] = value      # (apart, so an attribute that is a function stays one)
        return value

    def image(self):
        if self.images is None:
            raise Varying("images")
        return self.images

    # conveniences
    def zeros(self) -> np.ndarray:
        return np.zeros(self.n)

    def zeros3(self) -> np.ndarray:
        return np.zeros((3, self.n))


def camera_to_world(camera) -> np.ndarray:
    """(4, 4) Cycles' camera space (x right, y up, z forward) -> world: the camera's matrix with z
    flipped and its scale cleared (Cycles' blender_camera_matrix)."""
    m = np.asarray(camera.matrix, dtype=np.float64) @ np.diag([1.0, 1.0, -1.0, 1.0])
    scale = np.linalg.norm(m[:3, :3], axis=0)
    scale = np.where(np.abs(scale - 1.0) < 1e-12, 1.0, np.maximum(scale, 1e-300))     # unscaled: as it was
    m[:3, :3] = m[:3, :3] / scale
    return m


def camera_window(camera, width: int, height: int):
    """points rows (3, N) -> Window rows (3, N) of a camera (engine/scene/model.py Camera; a `type`
    "ORTHO" with `ortho_scale`, when a camera has them, projects orthographically): where each point
    lands in the frame, x from the left and y from the bottom, 0..1 across the image with the lens
    shift, z 0 (Cycles' camera_world_to_ndc through its worldtondc: the view plane of
    engine/scene/camera_rays.py view_plane)."""
    from ..scene.camera_rays import view_plane
    ortho = getattr(camera, "type", "PERSP") == "ORTHO"
    if ortho:                         # the fitted side spans ortho_scale (the lens's place in view_plane)
        lens = float(camera.sensor_width if camera.sensor_fit != "VERTICAL" else camera.sensor_height)
        lens /= float(getattr(camera, "ortho_scale", 1.0))
        plane_w, plane_h, extent = view_plane(_Lens(camera, lens), width, height)
    else:
        plane_w, plane_h, extent = view_plane(camera, width, height)
    to_camera = np.linalg.inv(camera_to_world(camera))

    def window(points):
        local = to_camera[:3, :3] @ points + to_camera[:3, 3:4]
        if ortho:
            x, y = local[0], local[1]
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                depth = np.where(local[2] != 0.0, local[2], 1.0)
            x, y = local[0] / depth, local[1] / depth
        return np.stack([(x - camera.shift_x * extent) / plane_w + 0.5,
                         (y - camera.shift_y * extent) / plane_h + 0.5, np.zeros_like(x)])
    return window


class _Lens:
    """A camera seen through another focal length (camera_window's orthographic view plane)."""

    def __init__(self, camera, lens):
        self.sensor_fit, self.sensor_width, self.sensor_height = camera.sensor_fit, camera.sensor_width, camera.sensor_height
        self.lens = lens


# -- the attributes of hits on a scene --------------------------------------------------------------
class HitPoints:
    """What the integrator knows of some hits besides their primitives: the rows `point`, `direction`
    (the ray's), `normal` (outward geometric), `shading` (the shading normal, outward side) and the
    (N,) `depth`, `ray_kind`, `distance`; any may be None.  Sliced and taken as the hits are."""
    FIELDS = ("point", "direction", "normal", "shading", "depth", "ray_kind", "distance")

    def __init__(self, **arrays):
        for name in self.FIELDS:
            setattr(self, name, arrays.get(name))

    def _map(self, fn):
        return HitPoints(**{name: None if getattr(self, name) is None else fn(getattr(self, name))
                            for name in self.FIELDS})

    def __getitem__(self, span) -> "HitPoints":
        return self._map(lambda a: a[..., span])

    def take(self, index) -> "HitPoints":
        return self._map(lambda a: a.take(index, axis=a.ndim - 1))

    def taken(self, index) -> "HitPoints":
        """take(index) with each field taken when it is first read (a program reads few of them); for a
        context used at once: the fields read later are taken from the arrays as they are then."""
        return _Taken(self, index)

    def given(self, name: str) -> bool:
        """Whether field `name` is given (not None), without taking it."""
        return getattr(self, name) is not None


class _Taken(HitPoints):
    """HitPoints.taken: the fields of `source` at `index`, each taken on first use."""

    def __init__(self, source: HitPoints, index):       # no fields set: __getattr__ takes them
        self._source, self._index = source, index

    def __getattr__(self, name):
        if name not in HitPoints.FIELDS:
            raise AttributeError(name)
        a = getattr(self._source, name)
        value = None if a is None else a.take(self._index, axis=a.ndim - 1)
        setattr(self, name, value)
        return value

    def given(self, name: str) -> bool:
        return self._source.given(name)


def components_adjacent(points):
    """Which order object_points sums a point's terms in: True when the points' components are adjacent
    (rows (3, k) that are the transpose of a (k, 3) array: (0 + 2) + 1), False for rows whose
    components lie apart or one point whose rows are not item-strided ((0 + 1) + 2), None for other
    layouts (einsum's own)."""
    item = points.itemsize
    if points.strides[0] == item and points.shape[1] > 0:
        return True
    if points.strides[1] == item or points.shape[1] <= 1:
        return False
    return None


def object_points(m, points) -> np.ndarray:
    """m (k or 1, 3, 4) world-to-object matrices, points rows (3, k) -> the object-space rows: the
    numbers of einsum("kij,jk->ik", m[:, :, :3], points) + m[:, :, 3].T, without gathering a matrix
    per point.  That einsum sums the three products in an order set by the points' layout: (0 + 1) + 2
    when a point's components are apart (rows), (0 + 2) + 1 when they are adjacent (the (k, 3) form's
    transpose: its unrolled contiguous loop); it starts from 0.0, so "+ 0.0" turns the -0.0 that
    all-zero terms give here into its 0.0.  Other layouts: the einsum itself."""
    k = points.shape[1]
    adjacent = components_adjacent(points)
    if adjacent is None:
        full = np.broadcast_to(m, (k, 3, 4))
        return np.einsum("kij,jk->ik", full[:, :, :3], points) + full[:, :, 3].T
    first, second, third = (0, 2, 1) if adjacent else (0, 1, 2)
    out = np.empty((3, k))
    for i in range(3):
        np.multiply(m[:, i, first], points[first], out=out[i])
        out[i] += m[:, i, second] * points[second]
        out[i] += m[:, i, third] * points[third]
        out[i] += m[:, i, 3]
    out += 0.0
    return out


class SceneAttributes:
    """A scene's per-triangle data for the input nodes, gathered once per prepared scene: the corner
    UVs and colour attributes, each triangle's object (its inverse matrix, texture space, location,
    Random), the triangles' corners, and the camera (Cycles' camera space).

    `compiled`: None (NumPy), or engine/nodes/context_jit.py for a numba render (HitTextures sets it):
    the Object and Generated attributes in one loop each, the same numbers."""

    def __init__(self, scene, triangles, tri_uv, compiled=None):
        self.compiled = compiled
        meshes = [m for m in scene.meshes if len(m.triangles)]
        self.triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        self.tri_uv = tri_uv                       # rows (6, T)
        self.tri_object = (np.concatenate([np.full(len(m.triangles), i) for i, m in enumerate(meshes)])
                           if meshes else np.zeros(0, np.int64))
        count = max(len(meshes), 1)
        self.to_object = np.tile(np.eye(4)[:3], (count, 1, 1))          # (O, 3, 4) world -> object
        self.to_world = np.tile(np.eye(3), (count, 1, 1))               # (O, 3, 3) object -> world
        self.location = np.zeros((count, 3))
        self.centre = np.zeros((count, 3))
        self.size = np.ones((count, 3))
        self.random = np.zeros(count)
        for i, m in enumerate(meshes):
            matrix = np.eye(4) if m.object_matrix is None else np.asarray(m.object_matrix, dtype=np.float64)
            inverse = np.linalg.pinv(matrix)
            self.to_object[i], self.to_world[i], self.location[i] = inverse[:3], matrix[:3, :3], matrix[:3, 3]
            if m.texspace is not None:
                centre, size = (np.asarray(v, dtype=np.float64) for v in m.texspace)
            else:                                   # Blender's auto texture space: the bounding box
                local = np.asarray(m.vertices, dtype=np.float64) @ inverse[:3, :3].T + inverse[:3, 3]
                lo, hi = local.min(axis=0), local.max(axis=0)
                centre, size = 0.5 * (lo + hi), 0.5 * (hi - lo)
            flat = size <= 1e-9 * max(float(np.abs(size).max()), 1.0)       # Blender: a zero size is 1
            self.centre[i], self.size[i] = centre, np.where(flat, 1.0, size)
            self.random[i] = float(m.object_random)
        # Normal Map: per corner world tangents and bitangent signs (engine/scene/model.py TriangleMesh).
        self.tri_tangent = self.tri_sign = None
        if any(m.tangents is not None and getattr(m, "tangent_signs", None) is not None for m in meshes):
            self.tri_tangent = np.concatenate([np.asarray(m.tangents, dtype=np.float64).reshape(-1, 3, 3)
                                               if m.tangents is not None else np.zeros((len(m.triangles), 3, 3))
                                               for m in meshes])
            self.tri_sign = np.concatenate([np.asarray(m.tangent_signs, dtype=np.float64).reshape(-1, 3)
                                            if getattr(m, "tangent_signs", None) is not None
                                            else np.zeros((len(m.triangles), 3)) for m in meshes])
        names = sorted({name for m in meshes for name in (m.colors or {})})
        self.colors = {}
        for name in names:
            parts = [np.asarray(m.colors[name], dtype=np.float64).reshape(-1, 9) if m.colors and name in m.colors
                     else np.zeros((len(m.triangles), 9)) for m in meshes]
            self.colors[name] = np.ascontiguousarray(np.concatenate(parts).T)        # rows (9, T)
        cam = getattr(scene, "camera", None)
        self.world_to_camera = None
        self.camera_pixel = None
        self.window = None
        if cam is not None:
            self.window = camera_window(cam, *(int(c) for c in getattr(scene, "resolution", (256, 256))))
            self.world_to_camera = np.linalg.inv(camera_to_world(cam))
            # The camera's axes and one pixel's size at unit distance, for Bump's footprint.
            w, h = (int(c) for c in getattr(scene, "resolution", (256, 256)))
            fit = getattr(cam, "sensor_fit", "AUTO")
            sensor = (cam.sensor_height if fit == "VERTICAL" else cam.sensor_width)
            across = h if fit == "VERTICAL" else (w if fit == "HORIZONTAL" else max(w, h))
            size = float(sensor) / float(cam.lens) / max(across, 1)
            m = np.asarray(cam.matrix, dtype=np.float64)
            self.camera_pixel = (m[:3, 0:1] / np.linalg.norm(m[:3, 0]),
                                 m[:3, 1:2] / np.linalg.norm(m[:3, 1]), -m[:3, 2:3] / np.linalg.norm(m[:3, 2]), size)

    def rows(self, name: str) -> np.ndarray:
        """The (T, 3, 3) corner array `name` (triangles, tri_tangent) as rows (9, T), corner c's
        component x in row 3 c + x (made on first use: gathers of rows are cheaper)."""
        cache = self.__dict__.setdefault("_rows", {})
        if name not in cache:
            cache[name] = np.ascontiguousarray(getattr(self, name).reshape(-1, 9).T)
        return cache[name]

    def context(self, kind, prim, b1, b2, points, cycles_version, images, triangle_kind) -> NodeContext:
        """The NodeContext of some hits (kind, prim, b1, b2 (N,); points: a HitPoints or None, e.g. at
        light samples: then positions and normals come from the triangles)."""
        n = len(kind)
        is_tri = kind == triangle_kind
        all_tri = bool(is_tri.all())
        # The triangle hits' positions among the hits: found here only when some are not triangles (all
        # of them: 0 .. n-1, made by the few attributes that index with them, `tri_index`).
        tri = None if all_tri else np.flatnonzero(is_tri)
        tri_count = n if all_tri else len(tri)

        def tri_index():
            return np.arange(n) if tri is None else tri
        # The triangle hits' primitives and barycentrics (all of the hits: the arrays themselves).
        prim_t, b1t, b2t = (prim, b1, b2) if all_tri else (prim.take(tri), b1.take(tri), b2.take(tri))

        def objects():
            """The triangle hits' objects (tri_count,) (read by the object attributes only)."""
            return self.tri_object.take(prim_t) if len(self.tri_object) else np.zeros(tri_count, np.int64)

        def one_object():
            """Whether the triangle hits all lie on one object (per_object then reads one row)."""
            obj = ctx.attr("_object")
            return len(self.centre) == 1 or (len(obj) > 0 and obj.min() == obj.max())

        def on_triangles(values_t, rest=0.0):
            """Rows (k, N) with the triangle hits' values; `rest` elsewhere."""
            if all_tri:
                return values_t
            out = np.full((values_t.shape[0], n), rest) if values_t.ndim == 2 else np.full(n, rest)
            out[..., tri] = values_t
            return out

        def bary(rows):             # rows (9, T): corner c's component x in row 3 c + x -> rows (3, tri_count)
            c = rows.take(prim_t, axis=1)
            b0 = 1.0 - b1t - b2t
            out = np.empty((tri_count, 3)).T     # the layout the (k, 3) form of this sum had
            np.multiply(b0, c[0:3], out=out)
            out += b1t * c[3:6]
            out += b2t * c[6:9]
            return out

        def position():
            if points is not None and points.point is not None:
                return points.point
            return on_triangles(bary(self.rows("triangles")))

        def geometric():
            c = self.triangles[prim_t]
            g = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]).T
            return on_triangles(g / np.maximum(np.sqrt((g * g).sum(axis=0)), 1e-300), 0.0)

        def towards():
            if points is None or points.direction is None or points.normal is None:
                return np.ones(n)
            return np.where((points.direction * points.normal).sum(axis=0) < 0.0, 1.0, -1.0)

        def true_normal():
            base = points.normal if points is not None and points.normal is not None else ctx.attr("_geometric")
            return base * ctx.attr("_towards")

        def normal():
            base = points.shading if points is not None and points.shading is not None else None
            return true_normal() if base is None else base * ctx.attr("_towards")

        def incoming():
            if points is None or points.direction is None:
                return ctx.attr("true_normal")
            return -points.direction

        def per_object(table):
            """table (O, ...) at the triangle hits' objects: one row when they all have one object
            (the products with it are the same numbers), else (k, ...)."""
            obj = ctx.attr("_object")
            return table[obj[0]][None] if ctx.attr("_one_object") else table.take(obj, axis=0)

        def obj_pos():
            p = ctx.attr("position")
            if not tri_count:
                return p
            pt = p[:, tri] if not all_tri else p
            m = per_object(self.to_object)
            adjacent = None if self.compiled is None or pt.dtype != np.float64 else components_adjacent(pt)
            local = (object_points(m, pt) if adjacent is None
                     else self.compiled.object_points(m, pt, adjacent))
            if all_tri:
                return local
            out = p.copy()
            out[:, tri] = local
            return out

        def texture_space(o):
            """Object-space rows (3, tri_count) of the triangle hits -> their Generated rows."""
            if self.compiled is not None:
                return self.compiled.generated(o, per_object(self.centre), per_object(self.size))
            centre, size = per_object(self.centre).T, per_object(self.size).T
            return (o - centre) / (2.0 * size) + 0.5

        def generated():
            o = ctx.attr("object")
            if not tri_count:
                return o
            if all_tri:
                return texture_space(o)
            out = o.copy()
            out[:, tri] = texture_space(o[:, tri])
            return out

        def object_normal():
            nrm = ctx.attr("normal")
            if not tri_count:
                return nrm
            m = self.to_world[ctx.attr("_object")]                    # M^T n
            hits_t = tri_index()
            local = np.einsum("kji,jk->ik", m, nrm[:, hits_t])
            out = nrm.copy()
            out[:, hits_t] = local / np.maximum(np.sqrt((local * local).sum(axis=0)), 1e-300)
            return out

        def uv():
            if self.tri_uv is None or not tri_count:
                return np.zeros((3, n))
            c = self.tri_uv.take(prim_t, axis=1)
            b0 = 1.0 - b1t - b2t
            u = b0 * c[0] + b1t * c[2] + b2t * c[4]
            v = b0 * c[1] + b1t * c[3] + b2t * c[5]
            return on_triangles(np.stack([u, v, np.zeros(tri_count)]))

        def camera():
            if self.world_to_camera is None:
                return np.zeros((3, n))
            m = self.world_to_camera
            return m[:3, :3] @ ctx.attr("position") + m[:3, 3:4]

        attrs = {"position": position, "_geometric": geometric, "_towards": towards, "true_normal": true_normal,
                 "normal": normal, "incoming": incoming, "object": obj_pos, "generated": generated,
                 "object_normal": object_normal, "uv": uv, "camera": camera,
                 "backfacing": lambda: (ctx.attr("_towards") < 0.0).astype(np.float64),
                 "object_location": lambda: on_triangles(self.location[ctx.attr("_object")].T),
                 "object_random": lambda: on_triangles(self.random[ctx.attr("_object")]),
                 "_object": objects, "_one_object": one_object}
        attrs["ray_kind"], attrs["ray_depth"] = lambda: np.full(n, SHADOW_RAY), lambda: np.zeros(n)   # light samples
        if points is not None:
            for name, field in (("ray_depth", "depth"), ("ray_kind", "ray_kind"), ("ray_length", "distance")):
                if points.given(field):
                    attrs[name] = (lambda field=field: getattr(points, field))
        for name, rows in self.colors.items():
            attrs[f"color:{name}"] = (lambda rows=rows: on_triangles(bary(rows)))
        def tangent_sign():
            if self.tri_sign is None or not tri_count:
                return np.zeros(n)
            c = self.tri_sign[prim_t]
            return on_triangles((1.0 - b1t - b2t) * c[:, 0] + b1t * c[:, 1] + b2t * c[:, 2])

        def to_world_normal(local):
            """Cycles' object_normal_transform: normalize(inverse(M)^T local)."""
            out = np.array(local, dtype=np.float64)
            if tri_count:
                m = self.to_object[ctx.attr("_object")][:, :, :3]     # inverse(M), (k, 3, 3)
                hits_t = tri_index()
                out[:, hits_t] = np.einsum("kji,jk->ik", m, out[:, hits_t])
            return out / np.maximum(np.sqrt((out * out).sum(axis=0)), 1e-300)

        attrs["tangent"] = lambda: (np.zeros((3, n)) if self.tri_tangent is None or not tri_count
                                    else on_triangles(bary(self.rows("tri_tangent"))))
        attrs["tangent_sign"] = tangent_sign
        attrs["has_tangent"] = lambda: ((ctx.attr("tangent_sign") != 0.0)
                                        & ((ctx.attr("tangent") ** 2).sum(axis=0) > 0.0))
        attrs["tangent_base"] = lambda: ctx.attr("normal") * ctx.attr("_towards")
        attrs["tangent_corners"] = lambda: TangentCorners(kind, prim, b1, b2, triangle_kind, self.tri_tangent,
                                                          self.tri_sign)
        attrs["object_to_world_normal"] = lambda: to_world_normal
        if self.camera_pixel is not None:
            attrs["camera_pixel"] = self.camera_pixel

        def object_transforms(inverse):
            out = np.tile(np.eye(4)[:3], (n, 1, 1))
            if tri_count:
                out[tri_index()] = (self.to_object if inverse else np.concatenate(
                    [self.to_world, self.location[:, :, None]], axis=2))[ctx.attr("_object")]
            return out
        attrs["object_to_world"] = lambda: object_transforms(False)
        attrs["world_to_object"] = lambda: object_transforms(True)
        if self.world_to_camera is not None:
            attrs["world_to_camera"] = self.world_to_camera
            attrs["camera_to_world"] = lambda: np.linalg.inv(self.world_to_camera)
            attrs["window"] = lambda: self.window(ctx.attr("position"))
        ctx = NodeContext(n, cycles_version, attrs, images)

        def shifted(offset):
            """The context of these hits moved by `offset` rows (3, N) (their normals kept)."""
            nb1, nb2 = b1.copy(), b2.copy()
            if tri_count:
                c = self.triangles[prim_t]
                e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
                hits_t = tri_index()
                w = (ctx.attr("position")[:, hits_t] + offset[:, hits_t]).T - c[:, 0]
                d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
                w1, w2 = (w * e1).sum(1), (w * e2).sum(1)
                inv = 1.0 / np.maximum(d11 * d22 - d12 * d12, 1e-300)
                nb1[hits_t], nb2[hits_t] = (d22 * w1 - d12 * w2) * inv, (d11 * w2 - d12 * w1) * inv
            moved = HitPoints(**{f: getattr(points, f) for f in HitPoints.FIELDS}) if points is not None else \
                HitPoints(direction=None)
            moved.point = ctx.attr("position") + offset
            moved.normal = ctx.attr("true_normal") * ctx.attr("_towards") if moved.normal is None else moved.normal
            moved.shading = ctx.attr("normal") * ctx.attr("_towards") if moved.shading is None else moved.shading
            return self.context(kind, prim, nb1, nb2, moved, cycles_version, images, triangle_kind)
        ctx.shifted = shifted
        return ctx
