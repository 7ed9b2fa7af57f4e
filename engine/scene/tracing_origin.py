"""The point the tracer measures positions from, so that an image does not depend on where the
scene stands.

Embree traces in float32 and the spawn offsets grow with the size of the coordinates
(engine/geometry/scene_geometry.py TRIANGLE_OFFSET).  A unit room 5e5 units from the world origin
loses its detail there: its vertices round to 1/32 unit and a shadow ray starts half a unit off
the surface, so disks under the balls go black.  The tracer therefore works in coordinates
relative to a tracing origin, subtracted in float64 before anything is rounded to float32:

* the camera's position when the scene stands far from the world origin: the camera farther from
  it than FAR times the scene's extent (the side of the box that holds the camera and every
  primitive and light).  Every position the tracer sees is then within the scene's extent of 0.
* the world origin otherwise: the scene is used as it is (no copy), so the images of scenes near
  the origin are the same bit for bit as without this module.

Only positions move (vertices, centres, corners, light positions, the camera's location);
directions, normals, distances, radiance and texture coordinates are the same in both frames,
and so is every pass the tracer writes (depth is measured from the camera).
"""
from __future__ import annotations

import dataclasses

import numpy as np

FAR = 16.0


def _positions(scene):
    """Every position array of the scene ((N, 3) float64), with the spheres' bounds."""
    yield np.asarray(scene.camera.matrix, dtype=np.float64)[:3, 3].reshape(1, 3)
    for mesh in scene.meshes:
        if len(mesh.vertices):
            yield np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    for sphere in scene.spheres:
        center = np.asarray(sphere.center, dtype=np.float64)
        yield np.stack([center - sphere.radius, center + sphere.radius])
    for quad in scene.quads:
        yield np.asarray(quad.corners, dtype=np.float64).reshape(-1, 3)
    for light in scene.lights:
        yield np.asarray(light.vertices, dtype=np.float64).reshape(-1, 3)
    for point in scene.points:
        yield np.asarray(point.position, dtype=np.float64).reshape(1, 3)


def scene_extent(scene) -> float:
    """The largest side of the box that holds the camera and every primitive and light."""
    # the bounds of each coordinate of each array, then of those (a minimum and a maximum are exact
    # in any order: the box of all points concatenated; one column at a time is 20 times faster
    # than NumPy's min(axis=0) on an (N, 3) array)
    bounds = np.array([[p[:, k].min() for k in range(3)] + [p[:, k].max() for k in range(3)]
                       for p in _positions(scene)])
    return float((bounds[:, 3:].max(axis=0) - bounds[:, :3].min(axis=0)).max())


def tracing_origin(scene) -> np.ndarray | None:
    """The camera's position (3,) when the scene stands far from the world origin, else None
    (trace in world coordinates).  The scene must be valid (Scene.validate)."""
    camera = np.asarray(scene.camera.matrix, dtype=np.float64)[:3, 3]
    if np.abs(camera).max() <= FAR * scene_extent(scene):
        return None
    return camera.copy()


def moved_camera(camera, origin: np.ndarray):
    """The camera with its location relative to `origin`."""
    matrix = np.array(camera.matrix, dtype=np.float64)
    matrix[:3, 3] -= origin
    return dataclasses.replace(camera, matrix=matrix)


def moved(scene, origin: np.ndarray):
    """A copy of the scene with every position relative to `origin` (the scene is not changed;
    what holds no position is shared)."""
    def shifted(a):
        return np.asarray(a, dtype=np.float64) - origin
    return dataclasses.replace(
        scene, camera=moved_camera(scene.camera, origin),
        meshes=[dataclasses.replace(m, vertices=shifted(m.vertices)) for m in scene.meshes],
        spheres=[dataclasses.replace(s, center=tuple(shifted(s.center))) for s in scene.spheres],
        quads=[dataclasses.replace(q, corners=shifted(q.corners)) for q in scene.quads],
        lights=[dataclasses.replace(light, vertices=shifted(light.vertices)) for light in scene.lights],
        points=[dataclasses.replace(p, position=tuple(shifted(p.position))) for p in scene.points])
