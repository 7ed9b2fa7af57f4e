"""Bad input through the add-on: a clear message that names the object (never a traceback, never a
silent black image), and the user's .blend left exactly as it was.  Plus: every sample scene
renders without a single NaN/infinite sample.

Each case builds a tiny scene, saves it, fingerprints the data, renders it with
bpy.ops.render.render (engine TNCG15_MC) and checks the message that reached Blender's reports
(printed by Blender in background mode), the RenderReport, the fingerprint and the saved file.
``bpy.data.is_dirty`` is not usable for this: in the bpy module it is True even right after
saving or opening a file.
"""
import hashlib
import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

from conftest import REPO
from mcrt_addon.headless import set_exr_output
from rendering import forget_reports, last_report, open_blend, read_exr

NAN = float("nan")
NO_LIGHT = "the scene has no emitters and a black background: the image will be black"


# ------------------------------------------------------------------------------------ helpers
def _value(v):
    """A comparable, NaN-safe text form of an RNA value."""
    try:
        return tuple(repr(float(x)) for x in v)
    except (TypeError, ValueError):                # scalars, strings
        return repr(v)


def _node_values(tree):
    if tree is None:
        return None
    return sorted((node.name, node.bl_idname, sock.identifier, _value(sock.default_value))
                  for node in tree.nodes for sock in node.inputs if hasattr(sock, "default_value"))


def fingerprint():
    """Everything a render could plausibly touch, as plain comparable data."""
    objects = {}
    for ob in bpy.data.objects:
        objects[ob.name] = (ob.type, ob.data.name if ob.data else None,
                            tuple(_value(row) for row in ob.matrix_world),
                            _value(ob.location), _value(ob.rotation_euler), _value(ob.scale),
                            ob.hide_render, getattr(ob, "tncg15", None) and ob.tncg15.implicit_sphere)
    meshes = {}
    for me in bpy.data.meshes:
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        meshes[me.name] = (hashlib.sha256(co.tobytes()).hexdigest(), len(me.polygons), len(me.edges),
                           tuple(m.name if m else None for m in me.materials))
    materials = {m.name: _node_values(m.node_tree) for m in bpy.data.materials}
    worlds = {w.name: (_node_values(w.node_tree), _value(w.color)) for w in bpy.data.worlds}
    lights = {li.name: (li.type, repr(li.energy), _value(li.color), repr(getattr(li, "size", None)))
              for li in bpy.data.lights}
    scenes = {}
    for sc in bpy.data.scenes:
        r, p = sc.render, sc.tncg15
        scenes[sc.name] = (r.engine, r.resolution_x, r.resolution_y, r.resolution_percentage,
                           r.use_border, r.filepath, sc.camera.name if sc.camera else None,
                           sc.world.name if sc.world else None, sc.frame_current,
                           p.samples, p.seed, p.max_depth, p.shadow_rays, p.accelerator, p.threads)
    ids = tuple(len(coll) for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials,
                                       bpy.data.lights, bpy.data.cameras, bpy.data.worlds))
    return dict(objects=objects, meshes=meshes, materials=materials, worlds=worlds, lights=lights,
                scenes=scenes, ids=ids)


