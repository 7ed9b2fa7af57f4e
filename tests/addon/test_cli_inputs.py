"""`python -m mcrt_addon render` refuses (one line naming the file and what it is, exit 2, before
rendering) an -o/--png/--stats-json onto any file the render reads: the .blend, a library it links,
an image texture's file (mcrt_addon/cli.py files_read, engine/film/output.py refuse_inputs)."""
import os

import bpy
import pytest

from tests.file_safety import assert_one_line, snapshot
from test_cli_safety import run_cli


@pytest.fixture
def linked(tmp_path, empty_scene):
    """main.blend: a camera, a cube linked from lib.blend, a material with the image texture tex.png."""
    bpy.ops.mesh.primitive_cube_add()
    bpy.context.object.name = "LibCube"
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "lib.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(tmp_path / "lib.blend"), link=True) as (src, dst):
        dst.objects = ["LibCube"]
    scene = bpy.context.scene
    for obj in dst.objects:
        scene.collection.objects.link(obj)
    image = bpy.data.images.new("Tex", 4, 4)
    image.filepath_raw = str(tmp_path / "tex.png")
    image.file_format = "PNG"
    image.save()
    material = bpy.data.materials.new("Textured")
    node = material.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    bpy.ops.mesh.primitive_plane_add()
    bpy.context.object.data.materials.append(material)
    bpy.ops.object.camera_add(location=(0, -6, 2), rotation=(1.3, 0, 0))
    scene.camera = bpy.context.object
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "main.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return tmp_path


CASES = [
    ("stats-onto-the-library", ["--stats-json", "{dir}/lib.blend"], "the library 'lib.blend' linked by the .blend"),
    ("png-onto-the-texture", ["--png", "{dir}/tex.png"], "the file of image texture 'Tex'"),
    ("output-onto-the-texture", ["-o", "{dir}/tex.png"], "the file of image texture 'Tex'"),
    ("output-onto-the-blend", ["-o", "{dir}/main.blend"], "the .blend rendered"),
]


# Two of the four in `make test-slow` (.ci/run runs it): the texture and the .blend stay in `make test`.
SLOW_CASES = {"stats-onto-the-library", "output-onto-the-texture"}


@pytest.mark.parametrize("name, args, fragment", [
    pytest.param(*c, id=c[0], marks=[pytest.mark.slow] if c[0] in SLOW_CASES else []) for c in CASES])
def test_an_output_onto_a_file_the_render_reads_is_refused(linked, name, args, fragment):
    args = [a.replace("{dir}", str(linked)) for a in args]
    output = [] if "-o" in args else ["-o", str(linked / "out.exr")]
    before = snapshot(linked)
    r = run_cli("render", linked / "main.blend", *output, *args, "--samples", "1", "--resolution", "8", "8")
    assert_one_line(r, 2, "is an input file; refusing to overwrite it")
    assert fragment in r.stderr and os.path.basename(args[-1]) in r.stderr, r.stderr
    assert snapshot(linked) == before


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_a_render_of_the_linking_blend_still_renders(linked):
    """The control: the same .blend and outputs elsewhere render (the refusals above are not a broken file)."""
    r = run_cli("render", linked / "main.blend", "-o", linked / "out.exr", "--stats-json", linked / "s.json",
                "--samples", "1", "--resolution", "8", "8")
    assert r.returncode == 0, r.stderr[-2000:]


@pytest.mark.parametrize("address", ["garbage", "http//nowhere", "tcp://host:99999"])
def test_a_malformed_cluster_address_is_refused_before_the_blend_is_opened(address, monkeypatch, capsys, tmp_path):
    """Was checked only once Blender had opened the .blend and started the render (exit 1); now one
    line and exit 2 first, as `python -m engine render --cluster` does."""
    from mcrt_addon import cli
    opened = []
    monkeypatch.setattr(cli, "open_blend", lambda *a: opened.append(a) or "opened")
    monkeypatch.delenv("TNCG15_CLUSTER", raising=False)
    blend = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                         "sample_blends", "cornell.blend")
    code = cli.main(["render", blend, "-o", str(tmp_path / "out.exr"), "--cluster", address])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and not opened and os.listdir(tmp_path) == []
    assert len(err) == 1 and "not a Dask scheduler address" in err[0], err
    assert "TNCG15_CLUSTER" not in os.environ
