"""Render a shader-node setup with Cycles on a flat quad seen head-on, for per-pixel kernel tests.

A plane spanning object coordinates [-1, 1]^2 at z = 0 (identity transform) fills the view of an
orthographic camera looking down -Z.  The caller's nodes get, as their coordinate, the Texture
Coordinate node's Object output SNAPPED to the pixel centre (Vector Math Snap + Multiply + Add), so
every pixel is the node's value at exactly the point `coordinates(resolution)` returns, whatever
Cycles' sub-pixel jitter (1 spp, box filter of width 0.01 px anyway).  The resolution must be a
power of two, so that the pixel centres are exact in float32 as in float64.

    def build(nodes, links, coord):                 # coord: a Vector output socket
        math = nodes.new("ShaderNodeMath"); math.operation = "SINE"
        links.new(coord, math.inputs[0])            # (a vector into a float socket: its average)
        return math.outputs[0]                      # -> Emission (strength 1) -> Material Output
    image, points = render(build)                   # (H, W, 3) float64, (3, H*W) object coordinates

`build` may instead return {name: socket}: each socket goes to a Shader AOV Output (colour AOV
`name`) so that one render checks many nodes; `render` then returns ({name: (H, W, 3)}, points).
A float socket reaches the emission / the AOV as (f, f, f), a vector as its (x, y, z).

Raw float pixels: a 32-bit EXR (linear, no view transform is applied to EXR files; the scene's view
transform is Standard anyway), no denoising, no clamping, bounces 0.

A kernel test needs the node's props as the exporter captures them: `keep(key, node)` in `build`
stores {"props": capture_props(node) (its plain enum / bool / number properties and
mcrt_addon/export/node_props.py special_props), "inputs": its enabled input sockets' default values}, and
`render(..., kept=True)` returns them as a third value {key: ...}, from either Blender.

`render(..., view={"plane": {...}, "camera": {...}, "camera_object": {...}})` sets attributes of the
plane object (location, rotation_euler, scale), of the camera data (type, lens, shift_x, ortho_scale,
...) and of the camera object (location, rotation_euler) before rendering: the Object coordinate is
then no longer the pixel centre (read Geometry Position into an AOV instead).

Blender 3.4: `render(build, blender="3.4")` runs Debian's `/usr/bin/blender -b` on this file (it
is also a Blender script); `build` must then be a module-level function of an importable module
(it is imported by module name and qualified name in Blender's Python, whose PYTHONPATH is the
repository and this venv's site-packages) and its extra keyword arguments JSON data.
"""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
BLENDER34 = os.environ.get("BLENDER_BIN") or shutil.which("blender") or "/usr/bin/blender"
RESOLUTION = 32
KEPT = {}                      # keep(): props captured while `build` runs


def coordinates(resolution=RESOLUTION, z=0.0):
    """Object coordinates (3, H*W) of the pixel centres, pixels in image order (top row first)."""
    w = int(resolution)
    centres = -1.0 + (2.0 * np.arange(w) + 1.0) / w
    x = np.tile(centres, w)
    y = np.repeat(centres[::-1], w)
    return np.stack([x, y, np.full(w * w, float(z))])


def render(build, resolution=RESOLUTION, blender="5.0", z=0.0, kept=False, view=None, **kwargs):
    """Cycles' image of `build`'s output(s) and the object coordinates of the pixel centres (and the
    props `keep` stored, with kept=True).

    `kwargs` are passed on to `build(nodes, links, coord, **kwargs)`; `z` is the coordinate's z."""
    _check_resolution(resolution)
    with tempfile.TemporaryDirectory(dir=os.environ.get("FLAT_QUAD_KEEP")) as tmp:
        path = os.path.join(tmp, "flat_quad.exr")
        if blender == "5.0":
            names = render_in_process(build, path, resolution, z, kwargs, view)
        elif blender == "3.4":
            names = _render_blender34(build, path, resolution, z, kwargs, view)
        else:
            raise ValueError(f"blender must be '5.0' or '3.4', not {blender!r}")
        images = read_layers(path, names)
        if blender == "3.4":
            with open(path + ".json") as f:
                props = json.load(f)["kept"]
        else:
            props = json.loads(json.dumps(KEPT))           # as plain as a scene file keeps them
    points = coordinates(resolution, z)
    return (images, points, props) if kept else (images, points)


