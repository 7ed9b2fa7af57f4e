"""Scene files: JSON for the description, an optional NPZ beside it for large arrays.

    {"format": "tncg15-scene", "version": 1, "name": "...", "resolution": [w, h],
     "background": [r, g, b],
     "camera": {"matrix": [[...4x4...]]  or  "look_at": {"position": [...], "target": [...], "up": [...]},
                "lens": 50, "sensor_width": 36, "sensor_height": 24, "sensor_fit": "AUTO",
                "shift_x": 0, "shift_y": 0},
     "materials": [{"name": "White", "kind": "diffuse", "color": [..], "ior": 1.5, "emission": [..]}],
     "meshes": [{"name": "Floor", "vertices": [[..]] or "@key", "triangles": [[..]] or "@key",
                 "material": "White"  or  "material_ids": [..] or "@key"}],
     "spheres": [{"name": "Ball", "center": [..], "radius": 0.3, "material": "Glass"}],
     "quads": [{"name": "Light", "corners": [[..] x4], "material": "Light"}]}

A value "@key" names an array in the NPZ file with the JSON's name and suffix .npz.
"""
from __future__ import annotations

import json
import os

import numpy as np

from .scene import Camera, Material, Quad, Scene, SceneError, Sphere, TriangleMesh

FORMAT = "tncg15-scene"


def _material_index(entry, names, owner):
    ref = entry.get("material", 0)
    if isinstance(ref, int):
        if not 0 <= ref < len(names):
            raise SceneError(f"Object '{owner}': material index {ref} out of range")
        return ref
    if ref not in names:
        raise SceneError(f"Object '{owner}': unknown material '{ref}'")
    return names.index(ref)


def load_scene(path: str) -> Scene:
    try:
        with open(path) as fh:
            data = json.load(fh)
    except OSError as exc:
        raise SceneError(f"cannot read scene '{path}': {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise SceneError(f"scene '{path}' is not valid JSON: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise SceneError(f"scene '{path}' is not a {FORMAT} file (missing \"format\": \"{FORMAT}\")")
    npz_path = os.path.splitext(path)[0] + ".npz"
    arrays = np.load(npz_path) if os.path.exists(npz_path) else {}

    def array(value, owner, label):
        if isinstance(value, str) and value.startswith("@"):
            if value[1:] not in arrays:
                raise SceneError(f"Object '{owner}': array '{value[1:]}' not found in {npz_path}")
            return np.asarray(arrays[value[1:]])
        return np.asarray(value)

    try:
        materials = [Material(name=m["name"], kind=m.get("kind", "diffuse"),
                              color=tuple(m.get("color", (0.8, 0.8, 0.8))),
                              ior=float(m.get("ior", 1.5)),
                              emission=tuple(m.get("emission", (0.0, 0.0, 0.0))))
                     for m in data.get("materials", [])]
        names = [m.name for m in materials]
        cam = data.get("camera")
        camera = None
        if cam is not None:
            optics = {k: cam[k] for k in ("lens", "sensor_width", "sensor_height", "sensor_fit",
                                          "shift_x", "shift_y", "name") if k in cam}
            if "look_at" in cam:
                la = cam["look_at"]
                camera = Camera.look_at(la["position"], la["target"], la.get("up", (0, 0, 1)), **optics)
            else:
                camera = Camera(matrix=np.asarray(cam["matrix"], dtype=np.float64), **optics)
        meshes = []
        for m in data.get("meshes", []):
            name = m.get("name", f"mesh{len(meshes)}")
            tris = array(m["triangles"], name, "triangles")
            if "material_ids" in m:
                ids = array(m["material_ids"], name, "material_ids")
            else:
                ids = np.full(len(tris), _material_index(m, names, name))
            meshes.append(TriangleMesh(name, array(m["vertices"], name, "vertices"), tris, ids))
        spheres = [Sphere(s.get("name", f"sphere{i}"), tuple(s["center"]), float(s["radius"]),
                          _material_index(s, names, s.get("name", f"sphere{i}")))
                   for i, s in enumerate(data.get("spheres", []))]
        quads = [Quad(q.get("name", f"quad{i}"), np.asarray(q["corners"], dtype=np.float64),
                      _material_index(q, names, q.get("name", f"quad{i}")))
                 for i, q in enumerate(data.get("quads", []))]
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, SceneError):
            raise
        raise SceneError(f"scene '{path}': malformed entry ({type(exc).__name__}: {exc})") from None
    return Scene(camera, materials, meshes, spheres, quads,
                 background=tuple(data.get("background", (0.0, 0.0, 0.0))),
                 resolution=tuple(data.get("resolution", (256, 256))),
                 name=data.get("name", os.path.basename(path)))


def save_scene(scene: Scene, path: str) -> None:
    """Write JSON plus an NPZ with the mesh arrays."""
    arrays = {}
    meshes = []
    for i, mesh in enumerate(scene.meshes):
        arrays[f"mesh{i}_vertices"] = np.asarray(mesh.vertices, dtype=np.float64)
        arrays[f"mesh{i}_triangles"] = np.asarray(mesh.triangles, dtype=np.int64)
        arrays[f"mesh{i}_material_ids"] = np.asarray(mesh.material_ids, dtype=np.int64)
        meshes.append({"name": mesh.name, "vertices": f"@mesh{i}_vertices",
                       "triangles": f"@mesh{i}_triangles", "material_ids": f"@mesh{i}_material_ids"})
    cam = scene.camera
    data = {
        "format": FORMAT, "version": 1, "name": scene.name,
        "resolution": list(scene.resolution), "background": list(scene.background),
        "camera": None if cam is None else {
            "name": cam.name, "matrix": np.asarray(cam.matrix).tolist(), "lens": cam.lens,
            "sensor_width": cam.sensor_width, "sensor_height": cam.sensor_height,
            "sensor_fit": cam.sensor_fit, "shift_x": cam.shift_x, "shift_y": cam.shift_y},
        "materials": [{"name": m.name, "kind": m.kind, "color": list(m.color), "ior": m.ior,
                       "emission": list(m.emission)} for m in scene.materials],
        "meshes": meshes,
        "spheres": [{"name": s.name, "center": list(s.center), "radius": s.radius,
                     "material": s.material_id} for s in scene.spheres],
        "quads": [{"name": q.name, "corners": np.asarray(q.corners).tolist(), "material": q.material_id}
                  for q in scene.quads],
    }
    with open(path, "w") as fh:
        json.dump(data, fh, indent=1)
    if arrays:
        np.savez_compressed(os.path.splitext(path)[0] + ".npz", **arrays)
