"""The input-node kernels (engine/nodes/inputs.py), the Image Texture node (engine/nodes/image.py) and the
hit attributes of a scene (engine/nodes/context.py SceneAttributes)."""
import math

import numpy as np
import pytest

from engine.geometry.scene_geometry import TRIANGLE
from engine.nodes import image, inputs
from engine.nodes.context import HitPoints, NodeContext, SceneAttributes
from engine.scene.model import Material, Scene, TriangleMesh


def test_mapping_point_texture_vector_normal_as_cycles():
    v = np.array([[1.0, 0.0], [0.0, 2.0], [0.5, 1.0]])
    loc, rot, scale = (np.array([[0.1], [0.2], [0.3]]) * np.ones(2), np.array([[0.3], [-0.2], [0.7]]) * np.ones(2),
                       np.array([[2.0], [1.0], [0.5]]) * np.ones(2))
    x, y, z = rot[:, 0]
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    r = rz @ ry @ rx                                            # Blender's XYZ Euler
    ctx = NodeContext(2)
    args = {"Vector": v, "Location": loc, "Rotation": rot, "Scale": scale}

    def out(kind):
        return inputs.mapping(args, {"vector_type": kind}, ctx)["Vector"]
    assert np.allclose(out("POINT"), r @ (v * scale) + loc)
    assert np.allclose(out("TEXTURE"), (r.T @ (v - loc)) / scale)
    assert np.allclose(out("VECTOR"), r @ (v * scale))
    n = r @ (v / scale)
    assert np.allclose(out("NORMAL"), n / np.linalg.norm(n, axis=0))
    # the inverse of POINT is TEXTURE
    back = inputs.mapping({**args, "Vector": out("POINT")}, {"vector_type": "TEXTURE"}, ctx)["Vector"]
    assert np.allclose(back, v)


def test_layer_weight_and_fresnel_match_the_mix_factors():
    from engine.materials.mix import factor_value
    from engine.materials.protocol import ShadingPoint
    from engine.scene.model import MixFactor
    rng = np.random.default_rng(3)
    wo = rng.normal(size=(3, 50))
    wo[2] = np.abs(wo[2])
    wo /= np.linalg.norm(wo, axis=0)
    n = np.tile([[0.0], [0.0], [1.0]], 50)
    outward = np.where(rng.random(50) < 0.3, -1.0, 1.0) * n      # some back faces
    si = ShadingPoint(wo, n, n, outward, np.ones((3, 50)), np.zeros(50, np.int64), False, None, None)
    ctx = NodeContext(50, (5, 0), {"incoming": wo, "normal": n,
                                   "backfacing": ((wo * outward).sum(0) < 0).astype(float)})
    for blend in (0.2, 0.5, 0.8):
        lw = inputs.layer_weight({"Blend": np.full(50, blend)}, {}, ctx)
        for output in ("fresnel", "facing"):
            expected = factor_value(MixFactor(kind="layer_weight", blend=blend, output=output), si)
            assert np.allclose(np.clip(lw[output.capitalize()], 0, 1), expected)
    fr = inputs.fresnel({"IOR": np.full(50, 1.45)}, {}, ctx)["Fac"]
    assert np.allclose(fr, factor_value(MixFactor(kind="fresnel", ior=1.45), si))


def mesh_scene(matrix):
    verts = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    world = verts @ matrix[:3, :3].T + matrix[:3, 3]
    mesh = TriangleMesh("Tri", world, np.array([[0, 1, 2]]), np.array([0]),
                        uvs=np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]]), object_matrix=matrix)
    return Scene(None, [Material("M")], [mesh], [], [])


def test_object_generated_uv_and_normal_coordinates_at_a_hit():
    matrix = np.eye(4)
    matrix[:3, :3] = np.diag([2.0, 1.0, 1.0]) @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    matrix[:3, 3] = (1.0, 2.0, 3.0)
    scene = mesh_scene(matrix)
    attrs = SceneAttributes(scene, scene.meshes[0].vertices[scene.meshes[0].triangles],
                            np.array([[0.0], [0.0], [1.0], [0.0], [0.0], [1.0]]))
    b1, b2 = np.array([0.25]), np.array([0.5])                 # local point (0.5, 0.5, 0)
    ctx = attrs.context(np.array([TRIANGLE]), np.array([0]), b1, b2, None, (5, 0), None, TRIANGLE)
    assert np.allclose(ctx.attr("object")[:, 0], [0.5, 0.5, 0.0])
    assert np.allclose(ctx.attr("generated")[:, 0], [0.25, 0.5, 0.5])    # bounding box [0, 2] x [0, 1] x 0
    assert np.allclose(ctx.attr("uv")[:, 0], [0.25, 0.5, 0.0])
    assert np.allclose(np.abs(ctx.attr("object_normal")[:, 0]), [0.0, 0.0, 1.0])
    assert np.allclose(ctx.attr("object_location")[:, 0], [1.0, 2.0, 3.0])