def keep(key, node):
    """Store {"props": capture_props(node), "inputs": {identifier: default value}} (the defaults of its
    enabled input sockets, as the exporter gives a kernel: a float, or 3 floats for a colour / vector)
    under `key` for render(..., kept=True).  Call it after setting the node's properties."""
    defaults = {}
    for sock in node.inputs:
        if not getattr(sock, "enabled", True):         # as the exporter: a hidden socket is left out
            continue
        value = getattr(sock, "default_value", None)
        if value is None:
            continue
        defaults[sock.identifier] = float(value) if isinstance(value, (int, float)) else [float(v) for v in value][:3]
    KEPT[key] = {"props": capture_props(node), "inputs": defaults}
    return node


def capture_props(node):
    """The node's props as the exporter gives them to the kernels: special_props (Color Ramp, curves)
    and its own plain enum / bool / int / float properties."""
    import bpy

    from mcrt_addon.export.node_props import special_props
    props = dict(special_props(node) or {})
    base = {p.identifier for p in bpy.types.ShaderNode.bl_rna.properties} | {"rna_type"}
    for prop in node.bl_rna.properties:
        if prop.identifier in base or prop.identifier in props:
            continue
        if prop.type in ("ENUM", "BOOLEAN", "INT", "FLOAT") and not getattr(prop, "array_length", 0) \
                and not getattr(prop, "is_enum_flag", False):
            props[prop.identifier] = getattr(node, prop.identifier)
    return props


def _check_resolution(resolution):
    r = int(resolution)
    if r < 2 or r & (r - 1):
        raise ValueError(f"the flat-quad resolution must be a power of two (exact pixel centres), not {r}")


