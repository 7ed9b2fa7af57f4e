"""The hit attributes and normal factors computed in fewer NumPy passes give the numbers of the forms
they replaced, bit for bit (engine/nodes/context.py SceneAttributes: Object and Generated coordinates
and the positions at light samples; engine/nodes/normals.py bump_shadowing at the changed normals
only).  The reference forms are written out here as the code had them."""
import numpy as np

from engine.geometry.scene_geometry import TRIANGLE
from engine.nodes.context import SceneAttributes
from engine.nodes.normals import bump_shadowing
from engine.scene.model import Material, Scene, TriangleMesh


def scene_of(count, rng, zero_object=False):
    meshes = []
    for i in range(count):
        matrix = np.eye(4)
        matrix[:3, :3] = rng.normal(size=(3, 3)) * 10.0 ** rng.integers(-3, 3)
        matrix[:3, 3] = rng.normal(size=3) * 10.0 ** rng.integers(-3, 3)
        if zero_object:                      # a mirror matrix about the origin: -0.0 terms at the origin
            matrix = np.diag([-1.0, -1.0, -1.0, 1.0])
        verts = rng.normal(size=(6, 3)) * 10.0 ** rng.integers(-2, 3)
        meshes.append(TriangleMesh(f"M{i}", verts, np.array([[0, 1, 2], [3, 4, 5]]), np.zeros(2, np.int64),
                                   object_matrix=matrix))
    scene = Scene(None, [Material("M")], meshes, [], [])
    triangles = np.concatenate([m.vertices[m.triangles] for m in meshes])
    return scene, SceneAttributes(scene, triangles, None)


def reference(attrs, kind, prim, b1, b2, position=None):
    """(position, object, generated) as the einsum / gathered forms gave them."""
    tri = np.flatnonzero(kind == TRIANGLE)
    prim_t, b1t, b2t = prim[tri], b1[tri], b2[tri]
    obj = attrs.tri_object[prim_t]
    if position is None:
        c = attrs.triangles[prim_t]
        b0 = 1.0 - b1t - b2t
        position = np.zeros((3, len(kind)))
        position[:, tri] = (b0[:, None] * c[:, 0] + b1t[:, None] * c[:, 1] + b2t[:, None] * c[:, 2]).T
    m = attrs.to_object[obj]
    local = np.einsum("kij,jk->ik", m[:, :, :3], position[:, tri]) + m[:, :, 3].T
    obj_pos = position.copy()
    obj_pos[:, tri] = local
    generated = obj_pos.copy()
    generated[:, tri] = (obj_pos[:, tri] - attrs.centre[obj].T) / (2.0 * attrs.size[obj].T) + 0.5
    return position, obj_pos, generated


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(np.signbit(a), np.signbit(b)) and np.array_equal(a, b)


def test_object_and_generated_coordinates_are_the_einsum_numbers():
    rng = np.random.default_rng(5)
    for count, n in ((1, 300), (3, 500)):
        scene, attrs = scene_of(count, rng)
        prim = rng.integers(0, 2 * count, n)
        b1, b2 = rng.random(n) * 0.5, rng.random(n) * 0.5
        for kind in (np.full(n, TRIANGLE), np.where(rng.random(n) < 0.8, TRIANGLE, TRIANGLE + 1)):
            kind = kind.astype(np.int8)
            ctx = attrs.context(kind, prim, b1, b2, None, (5, 0), None, TRIANGLE)
            position, obj_pos, generated = reference(attrs, kind, prim, b1, b2)
            assert same_bits(ctx.attr("position"), position) or not (kind != TRIANGLE).any()
            assert np.array_equal(ctx.attr("position")[:, kind == TRIANGLE], position[:, kind == TRIANGLE])
            assert same_bits(ctx.attr("object"), obj_pos)
            assert same_bits(ctx.attr("generated"), generated)
    # control: the sum in another order is not the einsum's (the comparison can fail)
    m = attrs.to_object[attrs.tri_object[prim]]
    p = ctx.attr("position")
    other = m[:, 0, 2] * p[2] + m[:, 0, 1] * p[1] + m[:, 0, 0] * p[0] + m[:, 0, 3]
    assert not np.array_equal(other[kind == TRIANGLE], ctx.attr("object")[0][kind == TRIANGLE])


def test_zero_terms_give_einsums_positive_zero():
    """At the origin under a mirror matrix every term is -0.0: einsum's sum starts from 0.0."""
    rng = np.random.default_rng(2)
    scene, attrs = scene_of(1, rng, zero_object=True)
    kind, prim = np.full(2, TRIANGLE, np.int8), np.zeros(2, np.int64)
    points = np.zeros((3, 2))
    from engine.nodes.context import HitPoints
    ctx = attrs.context(kind, prim, np.zeros(2), np.zeros(2), HitPoints(point=points), (5, 0), None, TRIANGLE)
    _, obj_pos, _ = reference(attrs, kind, prim, np.zeros(2), np.zeros(2), points)
    assert not np.signbit(obj_pos).any() and same_bits(ctx.attr("object"), obj_pos)
    assert np.signbit(-1.0 * points[0] + -0.0 * points[1] + -0.0 * points[2] + -0.0).all()   # control


