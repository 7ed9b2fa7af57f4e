"""Scene files: JSON for the description, an optional NPZ beside it for large arrays.

    {"format": "tncg15-scene", "version": 1, "name": "...", "resolution": [w, h],
     "background": [r, g, b],
     "camera": {"matrix": [[...4x4...]]  or  "look_at": {"position": [...], "target": [...], "up": [...]},
                "lens": 50, "sensor_width": 36, "sensor_height": 24, "sensor_fit": "AUTO",
                "shift_x": 0, "shift_y": 0},
     "materials": [{"name": "White", "kind": "diffuse", "color": [..], "ior": 1.5, "emission": [..]}],
                   (kind "principled": the glossy keys and "principled": {"metallic": 0, "specular_ior_level":
                   0.5, "specular_tint": [1, 1, 1], "coat_weight": 0, "coat_roughness": 0.03, "coat_ior": 1.5,
                   "coat_tint": [1, 1, 1], "sheen_weight": 0, "sheen_roughness": 0.5, "sheen_tint": [1, 1, 1],
                   "alpha": 1, "transmission_weight": 0}, each key optional; Blender 3.x's node instead:
                   "principled_v1": {"metallic": 0, "specular": 0.5, "specular_tint": 0, "sheen": 0,
                   "sheen_tint": 0.5, "clearcoat": 0, "clearcoat_roughness": 0.03, "transmission": 0,
                   "transmission_roughness": 0, "alpha": 1}, each key optional; kind "mix": "mix", the leaves and
                   their weights, engine/scene/mix_fields.py; kinds "glass" and "refraction":
                   "roughness" (default 0, smooth) and "distribution" (ggx, beckmann, multi_ggx); kinds
                   "transparent" and "translucent": the colour only; "sharp_closure": true on a mirror or smooth
                   glass made by Blender 3.x's Sharp distribution, which Filter Glossy leaves sharp)
     "meshes": [{"name": "Floor", "vertices": [[..]] or "@key", "triangles": [[..]] or "@key",
                 "material": "White"  or  "material_ids": [..] or "@key",
                 "normals": [[..] x 3T] or "@key", "smooth": [0/1 x T] or "@key",  (optional)
                 "terminator_offset": 0.1,                                           (optional)
                 "tangents": [[..] x 3T] or "@key"}],   (optional: corner tangents, for materials whose
                 "tangent_source" is "radial" or "uv"; "tangent_uv_map": the UV map's name, "" the active)
     "spheres": [{"name": "Ball", "center": [..], "radius": 0.3, "material": "Glass"}],
     "quads": [{"name": "Light", "corners": [[..] x4], "material": "Light"}],
     "lights": [{"name": "Lamp", "vertices": [[..] x N], "radiance": [r, g, b], "two_sided": false,
                 "visible_camera": false, "visible_diffuse": true, "visible_glossy": true,
                 "visible_transmission": true, "lights_diffuse": true}],
     "points": [{"name": "Bulb", "position": [..], "intensity": [r, g, b], "radius": 0.1,
                 "spot_size": 0.0, "spot_blend": 0.0, "spot_direction": [0, 0, -1],
                 "spot_falloff": "smoothstep"}],
     "suns": [{"name": "Sun", "direction": [..], "irradiance": [r, g, b], "angle": 0.01,
               "sky_disc": true (a Sky Texture's sun disc; absent: false)}],
     "environment": {"name": "World", "texture": "Sky" or 0, "strength": 1.0,          (optional: an image
                     "projection": "equirectangular", "interpolation": "Linear",        world, model.py
                     "matrix": [[..] x 3], "camera_strength": null, "camera_color": null,  Environment)
                     "lighting": true}}

"version" is FORMAT_VERSION (2: Area lights; 3: point, spot and sun lights; 4: image textures,
engine/scene/texture_fields.py; 5: smooth shading, a mesh's "normals": one shading normal per triangle
corner, 3 rows per triangle, "smooth": which triangles use them (all when absent),
"terminator_offset": Cycles' shadow terminator geometry offset); files of a newer version are
refused.  A scene without smooth meshes is written as version 4, which older readers still read.

A value "@key" names an array in the NPZ file with the JSON's name and suffix .npz.
"""
from __future__ import annotations

import json
import os
import stat

import numpy as np

