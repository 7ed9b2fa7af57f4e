"""Cycles' first-hit passes (engine/film/passes.py FIRST_HIT, and Cryptomatte: engine/film/cryptomatte.py)
against Cycles 5.0's own, pixel by pixel,
on one scene: a ground plane, a cube and a tilted emitter under a coloured sky, each object and
material with its own Pass Index.  The definitions are deterministic per sample point, so the images
agree except where a pixel's samples see different surfaces (edges: each renderer jitters on its own);
every pass must agree on at least MIN_SHARE of the pixels.  Controls that must fail: a wrong mist
falloff, an unnormalised normal, the object index compared with the material index."""
import os
import tempfile

import bpy
import numpy as np
import pytest

from mcrt_addon import passes as addon_passes

RES = (48, 36)
SPP = 16
MIN_SHARE = 0.94                  # of the pixels within tolerance (the rest: silhouette edges)
CAMERA = np.array([0.0, -6.5, 2.6])
PASSES = ("mist", "world_normal", "uv", "position", "object_index", "material_index", "emission",
          "environment", "crypto_object", "crypto_material", "crypto_asset")
CRYPTO = ("crypto_object", "crypto_material", "crypto_asset")
# position: sample 0's point on each side, so within the pixel's footprint (4 % of the distance)
TOLERANCE = {"mist": 0.01, "world_normal": 0.01, "uv": 0.02, "position": 0.04, "object_index": 0.0,
             "material_index": 0.0, "emission": 0.01, "environment": 0.001}
CRYPTO_COVERAGE = 1.0 / SPP + 1e-6        # one sample's share