def test_positions_at_light_samples_keep_their_layout():
    rng = np.random.default_rng(8)
    scene, attrs = scene_of(2, rng)
    n = 64
    kind, prim = np.full(n, TRIANGLE, np.int8), rng.integers(0, 4, n)
    b1, b2 = rng.random(n) * 0.5, rng.random(n) * 0.5
    position = attrs.context(kind, prim, b1, b2, None, (5, 0), None, TRIANGLE).attr("position")
    expected = reference(attrs, kind, prim, b1, b2)[0]
    c = attrs.triangles[prim]
    gathered = (((1.0 - b1 - b2)[:, None] * c[:, 0] + b1[:, None] * c[:, 1] + b2[:, None] * c[:, 2]).T)
    assert same_bits(position, expected) and position.strides == gathered.strides


def bump_reference(smooth, n, wi, diffuse, is_eval):
    """bump_shadowing under Blender 4.x / 5.0 over every point, as it was computed."""
    dot = lambda a, b: (a * b).sum(axis=0)
    same = (smooth == n).all(axis=0)
    cos_si, cos_sn, cos_ni = dot(smooth, wi), dot(smooth, n), dot(n, wi)
    reject = (cos_si * cos_sn * cos_ni < 0.0) & (is_eval | diffuse)
    cos_i, cos_d = np.abs(cos_si), np.abs(cos_sn)
    with np.errstate(divide="ignore", invalid="ignore"):
        tan2_d = 1.0 / np.maximum(cos_d, 1e-300) ** 2 - 1.0
        alpha2 = np.clip(0.125 * tan2_d, 0.0, 1.0)
        c2 = np.maximum(cos_i, 1e-300) ** 2
        lam = 0.5 * (np.sqrt(1.0 + alpha2 * (1.0 - c2) / c2) - 1.0)
        soft = 1.0 / (1.0 + lam)
    soft = np.where((cos_d >= 1.0) | (cos_i >= 1.0), 1.0, np.where(cos_i < 1e-6, 0.0, soft))
    return np.where(same, 1.0, np.where(reject, 0.0, np.where(diffuse, soft, 1.0)))


def test_bump_shadowing_at_the_changed_normals_only_gives_the_same_numbers():
    rng = np.random.default_rng(4)
    k = 400
    unit = lambda v: v / np.linalg.norm(v, axis=0)
    smooth, wi = unit(rng.normal(size=(3, k))), unit(rng.normal(size=(3, k)))
    n = unit(smooth + 0.4 * rng.normal(size=(3, k)))
    for share in (0.0, 0.3, 1.0):                                 # none, some, all unchanged
        nn = np.where(rng.random(k) < share, smooth, n)
        for diffuse in (rng.random(k) < 0.5, True, np.zeros(k, bool)):
            for is_eval in (False, True):
                got = bump_shadowing(smooth, nn, wi, diffuse, is_eval, (5, 0))
                want = bump_reference(smooth, nn, wi, diffuse, is_eval)
                assert got.shape == (k,) and np.array_equal(got, want)
    assert not np.array_equal(bump_shadowing(smooth, n, wi, True, False), np.ones(k))     # control: not all 1


def test_object_points_follow_einsums_order_for_every_layout():
    from engine.nodes.context import object_points
    rng = np.random.default_rng(9)
    table = rng.normal(size=(3, 3, 4)) * 10.0 ** rng.integers(-5, 5, size=(3, 3, 4))
    for k in (1, 2, 7, 300):
        big = rng.normal(size=(3, k + 5)) * 10.0 ** rng.integers(-5, 5, size=(3, k + 5))
        obj = rng.integers(0, 3, k)
        for points in (np.ascontiguousarray(big[:, :k]), np.asfortranarray(big[:, :k]), big[:, 2:k + 2],
                       np.asfortranarray(big)[:, 2:k + 2], big[:, ::-1][:, :k], big[:, :2 * (k // 2):2]):
            m = table[obj[:points.shape[1]]]
            want = np.einsum("kij,jk->ik", m[:, :, :3], points) + m[:, :, 3].T
            assert same_bits(object_points(m, points), want)
            if points.shape[1] > 100:   # control: the other order differs on these numbers
                a = [m[:, 0, j] * points[j] for j in range(3)]
                other = (a[0] + a[2]) + a[1] if points.strides[0] != 8 else (a[0] + a[1]) + a[2]
                assert not np.array_equal(other + m[:, 0, 3], want[0])