from .model import GLASS, GLOSSY, PRINCIPLED, REFRACTION, AreaLight, Camera, Material, PointLight, Principled, Quad, Scene, Sphere, SunLight, TriangleMesh
from .model import Environment, PrincipledV1
from ..core.errors import SceneError
from .fields import Fields, is_integer
from .mix_fields import mix_json, read_mix
from .programs import programs_json, read_programs
from .texture_fields import input_slots_json, read_input_slots, read_slot, read_textures, slot_json, textures_json

FORMAT = "tncg15-scene"
FORMAT_VERSION = 5
SMOOTH_VERSION = 5                  # the first version with mesh normals; scenes without them: 4
LIGHT_FLAGS = ("two_sided", "visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
               "lights_diffuse")
LAMP_FLAGS = ("lights_diffuse", "visible_glossy", "visible_transmission")     # point, spot and sun lights
SUN_FLAGS = LAMP_FLAGS + ("sky_disc",)
# A scene's JSON holds names and small lists; its arrays go in the NPZ (save_scene).  json.load holds
# about ten times the file's size in memory, so a larger file is refused before it is read.
LARGEST_JSON = 256 * 2**20


def _flags(fields, keys) -> dict:
    """The booleans of `keys` that an entry sets."""
    flags = {}
    for key in keys:
        if key in fields:
            value = fields.get(key)
            if not isinstance(value, bool):
                fields.fail(key, "true or false", value)
            flags[key] = value
    return flags


def _glossy_fields(m) -> dict:
    """The glossy kind's fields of a material entry (engine/scene/model.py Material), each only
    if present: files without them load with the defaults."""
    values = {}
    for key in ("roughness", "anisotropy", "rotation"):
        if key in m:
            values[key] = m.number(key)
    for key in ("tangent", "edge_tint", "conductor_ior", "conductor_k"):
        if key in m:
            values[key] = m.numbers(key, 3)
    for key in ("distribution", "fresnel", "tangent_source", "tangent_uv_map"):
        if key in m:
            values[key] = m.text(key)
    if "multiscatter" in m:
        value = m.get("multiscatter")
        if not isinstance(value, bool):
            m.fail("multiscatter", "true or false", value)
        values["multiscatter"] = value
    if "diffuse_roughness" in m:
        values["diffuse_roughness"] = m.number("diffuse_roughness")
    return values


# The Principled layers' keys (engine/scene/model.py Principled), each optional.
LAYER_KEYS = ("coat_weight", "coat_roughness", "coat_ior", "coat_tint", "sheen_weight", "sheen_roughness",
              "sheen_tint", "alpha", "transmission_weight")


def _principled_fields(m) -> dict:
    """A material entry's "principled" object (engine/scene/model.py Principled), if present;
    each of its keys optional (the node's defaults)."""
    if "principled_v1" in m:                    # Blender 3.x's inputs: {"metallic": 0, "specular": 0.5, ...}
        p, default = Fields(m.get("principled_v1"), f"{m.owner}: principled_v1"), PrincipledV1()
        return {"principled": PrincipledV1(**{key: p.number(key, value) for key, value in vars(default).items()})}
    if "principled" not in m:
        return {}
    p, default = Fields(m.get("principled"), f"{m.owner}: principled"), Principled()
    return {"principled": Principled(metallic=p.number("metallic", default.metallic),
                                     specular_ior_level=p.number("specular_ior_level", default.specular_ior_level),
                                     specular_tint=p.numbers("specular_tint", 3, default.specular_tint),
                                     **{key: p.numbers(key, 3, getattr(default, key)) if key.endswith("_tint")
                                        else p.number(key, getattr(default, key)) for key in LAYER_KEYS})}


def _principled_json(m) -> dict:
    """The "principled" object of material m for the scene file (Principled materials only)."""
    if m.kind != PRINCIPLED:
        return {}
    p = m.principled or Principled()
    if isinstance(p, PrincipledV1):
        return {"principled_v1": dict(vars(p))}
    layers = {key: list(getattr(p, key)) if key.endswith("_tint") else getattr(p, key) for key in LAYER_KEYS
              if np.any(np.asarray(getattr(p, key)) != np.asarray(getattr(Principled(), key)))}  # the layers set only
    return {"principled": {"metallic": p.metallic, "specular_ior_level": p.specular_ior_level,
                           "specular_tint": list(p.specular_tint), **layers}}


