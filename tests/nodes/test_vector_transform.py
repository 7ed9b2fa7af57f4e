"""Vector Transform (engine/nodes/vector_transform.py) and the hit attributes it and Texture
Coordinate Window read (engine/nodes/context.py), without Blender: a round trip through Object space
is the identity, a normal stays perpendicular to the surface under an uneven scale (5.0; as a vector,
3.4's, it does not: the control), the scene's hits carry their object's matrix, and a point on the
camera's axis has Window (0.5, 0.5) (off it with the lens shift)."""
import numpy as np
import pytest

from engine.nodes.context import NodeContext, Varying, camera_window
from engine.nodes.vector_transform import vector_transform
from engine.scene.model import Camera

M = np.array([[2.0, 0.0, 0.0, 0.5], [0.0, 0.5, 0.0, -1.0], [0.0, 0.0, 1.0, 2.0], [0.0, 0.0, 0.0, 1.0]])


def ctx(version=(5, 0), n=2):
    cam = np.eye(4)
    return NodeContext(n, version, {"object_to_world": np.tile(M[:3], (n, 1, 1)),
                                    "world_to_object": np.tile(np.linalg.inv(M)[:3], (n, 1, 1)),
                                    "world_to_camera": cam, "camera_to_world": cam})


def vt(v, kind, a, b, version=(5, 0)):
    return vector_transform({"Vector": v}, {"vector_type": kind, "convert_from": a, "convert_to": b},
                            ctx(version, v.shape[1]))["Vector"]


def test_round_trip_and_normals():
    v = np.array([[0.3, -1.0], [2.0, 0.5], [-0.7, 1.5]])
    for kind in ("POINT", "VECTOR"):
        assert np.allclose(vt(vt(v, kind, "OBJECT", "WORLD"), kind, "WORLD", "OBJECT"), v)
    assert np.allclose(vt(v, "POINT", "OBJECT", "WORLD"), M[:3, :3] @ v + M[:3, 3:4])
    tangent, normal = np.array([[1.0], [1.0], [0.0]]), np.array([[1.0], [-1.0], [0.0]]) / np.sqrt(2)
    world_tangent = vt(tangent, "VECTOR", "OBJECT", "WORLD")
    assert abs(float((vt(normal, "NORMAL", "OBJECT", "WORLD") * world_tangent).sum())) < 1e-12
    legacy = vt(normal, "NORMAL", "OBJECT", "WORLD", (3, 4))                 # CONTROL: 3.4's direction
    assert abs(float((legacy * world_tangent).sum())) > 0.1
    assert np.isclose(np.linalg.norm(legacy), 1.0)
    with pytest.raises(Varying):                                             # folding: per hit
        vector_transform({"Vector": v[:, :1]}, {"convert_from": "OBJECT", "convert_to": "WORLD"}, NodeContext(1))


def test_window_of_a_shifted_camera():
    cam = Camera.look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), lens=36.0, sensor_width=36.0)
    on_axis = np.array([[0.0], [0.0], [0.0]])
    assert np.allclose(camera_window(cam, 64, 32)(on_axis)[:, 0], (0.5, 0.5, 0.0))
    cam.shift_x = 0.25
    assert np.allclose(camera_window(cam, 64, 32)(on_axis)[:, 0], (0.25, 0.5, 0.0))
    corner = np.array([[2.5], [1.25], [0.0]])                                 # the frame's top right at distance 5
    cam.shift_x = 0.0
    assert np.allclose(camera_window(cam, 64, 32)(corner)[:, 0], (1.0, 1.0, 0.0))


def test_scene_hits_carry_their_objects_matrix_and_the_camera():
    from engine.geometry.scene_geometry import TRIANGLE
    from engine.nodes.context import SceneAttributes
    from engine.scene.model import Material, Scene, TriangleMesh
    verts = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    mesh = TriangleMesh("Tri", verts @ M[:3, :3].T + M[:3, 3], np.array([[0, 1, 2]]), np.array([0]), object_matrix=M)
    cam = Camera.look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    scene = Scene(cam, [Material("M")], [mesh], [], [])
    attrs = SceneAttributes(scene, scene.meshes[0].vertices[scene.meshes[0].triangles], None)
    c = attrs.context(np.array([TRIANGLE, 0]), np.array([0, 0]), np.array([0.25, 0.0]), np.array([0.5, 0.0]), None,
                      (5, 0), None, TRIANGLE)
    assert np.allclose(c.attr("object_to_world")[0], M[:3]) and np.allclose(c.attr("object_to_world")[1], np.eye(4)[:3])
    assert np.allclose(c.attr("world_to_object")[0], np.linalg.inv(M)[:3])
    assert np.allclose(c.attr("camera_to_world") @ c.attr("world_to_camera"), np.eye(4))
    assert c.attr("window").shape == (3, 2)


def test_the_kernel_is_registered():
    from engine.nodes import registry
    assert registry.supported("ShaderNodeVectorTransform")
