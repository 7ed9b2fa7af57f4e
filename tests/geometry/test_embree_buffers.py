"""engine/geometry/accel/embree_buffers.py: triangles written into Embree's buffers as arrays give
an Embree scene that answers every ray exactly as embreex's TriangleMesh of the same triangles."""
import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from engine.geometry.accel import embree_buffers


def answers(triangles, attach, origins, directions):
    scene = rtcore_scene.EmbreeScene(robust=True)
    attach(scene, triangles)
    return scene.run(origins, directions, dists=np.full(len(origins), 1e30, np.float32), output=1)


def same(a, b):
    return all(np.array_equal(a[k], b[k]) for k in a)


def test_attached_triangles_answer_every_ray_as_triangle_mesh():
    assert embree_buffers.available(), "this embreex's layout or library was not recognised: TriangleMesh runs"
    rng = np.random.default_rng(3)
    centres = rng.uniform(-1, 1, (3000, 1, 3))
    triangles = (centres + rng.normal(0, 0.08, (3000, 3, 3))).astype(np.float32)
    origins = rng.uniform(-2, 2, (20000, 3)).astype(np.float32)
    directions = rng.normal(0, 1, (20000, 3)).astype(np.float32)
    theirs = answers(triangles, TriangleMesh, origins, directions)
    ours = answers(triangles, embree_buffers.attach_triangles, origins, directions)
    assert (theirs["primID"] >= 0).sum() > 1000
    assert same(ours, theirs)
    # control: the corners in another order (the same surfaces) give other barycentrics and normals
    rotated = np.ascontiguousarray(triangles[:, [1, 2, 0]])
    assert not same(answers(rotated, embree_buffers.attach_triangles, origins, directions), theirs)
