"""Vector Transform (engine/nodes/vector_transform.py) and Texture Coordinate Window
(engine/nodes/context.py camera_window) against Cycles, pixel by pixel, on the flat quad of
tests/nodes/flat_quad.py moved, tilted and scaled unevenly under a turned camera: every Point /
Vector / Normal conversion between World, Object and Camera (5.0, and 3.4 whose normals are
directions), of the hit's position (read back from a Geometry Position AOV, so the comparison is at
Cycles' own points); Window under a perspective and an orthographic camera, both shifted.
CONTROLS: the object matrix transposed; the other Blender's normals; Window without the camera's shift."""
import types

import numpy as np
import pytest

from engine.nodes.inputs import euler_matrix
from engine.nodes.vector_transform import KERNELS
from tests.nodes import flat_quad

pytestmark = pytest.mark.slow
RES = 32
SPACES = ("WORLD", "OBJECT", "CAMERA")
KINDS = ("POINT", "VECTOR", "NORMAL")
PLANE = {"location": (0.1, -0.2, -0.3), "rotation_euler": (0.3, -0.2, 0.5), "scale": (3.0, 2.5, 1.0)}
CAMERA_OBJECT = {"location": (0.0, 0.0, 2.0), "rotation_euler": (0.0, 0.0, 0.4), "scale": (1.3, 0.8, 1.1)}


def cases():
    return [(k, a, b) for k in KINDS for a in SPACES for b in SPACES]


def build_transforms(nodes, links, coord):
    geo = nodes.new("ShaderNodeNewGeometry")
    result = {"P": geo.outputs["Position"]}
    for i, (kind, a, b) in enumerate(cases()):
        node = nodes.new("ShaderNodeVectorTransform")
        node.vector_type, node.convert_from, node.convert_to = kind, a, b
        links.new(geo.outputs["Position"], node.inputs["Vector"])
        flat_quad.keep(f"c{i}", node)
        result[f"c{i}"] = node.outputs["Vector"]
    return result


def build_window(nodes, links, coord):
    geo = nodes.new("ShaderNodeNewGeometry")
    tc = nodes.new("ShaderNodeTexCoord")
    return {"P": geo.outputs["Position"], "W": tc.outputs["Window"]}


def matrix(location, rotation_euler, scale=(1.0, 1.0, 1.0)):
    m = np.eye(4)
    m[:3, :3] = euler_matrix(np.asarray(rotation_euler, dtype=np.float64)) * np.asarray(scale, dtype=np.float64)
    m[:3, 3] = location
    return m


def context(n, version, object_matrix):
    from engine.nodes.context import NodeContext, camera_to_world
    cam = camera_to_world(types.SimpleNamespace(matrix=matrix(**CAMERA_OBJECT)))      # its scale cleared
    to_camera = np.linalg.inv(cam)
    return NodeContext(n, version, {"object_to_world": np.tile(object_matrix[:3], (n, 1, 1)),
                                    "world_to_object": np.tile(np.linalg.inv(object_matrix)[:3], (n, 1, 1)),
                                    "world_to_camera": to_camera, "camera_to_world": cam})


def transform_errors(images, kept, version, object_matrix):
    p = images["P"].reshape(-1, 3).T
    ctx = context(p.shape[1], version, object_matrix)
    worst = {}
    for i, case in enumerate(cases()):
        ours = KERNELS["ShaderNodeVectorTransform"]({"Vector": p}, kept[f"c{i}"]["props"], ctx)["Vector"]
        theirs = images[f"c{i}"].reshape(-1, 3).T
        worst[case] = float((np.abs(ours - theirs) / np.maximum(1.0, np.abs(theirs))).max())
    return worst


@pytest.mark.parametrize("blender, version", [("5.0", (5, 0)), ("3.4", (3, 4))])
def test_vector_transform_agrees_with_cycles(blender, version):
    images, _, kept = flat_quad.render(build_transforms, resolution=RES, blender=blender, kept=True,
                                       view={"plane": PLANE, "camera_object": CAMERA_OBJECT})
    m = matrix(**PLANE)
    worst = transform_errors(images, kept, version, m)
    print(f"Vector Transform {blender}: worst relative error {max(worst.values()):.2e}")
    assert max(worst.values()) < 2e-5, {k: v for k, v in worst.items() if v >= 2e-5}
    changed = [c for c in cases() if c[1] != c[2] and np.abs(images[f"c{cases().index(c)}"] - images["P"]).max() > 0.1]
    assert len(changed) == 18, changed                     # every conversion between spaces does something
    # CONTROL: the object matrix transposed (its 3x3 part) -> every conversion through Object fails
    t = m.copy()
    t[:3, :3] = m[:3, :3].T
    bad = transform_errors(images, kept, version, t)
    through_object = [c for c in cases() if "OBJECT" in c[1:] and c[1] != c[2]]
    assert min(bad[c] for c in through_object) > 1e-2, bad
    # CONTROL: the other version's normals (3.4: directions, normalised once; 5.0: inverse transposes)
    other = transform_errors(images, kept, (3, 4) if version >= (4, 0) else (5, 0), m)
    normals = [c for c in cases() if c[0] == "NORMAL" and "OBJECT" in c[1:] and c[1] != c[2]]
    assert min(other[c] for c in normals) > 1e-2, {c: other[c] for c in normals}


def window_camera(view):
    cam = view["camera"]
    return types.SimpleNamespace(matrix=matrix(**view["camera_object"]), lens=cam.get("lens", 50.0),
                                 sensor_width=36.0, sensor_height=24.0, sensor_fit="AUTO",
                                 shift_x=cam["shift_x"], shift_y=cam["shift_y"], type=cam.get("type", "PERSP"),
                                 ortho_scale=cam.get("ortho_scale", 6.0))


VIEWS = {"perspective": {"camera": {"type": "PERSP", "lens": 36.0, "shift_x": 0.2, "shift_y": -0.1},
                         "camera_object": {"location": (0.0, 0.0, 1.0), "rotation_euler": (0.0, 0.0, 0.3)}},
         "orthographic": {"camera": {"type": "ORTHO", "ortho_scale": 1.5, "shift_x": 0.1, "shift_y": -0.15},
                          "camera_object": {"location": (0.0, 0.0, 1.0), "rotation_euler": (0.0, 0.0, 0.3)},
                          "plane": {"scale": (2.0, 2.0, 1.0)}}}


@pytest.mark.parametrize("name", sorted(VIEWS))
def test_window_agrees_with_cycles(name):
    from engine.nodes.context import camera_window
    view = VIEWS[name]
    images, _ = flat_quad.render(build_window, resolution=RES, view=view)
    p = images["P"].reshape(-1, 3).T
    theirs = images["W"].reshape(-1, 3).T
    camera = window_camera(view)
    ours = camera_window(camera, RES, RES)(p)
    err = float(np.abs(ours - theirs).max())
    print(f"Window {name}: max abs error {err:.2e}")
    assert err < 1e-5
    assert np.ptp(theirs[0]) > 0.9 and np.ptp(theirs[1]) > 0.9
    # CONTROL: the shift left out
    unshifted = camera_window(types.SimpleNamespace(**{**vars(camera), "shift_x": 0.0, "shift_y": 0.0}), RES, RES)(p)
    assert np.abs(unshifted - theirs).max() > 0.05