def test_hit_points_give_the_viewer_facing_normals_and_backfacing():
    scene = mesh_scene(np.eye(4))
    attrs = SceneAttributes(scene, scene.meshes[0].vertices[scene.meshes[0].triangles], None)
    up = np.array([[0.0], [0.0], [1.0]])
    points = HitPoints(point=np.zeros((3, 1)), direction=up.copy(), normal=up, shading=up)   # from below
    ctx = attrs.context(np.array([TRIANGLE]), np.array([0]), np.zeros(1), np.zeros(1), points, (5, 0), None, TRIANGLE)
    assert ctx.attr("backfacing")[0] == 1.0
    assert np.allclose(ctx.attr("normal")[:, 0], [0, 0, -1]) and np.allclose(ctx.attr("incoming")[:, 0], [0, 0, -1])
    geo = inputs.geometry({}, {"_outputs": ["Normal", "Backfacing"]}, ctx)
    assert set(geo) == {"Normal", "Backfacing"}


def test_sphere_and_tube_maps_as_cycles():
    co = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).T   # +x, +y, +z
    u, v = image.map_to_sphere(co)
    assert np.allclose(u, [0.25, 0.5, 0.0]) and np.allclose(v, [0.5, 0.5, 1.0])
    u, v = image.map_to_tube(co)
    assert np.allclose(u, [0.25, 0.5, 0.0]) and np.allclose(v, [0.5, 0.5, 0.0])      # on the axis: 0, 0


@pytest.mark.parametrize("blend", [0.0, 0.3, 1.0])
def test_box_weights_sum_to_one_and_pick_the_dominant_axis(blend):
    rng = np.random.default_rng(1)
    n = rng.normal(size=(3, 400))
    w = image.box_weights(n, blend)
    assert np.allclose(w.sum(axis=0), 1.0) and (w >= -1e-12).all()
    axis = np.argmax(np.abs(n), axis=0)
    strong = np.abs(n).max(axis=0) > 0.9 * np.linalg.norm(n, axis=0)
    assert (np.argmax(w, axis=0)[strong] == axis[strong]).all()


def test_image_node_reads_the_scene_images():
    class Images:
        def sample(self, texture, u, v, interpolation, extension, alpha):
            return np.stack([u, v, np.full(len(u), texture)]), np.ones(len(u))
    ctx = NodeContext(2, images=Images())
    co = np.array([[0.1, 0.2], [0.3, 0.4], [0.0, 0.0]])
    out = image.image_texture({"Vector": co}, {"texture": 5, "projection": "FLAT"}, ctx)
    assert np.allclose(out["Color"], [[0.1, 0.2], [0.3, 0.4], [5, 5]])
    missing = image.image_texture({"Vector": co}, {"texture": -1}, ctx)["Color"]
    assert np.allclose(missing[:, 0], image.MISSING)


def test_light_path_flags():
    ctx = NodeContext(4, attributes={"ray_kind": np.array([0, 1, 2, 4]), "ray_depth": np.array([0, 1, 2, 0])})
    out = inputs.light_path({}, {}, ctx)
    assert out["Is Camera Ray"].tolist() == [1, 0, 0, 0] and out["Is Shadow Ray"].tolist() == [0, 0, 0, 1]
    assert out["Is Diffuse Ray"].tolist() == [0, 1, 0, 0] and out["Ray Depth"].tolist() == [0, 1, 2, 0]


def test_mapping_with_a_rotation_per_point_matches_each_point_alone():
    rng = np.random.default_rng(5)
    v, loc, rot, scale = (rng.normal(size=(3, 4)) for _ in range(4))
    together = inputs.mapping({"Vector": v, "Location": loc, "Rotation": rot, "Scale": scale},
                              {"vector_type": "TEXTURE"}, NodeContext(4))["Vector"]
    for i in range(4):
        alone = inputs.mapping({"Vector": v[:, i:i + 1], "Location": loc[:, i:i + 1], "Rotation": rot[:, i:i + 1],
                                "Scale": scale[:, i:i + 1]}, {"vector_type": "TEXTURE"}, NodeContext(1))["Vector"]
        assert np.allclose(together[:, i:i + 1], alone)