def _glossy_json(m) -> dict:
    """The glossy fields of material m for the scene file (glossy and Principled materials only)."""
    if m.kind not in (GLOSSY, PRINCIPLED):
        return {}
    source = {} if m.tangent_source == "fixed" else {"tangent_source": m.tangent_source, "tangent_uv_map": m.tangent_uv_map}
    return {"roughness": m.roughness, "anisotropy": m.anisotropy, "rotation": m.rotation,
            "tangent": list(m.tangent), "distribution": m.distribution, "fresnel": m.fresnel,
            "multiscatter": bool(m.multiscatter), "edge_tint": list(m.edge_tint),
            "conductor_ior": list(m.conductor_ior), "conductor_k": list(m.conductor_k), **source}


def _dielectric_json(m) -> dict:
    """Roughness and distribution of rough glass and refraction materials (smooth ones: nothing, so
    their files stay as they were and load smooth: engine/scene/model.py DEFAULT_ROUGHNESS)."""
    if m.kind not in (GLASS, REFRACTION) or not (m.roughness or m.has_input_texture("roughness")):
        return {}
    return {"roughness": float(m.roughness), "distribution": m.distribution}


def _diffuse_roughness_json(m) -> dict:
    """Only where it is not 0: files of Lambertian materials stay as they were."""
    return {"diffuse_roughness": float(m.diffuse_roughness)} if m.diffuse_roughness else {}


def _object_fields(m, arrays) -> dict:
    """A mesh entry's object data for shader nodes (engine/scene/model.py TriangleMesh.object_matrix ...)."""
    out = {}
    if "object_matrix" in m:
        out["object_matrix"] = np.asarray(m.matrix("object_matrix", 4, 4), dtype=np.float64)
    if "texspace" in m:
        value = m.get("texspace")
        try:
            centre, size = (tuple(float(c) for c in v) for v in value)
        except (TypeError, ValueError):
            m.fail("texspace", "[centre, half size], 3 numbers each", value)
        out["texspace"] = (centre, size)
    if "object_random" in m:
        out["object_random"] = m.number("object_random", 0.0)
    if "colors" in m:
        value = m.get("colors")
        if not isinstance(value, dict):
            m.fail("colors", "an object of attribute name: array", value)
        out["colors"] = {name: np.asarray(arrays[ref[1:]] if isinstance(ref, str) and ref.startswith("@") and
                                          ref[1:] in arrays else ref, dtype=np.float64).reshape(-1, 3, 3)
                         for name, ref in value.items()}
    return out


def _object_json(mesh, i, arrays) -> dict:
    out = {}
    if mesh.object_matrix is not None:
        out["object_matrix"] = np.asarray(mesh.object_matrix, dtype=np.float64).tolist()
    if mesh.texspace is not None:
        out["texspace"] = [[float(c) for c in v] for v in mesh.texspace]
    if mesh.object_random:
        out["object_random"] = float(mesh.object_random)
    if mesh.colors:
        out["colors"] = {}
        for k, (name, c) in enumerate(sorted(mesh.colors.items())):
            arrays[f"mesh{i}_color{k}"] = np.asarray(c, dtype=np.float64).reshape(-1, 3)
            out["colors"][name] = f"@mesh{i}_color{k}"
    return out


def _material_index(fields, names):
    ref = fields.get("material", 0)
    if is_integer(ref):
        if not 0 <= ref < len(names):
            raise SceneError(f"{fields.owner}: material index {ref} out of range")
        return int(ref)
    if not isinstance(ref, str):
        fields.fail("material", "a material name or index", ref)
    if ref not in names:
        raise SceneError(f"{fields.owner}: unknown material '{ref}'")
    return names.index(ref)