def build_scene():
    """The test scene in a fresh empty file (factory settings)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100

    def material(name, color, index, emission=0.0):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        m.pass_index = index
        nodes = m.node_tree.nodes
        bsdf = nodes.get("Principled BSDF")
        if emission:
            nodes.remove(bsdf)
            em = nodes.new("ShaderNodeEmission")
            em.inputs["Color"].default_value = (*color, 1.0)
            em.inputs["Strength"].default_value = emission
            m.node_tree.links.new(em.outputs[0], nodes["Material Output"].inputs["Surface"])
        else:
            bsdf.inputs["Base Color"].default_value = (*color, 1.0)
            bsdf.inputs["Roughness"].default_value = 1.0
        return m

    def add(op, name, mat, index, **kw):
        op(**kw)
        ob = bpy.context.active_object
        ob.name, ob.pass_index = name, index
        ob.data.materials.append(mat)
        return ob

    rig = bpy.data.objects.new("Rig", None)           # the Emitter's parent: its Cryptomatte asset
    scene.collection.objects.link(rig)
    add(bpy.ops.mesh.primitive_plane_add, "Ground", material("GroundMat", (0.6, 0.6, 0.6), 7), 3,
        size=12.0, location=(0, 0, 0))
    cube = add(bpy.ops.mesh.primitive_cube_add, "Cube", material("CubeMat", (0.8, 0.2, 0.1), 9), 5,
               size=1.6, location=(0.4, 0.6, 0.8))
    cube.rotation_euler = (0.0, 0.0, 0.5)
    lamp = add(bpy.ops.mesh.primitive_plane_add, "Emitter", material("Glow", (1.0, 0.8, 0.5), 2, emission=3.0),
               11, size=1.2, location=(-1.6, 0.4, 1.2))
    lamp.rotation_euler = (1.2, 0.0, 0.6)
    lamp.parent = rig
    bpy.ops.object.camera_add(location=tuple(CAMERA), rotation=(np.radians(75), 0.0, 0.0))
    scene.camera = bpy.context.active_object
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.3, 0.5, 1.0)
    world.mist_settings.start, world.mist_settings.depth, world.mist_settings.falloff = 2.0, 9.0, "QUADRATIC"
    scene.world = world
    vl = scene.view_layers[0]
    for name in PASSES:
        setattr(vl, addon_passes.TOGGLES[name], True)
    return scene


def render_passes(scene):
    """{tracer pass name: (H, W, c)} of the scene's engine, through Blender's multi-layer EXR."""
    fd, path = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    addon_passes.set_multilayer_output(scene)
    scene.render.filepath, scene.render.use_file_extension = path, False
    scene.render.use_compositing = False
    bpy.ops.render.render(write_still=True)
    from engine.film.passes import read_multilayer_exr
    channels = read_multilayer_exr(path)
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    meta = {a.name: a.value for a in inp.spec().extra_attribs if a.name.startswith("cryptomatte/")}
    inp.close()
    os.remove(path)
    image, passes = addon_passes.passes_from_channels(channels, PASSES)
    passes["metadata"] = meta
    return passes


def render_cycles(scene):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.use_denoising, c.seed = "CPU", SPP, False, 3
    c.use_adaptive_sampling = False
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    c.max_bounces = 4
    return render_passes(scene)


def render_tncg15(scene):
    scene.render.engine = "TNCG15_MC"
    p = scene.tncg15
    p.samples, p.seed, p.max_depth = SPP, 3, 4
    p.pixel_filter_type, p.filter_width = "BOX", 1.0
    return render_passes(scene)


def share_within(ours, theirs, tol):
    return float(np.mean(np.abs(np.asarray(ours) - np.asarray(theirs)).max(axis=-1) <= tol + 1e-6))


@pytest.fixture(scope="module")
def rendered(addon):
    scene = build_scene()
    cycles = render_cycles(scene)
    ours = render_tncg15(scene)
    scene.world.mist_settings.falloff = "LINEAR"             # the mist control
    linear = render_tncg15(scene)["mist"]
    return cycles, ours, linear


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in PASSES if n not in CRYPTO])
def test_first_hit_pass_agrees_with_cycles(rendered, name):
    cycles, ours, _ = rendered
    assert name in cycles and name in ours, (sorted(cycles), sorted(ours))
    tol = TOLERANCE[name]
    if name == "position":
        tol = tol * np.linalg.norm(cycles[name] - CAMERA, axis=-1)
    share = share_within(ours[name], cycles[name], tol)
    assert share >= MIN_SHARE, f"{name}: {share:.3f} of the pixels agree"


@pytest.mark.slow
def test_the_scene_exercises_every_pass(rendered):
    """The scene is no trivial pass: several index values, sky and emitter seen, mist in (0, 1)."""
    cycles, ours, _ = rendered
    assert len(np.unique(cycles["object_index"])) == 4               # 0 sky, 3, 5, 11
    assert set(np.unique(ours["material_index"])) == {0.0, 7.0, 9.0, 2.0}
    assert (cycles["environment"] > 0.1).any() and (cycles["emission"] > 1.0).any()
    mist = cycles["mist"]
    assert ((mist > 0.05) & (mist < 0.95)).mean() > 0.3
    assert (cycles["uv"][..., 2] == 1.0).mean() > 0.5


@pytest.mark.slow
def test_controls_fail(rendered):
    cycles, ours, linear = rendered
    assert share_within(linear, cycles["mist"], TOLERANCE["mist"]) < 0.6          # falloff linear, not quadratic
    assert share_within(0.9 * ours["world_normal"], cycles["world_normal"], TOLERANCE["world_normal"]) < 0.5   # the sky: 0 both
    assert share_within(ours["object_index"], cycles["material_index"], 0.0) < 0.5    # the sky: 0 both


@pytest.mark.slow
@pytest.mark.parametrize("name", CRYPTO)
def test_cryptomatte_agrees_with_cycles(rendered, name):
    """The ids of rank 0 and their coverage, pixel by pixel; the ids are bit for bit Cycles'
    (MurmurHash3 of the names), so the manifests agree too."""
    cycles, ours, _ = rendered
    c, o = cycles[name], ours[name]
    assert c.shape[-1] == o.shape[-1] == 12
    same_id = (o[..., 0].view(np.uint32) == c[..., 0].view(np.uint32))
    close = np.abs(o[..., 1] - c[..., 1]) <= CRYPTO_COVERAGE
    assert (same_id & close).mean() >= MIN_SHARE, (same_id.mean(), close.mean())
    assert len(np.unique(c[..., 0])) >= 3                   # several ids on screen (and 0: the sky)
    key = {v: k.split("/")[1] for k, v in cycles["metadata"].items() if k.endswith("/name")}
    layer = f"ViewLayer.{addon_passes.BLENDER_PASSES[name][0]}"
    import json
    theirs = json.loads(cycles["metadata"][f"cryptomatte/{key[layer]}/manifest"])
    ours_manifest = json.loads(ours["metadata"][f"cryptomatte/{key[layer]}/manifest"])
    assert ours_manifest and all(theirs.get(n) == h for n, h in ours_manifest.items()), (ours_manifest, theirs)


@pytest.mark.slow
def test_cryptomatte_control_fails(rendered):
    """Object ids compared with the material ids: none agree (other names, other hashes)."""
    cycles, ours, _ = rendered
    same = ours["crypto_object"][..., 0].view(np.uint32) == cycles["crypto_material"][..., 0].view(np.uint32)
    assert same[cycles["crypto_material"][..., 0] != 0].mean() < 0.05