def _render_blender34(build, path, resolution, z, kwargs, view=None):
    if "<locals>" in build.__qualname__ or build.__module__ == "__main__":
        raise ValueError("a Blender 3.4 build must be a module-level function of an importable module")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([REPO, sysconfig.get_paths()["purelib"]] + env.get("PYTHONPATH", "").split(os.pathsep))
    args = [BLENDER34, "-b", "--factory-startup", "--python-use-system-env", "--python", os.path.abspath(__file__),
            "--", "--module", build.__module__, "--function", build.__qualname__,
            "--kwargs", json.dumps(kwargs), "--resolution", str(int(resolution)), "--z", repr(float(z)),
            "--out", path, "--view", json.dumps(view or {})]
    r = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env)
    info = path + ".json"
    if r.returncode != 0 or not os.path.exists(info):
        raise RuntimeError(f"Blender 3.4 flat-quad render failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    with open(info) as f:
        return json.load(f)["names"]


def read_layers(path, names):
    """The (H, W, 3) float64 pixels of the image (names None) or {name: AOV pixels} of a multilayer
    EXR (Blender 5.0 writes each pass as its own part, 3.4 all in one: every part is read)."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise IOError(oiio.geterror())
    channels, pixels, part = [], [], 0
    while inp.seek_subimage(part, 0):
        spec = inp.spec()
        data = np.asarray(inp.read_image(part, 0, 0, spec.nchannels, oiio.FLOAT), dtype=np.float64)
        pixels += [data[..., i] for i in range(spec.nchannels)]
        channels += list(spec.channelnames)
        part += 1
    inp.close()
    if names is None:
        return np.stack(pixels[:3], axis=-1)

    def layer(pass_name):
        planes = []
        for c in "RGB":
            hits = [i for i, n in enumerate(channels) if n == f"{pass_name}.{c}" or n.endswith(f".{pass_name}.{c}")]
            if len(hits) != 1:
                raise IOError(f"{path}: no single channel for {pass_name}.{c} in {channels}")
            planes.append(pixels[hits[0]])
        return np.stack(planes, axis=-1)

    return {name: layer(name) for name in names}


# --- Blender side (bpy 5.0 in this process, or Blender 3.4 running this file) ----------------------

def render_in_process(build, path, resolution, z, kwargs, view=None):
    """Build the scene in the running Blender, render it to the EXR `path`; the AOV names (or None)."""
    import bpy
    scene = bpy.data.scenes.new("flat_quad")
    try:
        mat = bpy.data.materials.new("flat_quad")
        if mat.node_tree is None:                       # Blender 3.4 (5.0 materials always have nodes)
            mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        nodes.clear()
        KEPT.clear()
        coord = _snapped_coordinate(nodes, links, resolution, z)
        result = build(nodes, links, coord, **kwargs)
        out = nodes.new("ShaderNodeOutputMaterial")
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Strength"].default_value = 1.0
        links.new(emission.outputs[0], out.inputs["Surface"])
        names = None
        if isinstance(result, dict):
            names = list(result)
            layer = scene.view_layers[0]
            for name, socket in result.items():
                aov = layer.aovs.add()
                aov.name, aov.type = name, "COLOR"
                node = nodes.new("ShaderNodeOutputAOV")
                if hasattr(node, "aov_name"):
                    node.aov_name = name
                else:
                    node.name = name
                links.new(socket, node.inputs["Color"])
            links.new(next(iter(result.values())), emission.inputs["Color"])
        else:
            links.new(result, emission.inputs["Color"])

        mesh = bpy.data.meshes.new("flat_quad")
        mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
        mesh.materials.append(mat)
        plane = bpy.data.objects.new("flat_quad", mesh)
        scene.collection.objects.link(plane)
        cam_data = bpy.data.cameras.new("flat_quad")
        cam_data.type, cam_data.ortho_scale = "ORTHO", 2.0
        cam_data.clip_start, cam_data.clip_end = 0.01, 10.0
        cam = bpy.data.objects.new("flat_quad_camera", cam_data)
        cam.location = (0.0, 0.0, 1.0)
        scene.collection.objects.link(cam)
        scene.camera = cam
        for target, key in ((plane, "plane"), (cam_data, "camera"), (cam, "camera_object")):
            for name, value in (view or {}).get(key, {}).items():
                setattr(target, name, value)
        _setup_render(scene, resolution, path, names is not None)
        bpy.ops.render.render(write_still=True, scene=scene.name)
        return names
    finally:
        for obj in list(scene.collection.objects):
            data = obj.data
            bpy.data.objects.remove(obj)
            if isinstance(data, bpy.types.Mesh):
                for m in list(data.materials):
                    if m is not None:
                        bpy.data.materials.remove(m)
                bpy.data.meshes.remove(data)
            elif data is not None:
                bpy.data.cameras.remove(data)
        bpy.data.scenes.remove(scene)


def _snapped_coordinate(nodes, links, resolution, z):
    """Texture Coordinate Object output -> pixel centre: snap((x+1, y+1), 2/W) - 1 + 1/W, z := z."""
    tc = nodes.new("ShaderNodeTexCoord")
    step = 2.0 / resolution
    shift = _vector_math(nodes, "ADD", (1.0, 1.0, 0.0))
    links.new(tc.outputs["Object"], shift.inputs[0])
    snap = _vector_math(nodes, "SNAP", (step, step, 1.0))
    links.new(shift.outputs[0], snap.inputs[0])
    flat = _vector_math(nodes, "MULTIPLY", (1.0, 1.0, 0.0))
    links.new(snap.outputs[0], flat.inputs[0])
    centre = _vector_math(nodes, "ADD", (-1.0 + step / 2, -1.0 + step / 2, float(z)))
    links.new(flat.outputs[0], centre.inputs[0])
    return centre.outputs[0]


def _vector_math(nodes, operation, b):
    node = nodes.new("ShaderNodeVectorMath")
    node.operation = operation
    node.inputs[1].default_value = b
    return node


def _setup_render(scene, resolution, path, multilayer):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = 1
    for name in ("use_adaptive_sampling", "use_denoising", "use_preview_denoising"):
        if hasattr(c, name):
            setattr(c, name, False)
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.max_bounces = 0
    c.seed = 0
    c.pixel_filter_type = "BOX"
    c.filter_width = 0.01
    scene.render.resolution_x = scene.render.resolution_y = int(resolution)
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):                 # Blender 5.0: multilayer is a media type
        settings.media_type = "MULTI_LAYER_IMAGE" if multilayer else "IMAGE"
    if not multilayer or not hasattr(settings, "media_type"):
        settings.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGB" if not multilayer else "RGBA"
    settings.exr_codec = "ZIP"
    scene.render.filepath = path
    scene.render.use_file_extension = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False


def _blender_main(argv):
    import argparse
    import importlib
    p = argparse.ArgumentParser()
    p.add_argument("--module", required=True)
    p.add_argument("--function", required=True)
    p.add_argument("--kwargs", default="{}")
    p.add_argument("--resolution", type=int, default=RESOLUTION)
    p.add_argument("--z", type=float, default=0.0)
    p.add_argument("--out", required=True)
    p.add_argument("--view", default="{}")
    a = p.parse_args(argv)
    build = importlib.import_module(a.module)
    for part in a.function.split("."):
        build = getattr(build, part)
    harness = importlib.import_module("tests.nodes.flat_quad")     # the module `build` calls keep() of
    names = harness.render_in_process(build, a.out, a.resolution, a.z, json.loads(a.kwargs), json.loads(a.view))
    import bpy
    with open(a.out + ".json", "w") as f:
        json.dump({"names": names, "blender": list(bpy.app.version), "kept": harness.KEPT}, f)


if __name__ == "__main__":
    _blender_main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