def _regular_file(path: str, what: str, largest: int | None = None) -> None:
    """SceneError unless `path` is a regular file (not /dev/zero, a FIFO or a directory, which read
    forever or fail oddly) of at most `largest` bytes."""
    try:
        info = os.stat(path)
    except OSError as exc:
        raise SceneError(f"cannot read {what} '{path}': {exc.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise SceneError(f"{what} '{path}' is not a regular file")
    if largest is not None and info.st_size > largest:
        raise SceneError(f"{what} '{path}' is {info.st_size / 2**20:,.0f} MiB: a scene file is at most "
                         f"{largest // 2**20} MiB (large arrays go in the NPZ beside it)")


def _read_json(path: str):
    _regular_file(path, "scene", LARGEST_JSON)
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except OSError as exc:
        raise SceneError(f"cannot read scene '{path}': {exc.strerror}") from None
    except UnicodeDecodeError:
        raise SceneError(f"scene '{path}' is not a text (JSON) file") from None
    except json.JSONDecodeError as exc:
        raise SceneError(f"scene '{path}' is not valid JSON: {exc}") from None
    except ValueError as exc:                  # an integer of more than 4300 digits (int_max_str_digits)
        reason = str(exc).split(":")[0]
        raise SceneError(f"scene '{path}' holds a number too long to be a scene value ({reason})") from None
    except RecursionError:
        raise SceneError(f"scene '{path}' is nested too deeply to be a scene file") from None


def _read_npz(path: str) -> dict:
    """Every array of the NPZ beside the scene, read now so a corrupt file is one clear error."""
    if not os.path.exists(path):
        return {}
    _regular_file(path, "arrays")
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {name: np.asarray(npz[name]) for name in npz.files}
    except Exception as exc:                       # noqa: BLE001 - zip, zlib, format and pickle errors
        raise SceneError(f"cannot read arrays '{path}': {type(exc).__name__}: {exc}") from None


def _camera(entry) -> Camera:
    fields, name = _named(entry, "Camera", "Camera")
    optics = {"name": name}
    for key in ("lens", "sensor_width", "sensor_height", "shift_x", "shift_y"):
        if key in fields:
            optics[key] = fields.number(key)
    if "sensor_fit" in fields:
        optics["sensor_fit"] = fields.text("sensor_fit")
    if "look_at" in fields:
        la = Fields(fields.get("look_at"), f"{fields.owner}: look_at")
        return Camera.look_at(la.numbers("position", 3), la.numbers("target", 3),
                              la.numbers("up", 3, (0.0, 0.0, 1.0)), **optics)
    return Camera(matrix=fields.matrix("matrix", 4, 4), **optics)


def _named(entry, kind: str, default: str, required: bool = False):
    """Fields of one list entry, named in messages by its "name" ("Object 'Floor'")."""
    fields = Fields(entry, f"{kind} {default}" if required else f"{kind} '{default}'")
    name = fields.text("name") if required else fields.text("name", default)
    fields.owner = f"{kind} '{name}'"
    return fields, name


def load_scene(path: str) -> Scene:
    data = _read_json(path)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise SceneError(f"scene '{path}' is not a {FORMAT} file (missing \"format\": \"{FORMAT}\")")
    top = Fields(data, f"Scene '{os.path.basename(path)}'")
    version = top.get("version", 1)
    if not (isinstance(version, int) and 1 <= version <= FORMAT_VERSION):
        raise SceneError(f"scene '{path}' has format version {version!r}; this engine reads 1 to {FORMAT_VERSION}")
    name = top.text("name", os.path.basename(path))
    top.owner = f"Scene '{name}'"
    arrays = _read_npz(os.path.splitext(path)[0] + ".npz")

    textures = read_textures(top, arrays, os.path.dirname(os.path.abspath(path)))
    materials = []

    def material(m, material_name):
        return Material(name=material_name, kind=m.text("kind", "diffuse"),
                        color=m.numbers("color", 3, (0.8, 0.8, 0.8)), ior=m.number("ior", 1.5),
                        emission=m.numbers("emission", 3, (0.0, 0.0, 0.0)),
                        color_texture=read_slot(m, "color_texture", textures),
                        emission_texture=read_slot(m, "emission_texture", textures),
                        input_textures=read_input_slots(m, textures),
                        mix=read_mix(m, textures, material), programs=read_programs(m),
                        **_glossy_fields(m), **_principled_fields(m), **_flags(m, ("sharp_closure",)))
    for i, entry in enumerate(top.objects("materials")):
        m, material_name = _named(entry, "Material", f"#{i}", required=True)
        materials.append(material(m, material_name))
    names = [m.name for m in materials]
    cam = top.get("camera", None)
    camera = None if cam is None else _camera(cam)
    meshes = []
    for i, entry in enumerate(top.objects("meshes")):
        m, mesh_name = _named(entry, "Object", f"mesh{i}")
        tris = m.array("triangles", arrays, 3, integer=True)
        ids = (m.array("material_ids", arrays, None, integer=True) if "material_ids" in m
               else np.full(len(tris), _material_index(m, names)))
        uvs = m.array("uvs", arrays, 2, integer=False) if "uvs" in m else None
        normals = m.array("normals", arrays, 3, integer=False) if "normals" in m else None
        smooth = m.array("smooth", arrays, None, integer=True) if "smooth" in m else None
        tangents = m.array("tangents", arrays, 3, integer=False) if "tangents" in m else None
        signs = m.array("tangent_signs", arrays, None, integer=False) if "tangent_signs" in m else None
        if smooth is not None and ((smooth < 0) | (smooth > 1)).any():
            m.fail("smooth", "a list of 0 (flat) or 1 (smooth) per triangle", smooth.tolist())
        meshes.append(TriangleMesh(mesh_name, m.array("vertices", arrays, 3, integer=False), tris, ids, uvs,
                                   normals=normals, smooth=None if smooth is None else smooth.astype(bool),
                                   terminator_offset=m.number("terminator_offset", 0.1), tangents=tangents,
                                   tangent_signs=signs,
                                   **_object_fields(m, arrays)))
    spheres = []
    for i, entry in enumerate(top.objects("spheres")):
        s, sphere_name = _named(entry, "Object", f"sphere{i}")
        spheres.append(Sphere(sphere_name, s.numbers("center", 3), s.number("radius"), _material_index(s, names)))
    quads = []
    for i, entry in enumerate(top.objects("quads")):
        q, quad_name = _named(entry, "Object", f"quad{i}")
        quads.append(Quad(quad_name, q.matrix("corners", 4, 3), _material_index(q, names)))
    lights = []
    for i, entry in enumerate(top.objects("lights")):
        f, light_name = _named(entry, "Light", f"light{i}")
        lights.append(AreaLight(light_name, f.array("vertices", arrays, 3, integer=False),
                                f.numbers("radiance", 3), **_flags(f, LIGHT_FLAGS)))
    points = []
    for i, entry in enumerate(top.objects("points")):
        f, light_name = _named(entry, "Light", f"point{i}")
        points.append(PointLight(light_name, f.numbers("position", 3), f.numbers("intensity", 3),
                                 f.number("radius", 0.0), spot_size=f.number("spot_size", 0.0),
                                 spot_blend=f.number("spot_blend", 0.0),
                                 spot_direction=f.numbers("spot_direction", 3, (0.0, 0.0, -1.0)),
                                 spot_falloff=f.text("spot_falloff", "smoothstep"), **_flags(f, LAMP_FLAGS)))
    suns = []
    for i, entry in enumerate(top.objects("suns")):
        f, light_name = _named(entry, "Light", f"sun{i}")
        suns.append(SunLight(light_name, f.numbers("direction", 3), f.numbers("irradiance", 3),
                             f.number("angle", 0.0), **_flags(f, SUN_FLAGS)))
    return Scene(camera, materials, meshes, spheres, quads,
                 background=top.numbers("background", 3, (0.0, 0.0, 0.0)), environment=_environment(top, textures),
                 resolution=top.integers("resolution", 2, (256, 256)), name=name, lights=lights,
                 points=points, suns=suns, textures=textures,
                 cycles_version=tuple(top.integers("cycles_version", 2, (5, 0))))


def _environment(top: Fields, textures: list):
    """The scene's Environment (engine/scene/model.py), or None without an "environment" entry."""
    if top.get("environment", None) is None:
        return None
    f = Fields(top.get("environment"), f"{top.owner}: environment")
    ref, names = f.get("texture"), [t.name for t in textures]
    index = int(ref) if is_integer(ref) else names.index(ref) if ref in names else None
    if index is None:
        raise SceneError(f"{f.owner}: unknown texture {ref!r}")
    camera_color = f.get("camera_color", None)
    camera_strength = f.get("camera_strength", None)
    lighting = f.get("lighting", True)
    if not isinstance(lighting, bool):
        f.fail("lighting", "true or false", lighting)
    return Environment(index, strength=f.number("strength", 1.0), projection=f.text("projection", "equirectangular"),
                       interpolation=f.text("interpolation", "Linear"),
                       matrix=tuple(map(tuple, f.matrix("matrix", 3, 3, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).tolist())),
                       camera_strength=None if camera_strength is None else f.number("camera_strength"),
                       camera_color=None if camera_color is None else f.numbers("camera_color", 3),
                       lighting=lighting, name=f.text("name", "World"))


def _environment_json(env) -> dict:
    if env is None:
        return {}
    return {"environment": {"name": env.name, "texture": int(env.texture), "strength": float(env.strength),
                            "projection": env.projection, "interpolation": env.interpolation,
                            "matrix": np.asarray(env.matrix, dtype=np.float64).tolist(),
                            "camera_strength": None if env.camera_strength is None else float(env.camera_strength),
                            "camera_color": None if env.camera_color is None else [float(c) for c in env.camera_color],
                            "lighting": bool(env.lighting)}}


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
        if mesh.uvs is not None:
            arrays[f"mesh{i}_uvs"] = np.asarray(mesh.uvs, dtype=np.float64).reshape(-1, 2)
            meshes[-1]["uvs"] = f"@mesh{i}_uvs"
        if mesh.tangents is not None:
            arrays[f"mesh{i}_tangents"] = np.asarray(mesh.tangents, dtype=np.float64).reshape(-1, 3)
            meshes[-1]["tangents"] = f"@mesh{i}_tangents"
        if mesh.tangent_signs is not None:
            arrays[f"mesh{i}_tangent_signs"] = np.asarray(mesh.tangent_signs, dtype=np.float64).reshape(-1)
            meshes[-1]["tangent_signs"] = f"@mesh{i}_tangent_signs"
        meshes[-1].update(_object_json(mesh, i, arrays))
        if mesh.normals is not None:
            arrays[f"mesh{i}_normals"] = np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3)
            meshes[-1]["normals"] = f"@mesh{i}_normals"
            meshes[-1]["terminator_offset"] = float(mesh.terminator_offset)
            if mesh.smooth is not None:
                arrays[f"mesh{i}_smooth"] = np.asarray(mesh.smooth, dtype=np.int8)
                meshes[-1]["smooth"] = f"@mesh{i}_smooth"
    cam = scene.camera

    def material_json(m):
        return dict({"name": m.name, "kind": m.kind, "color": list(m.color), "ior": m.ior,
                     "emission": list(m.emission)}, **_glossy_json(m), **_principled_json(m), **_diffuse_roughness_json(m),
                    **_dielectric_json(m),
                    **{key: slot_json(slot) for key, slot in (("color_texture", m.color_texture),
                                                              ("emission_texture", m.emission_texture))
                       if slot is not None}, **input_slots_json(m), **mix_json(m, material_json),
                    **programs_json(m), **({"sharp_closure": True} if m.sharp_closure else {}))
    data = {
        "format": FORMAT, "name": scene.name,
        "version": SMOOTH_VERSION if any(m.normals is not None for m in scene.meshes) else SMOOTH_VERSION - 1,
        "resolution": list(scene.resolution), "background": list(scene.background),
        "cycles_version": [int(v) for v in scene.cycles_version],
        "camera": None if cam is None else {
            "name": cam.name, "matrix": np.asarray(cam.matrix).tolist(), "lens": cam.lens,
            "sensor_width": cam.sensor_width, "sensor_height": cam.sensor_height,
            "sensor_fit": cam.sensor_fit, "shift_x": cam.shift_x, "shift_y": cam.shift_y},
        "textures": textures_json(scene, arrays),
        "materials": [material_json(m) for m in scene.materials],
        "meshes": meshes,
        "spheres": [{"name": s.name, "center": list(s.center), "radius": s.radius,
                     "material": s.material_id} for s in scene.spheres],
        "quads": [{"name": q.name, "corners": np.asarray(q.corners).tolist(), "material": q.material_id}
                  for q in scene.quads],
        "lights": [dict({"name": light.name, "vertices": np.asarray(light.vertices).tolist(),
                         "radiance": [float(c) for c in light.radiance]},
                        **{key: bool(getattr(light, key)) for key in LIGHT_FLAGS}) for light in scene.lights],
        "points": [{"name": p.name, "position": [float(v) for v in p.position],
                    "intensity": [float(v) for v in p.intensity], "radius": float(p.radius),
                    "spot_size": float(p.spot_size), "spot_blend": float(p.spot_blend),
                    "spot_direction": [float(v) for v in p.spot_direction], "spot_falloff": p.spot_falloff,
                    **{key: bool(getattr(p, key)) for key in LAMP_FLAGS}} for p in scene.points],
        "suns": [{"name": sun.name, "direction": [float(v) for v in sun.direction],
                  "irradiance": [float(v) for v in sun.irradiance], "angle": float(sun.angle),
                  **{key: bool(getattr(sun, key)) for key in LAMP_FLAGS},
                  **({"sky_disc": True} if getattr(sun, "sky_disc", False) else {})} for sun in scene.suns],
        **_environment_json(getattr(scene, "environment", None)),
    }
    with open(path, "w") as fh:
        json.dump(data, fh, indent=1)
    if arrays:
        np.savez_compressed(os.path.splitext(path)[0] + ".npz", **arrays)