def file_state(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest(), os.stat(path).st_mtime_ns


def room(ms, scene, lamp=True):
    """A floor, optionally a small emissive ceiling quad, camera, black world, TNCG15 MC at 16x16, 1 spp."""
    ms.camera(scene)
    ms.black_world(scene)
    ms.mesh_object(scene, "Floor", lambda bm: ms.quad(bm, [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]),
                   ms.diffuse("White", (0.8, 0.8, 0.8)))
    if lamp:
        ms.mesh_object(scene, "Lamp", lambda bm: ms.quad(bm, [(-.3, -.3, 2), (-.3, .3, 2), (.3, .3, 2),
                                                             (.3, -.3, 2)]),
                       ms.emission("Light", (1, 1, 1), 20.0))
    r = scene.render
    r.resolution_x = r.resolution_y = 16
    r.resolution_percentage = 100
    r.engine = "TNCG15_MC"
    p = scene.tncg15
    p.samples, p.max_depth, p.seed = 1, 2, 1


class Outcome:
    def __init__(self, error, warnings, output, image, exc):
        self.error, self.warnings, self.output, self.image, self.exc = error, warnings, output, image, exc


def render_checked(scene, tmp_path, capfd, name="case"):
    """Save, render with the operator, and check the data and the file were left alone."""
    out = str(tmp_path / f"{name}.exr")
    set_exr_output(scene, out)                       # part of the saved file: not a change by the render
    blend = str(tmp_path / f"{name}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, check_existing=False)
    before, saved = fingerprint(), file_state(blend)
    forget_reports()
    capfd.readouterr()
    exc = None
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as e:
        exc = str(e)
    captured = capfd.readouterr()
    output = captured.out + captured.err
    assert fingerprint() == before, "the render changed the user's data"
    assert file_state(blend) == saved, "the render touched the saved .blend"
    assert "Traceback" not in output and "internal error" not in output, output
    image = read_exr(out) if exc is None and os.path.isfile(out) else None
    return Outcome(last_report().error, last_report().warnings,
                   output, image, exc)


def assert_error(outcome, message):
    """The render failed with exactly ``message``, through Blender's report (the operator's error)."""
    assert outcome.error == message
    assert outcome.exc is not None and message in outcome.exc
    assert f"Error: {message}" in outcome.output           # printed by Blender's report system
    assert outcome.image is None
    assert "Traceback" not in outcome.error and "Error:" not in outcome.error


# ------------------------------------------------------------------------------------- cases
def test_missing_camera(empty_scene, make_samples_module, tmp_path, capfd):
    """Blender itself refuses before the engine runs; the message is clear and nothing is changed."""
    room(make_samples_module, empty_scene)
    empty_scene.camera = None
    o = render_checked(empty_scene, tmp_path, capfd)
    assert o.exc is not None and "no camera" in o.exc.lower()
    assert o.error is None and o.image is None


def test_active_camera_that_is_not_a_camera(empty_scene, make_samples_module, tmp_path, capfd):
    """Blender renders from any object set as active camera; the exporter names it and refuses."""
    room(make_samples_module, empty_scene)
    empty_scene.camera = bpy.data.objects["Floor"]
    o = render_checked(empty_scene, tmp_path, capfd)
    assert_error(o, "Object 'Floor' is used as camera but is a mesh")


def test_no_lights_warns_that_the_image_will_be_black(empty_scene, make_samples_module, tmp_path, capfd):
    room(make_samples_module, empty_scene, lamp=False)
    o = render_checked(empty_scene, tmp_path, capfd)
    assert o.error is None and o.exc is None
    assert o.warnings == [NO_LIGHT]                              # once, not once per validation
    assert o.output.count(f"Warning: {NO_LIGHT}") == 1          # reached Blender's reports
    assert o.image is not None and np.all(o.image == 0)


@pytest.mark.parametrize("where", ["location", "rotation", "scale", "vertex", "camera", "area_light"])
def test_nan_transform_or_vertex(empty_scene, make_samples_module, tmp_path, capfd, where):
    """Blender accepts NaN in location/rotation/scale (it clamps infinity to FLT_MAX, and a NaN
    matrix_world assignment is sanitised to zero scale); vertices take NaN through foreach_set."""
    ms = make_samples_module
    room(ms, empty_scene)
    floor = bpy.data.objects["Floor"]
    expected = "Object 'Floor': transform has NaN or infinite values (check its location, rotation and scale)"
    if where == "location":
        floor.location = (0.0, NAN, 0.0)
    elif where == "rotation":
        floor.rotation_euler = (NAN, 0.0, 0.0)                # used to fail inside numpy's SVD
    elif where == "scale":
        floor.scale = (1.0, 1.0, NAN)
    elif where == "vertex":
        co = np.empty(len(floor.data.vertices) * 3, np.float32)
        floor.data.vertices.foreach_get("co", co)
        co[4] = NAN
        floor.data.vertices.foreach_set("co", co)
        floor.data.update()
        expected = "Object 'Floor': 1 vertices have NaN or infinite coordinates"
    elif where == "camera":
        empty_scene.camera.rotation_euler.x = NAN
        expected = ("Camera 'Camera': transform has NaN or infinite values "
                    "(check its location, rotation and scale)")
    else:
        light = bpy.data.lights.new("AreaLamp", "AREA")
        ob = bpy.data.objects.new("AreaLamp", light)
        ob.location = (0.0, 0.0, NAN)
        empty_scene.collection.objects.link(ob)
        expected = "Light 'AreaLamp': transform has NaN or infinite values (check its location, rotation and scale)"
    o = render_checked(empty_scene, tmp_path, capfd)
    assert_error(o, expected)


def test_non_planar_quad_renders_as_two_triangles(empty_scene, make_samples_module, tmp_path, capfd):
    """A warped quad face is legal Blender geometry (Cycles splits it into two triangles): it renders,
    as emitter and as surface, without an error or a warning about it."""
    ms = make_samples_module
    room(ms, empty_scene, lamp=False)
    ms.mesh_object(empty_scene, "WarpedLamp",
                   lambda bm: ms.quad(bm, [(-.3, -.3, 2), (-.3, .3, 2.3), (.3, .3, 2), (.3, -.3, 2)]),
                   ms.emission("Light", (1, 1, 1), 20.0))
    ms.mesh_object(empty_scene, "Warped",
                   lambda bm: ms.quad(bm, [(-.4, 0, .6), (.4, 0, .6), (.4, 0.3, 1.4), (-.4, -0.3, 1.4)]),
                   ms.diffuse("Red", (0.8, 0.05, 0.05)))
    empty_scene.tncg15.samples = 4
    o = render_checked(empty_scene, tmp_path, capfd)
    assert o.error is None and o.exc is None
    assert not [w for w in o.warnings if "Warped" in w], o.warnings
    assert last_report().export["triangles"] == 6
    img = o.image
    assert img is not None and np.isfinite(img).all()
    assert img.max() > 5.0                                         # the warped lamp is seen
    red = (img[..., 0] > 3 * img[..., 1]) & (img[..., 0] > 0.01)
    assert red.sum() >= 4                                          # the warped red quad is lit
    assert last_report().stats["nonfinite_samples"] == 0


@pytest.mark.parametrize("emissive", [pytest.param(False, marks=pytest.mark.slow), True])   # the emissive one in `make test`
def test_empty_mesh_is_skipped_with_a_warning(empty_scene, make_samples_module, tmp_path, capfd, emissive):
    room(make_samples_module, empty_scene)
    me = bpy.data.meshes.new("Nothing")
    if emissive:
        me.materials.append(bpy.data.materials["Light"])
    empty_scene.collection.objects.link(bpy.data.objects.new("Empty Thing", me))
    o = render_checked(empty_scene, tmp_path, capfd)
    assert o.error is None and o.exc is None
    message = "Object 'Empty Thing': mesh has no faces; skipped"
    assert message in o.warnings
    assert f"Warning: {message}" in o.output
    assert o.image is not None and o.image.max() > 0                # the rest still renders


def test_absurd_resolution_is_refused(empty_scene, make_samples_module, tmp_path, capfd):
    """65536 x 65536 (Blender's maximum; 100000 is clamped to it) is refused by the engine before any
    pixel is allocated."""
    room(make_samples_module, empty_scene)
    r = empty_scene.render
    r.resolution_x = r.resolution_y = 100000
    assert (r.resolution_x, r.resolution_y) == (65536, 65536)
    empty_scene.name = "Huge"
    o = render_checked(empty_scene, tmp_path, capfd)
    assert_error(o, "Scene 'Huge': resolution 65536x65536 is too large (at most 268,435,456 pixels)")


def test_zero_percent_resolution_is_refused(empty_scene, make_samples_module, tmp_path, capfd):
    """Blender clamps 0 % to 1 %; 4 x 4 at 1 % is 0 pixels, which Blender refuses itself."""
    room(make_samples_module, empty_scene)
    r = empty_scene.render
    r.resolution_x = r.resolution_y = 4
    r.resolution_percentage = 0
    assert r.resolution_percentage == 1
    o = render_checked(empty_scene, tmp_path, capfd)
    assert o.exc is not None and "too small" in o.exc.lower()
    assert o.image is None


@pytest.mark.parametrize("kind", ["scaled_plane", "area_light"])
def test_zero_area_emitter(empty_scene, make_samples_module, tmp_path, capfd, kind):
    room(make_samples_module, empty_scene, lamp=(kind == "scaled_plane"))
    if kind == "scaled_plane":
        bpy.data.objects["Lamp"].scale = (1.0, 0.0, 1.0)
        expected = "Object 'Lamp': emitter has zero area"
    else:
        light = bpy.data.lights.new("AreaLamp", "AREA")
        light.size = 0.0
        ob = bpy.data.objects.new("AreaLamp", light)
        ob.location = (0.0, 0.0, 1.9)
        empty_scene.collection.objects.link(ob)
        expected = "Light 'AreaLamp': area light has zero area"
    o = render_checked(empty_scene, tmp_path, capfd)
    assert_error(o, expected)


# --------------------------------------------------------------- the command line, file untouched
def _cli(*args):
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "mcrt_addon", *map(str, args)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("case", ["nan_rotation", "no_camera"])
def test_cli_reports_one_line_and_leaves_the_file_alone(empty_scene, make_samples_module, tmp_path, case):
    room(make_samples_module, empty_scene)
    if case == "nan_rotation":
        bpy.data.objects["Lamp"].rotation_euler.z = NAN
        expected = ("error: Object 'Lamp': transform has NaN or infinite values "
                    "(check its location, rotation and scale)")
    else:
        empty_scene.camera = None
        expected = "error: Cannot render, no camera"
    blend = str(tmp_path / "bad.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, check_existing=False)
    before = file_state(blend)
    r = _cli("render", blend, "-o", tmp_path / "out.exr")
    assert r.returncode == 1, r.stderr
    errors = [line for line in r.stderr.splitlines() if "error:" in line]
    assert errors == ["python -m mcrt_addon: " + expected], r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert not os.path.exists(tmp_path / "out.exr")
    assert file_state(blend) == before


# ------------------------------------------------------------------ every sample scene is NaN-free
@pytest.mark.slow   # also in `make test`: the sample scenes of tests/addon/test_agreement.py, fuzz scenes, T5
def test_every_sample_scene_renders_without_nonfinite_samples(samples, make_samples_module):
    assert set(samples) == set(make_samples_module.SCENES)
    for name, path in samples.items():
        scene = open_blend(path, (32, 32))
        p = scene.tncg15
        p.samples, p.max_depth, p.seed, p.tile_size = 16, 8, 7, 16
        scene.render.engine = "TNCG15_MC"
        out = os.path.join(os.path.dirname(path), f"{name}_nan_check.exr")
        set_exr_output(scene, out)
        forget_reports()
        bpy.ops.render.render(write_still=True)
        last = last_report()
        assert last.error is None, (name, last.error)
        assert last.stats["nonfinite_samples"] == 0, name
        assert not [w for w in last.warnings if "NaN" in w], (name, last.warnings)
        img = read_exr(out)
        assert img.shape == (32, 32, 3), name
        assert np.isfinite(img).all(), name
        assert img.mean() > 0.01 and (img.max(axis=2) > 0).mean() > 0.5, (name, img.mean())
