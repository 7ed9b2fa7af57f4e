"""`python -m engine render` on bad input: one line naming the problem, exit 2, no traceback, and
every file in the directory (inputs, an existing output) byte-identical afterwards.  Plus outputs
(atomic, disk full) and signals (SIGINT/SIGTERM keep finished tiles, SIGKILL leaves no worker)."""
import copy
import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from engine.film.image_files import read_image
from tests.file_safety import OLD_OUTPUT, alive, assert_one_line, children, snapshot
from engine.rendering.memory import check_memory, estimate_bytes
from engine.core.errors import SceneError
from engine.core.settings import RenderSettings

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SCENE = {
    "format": "tncg15-scene", "name": "T", "resolution": [8, 8],
    "camera": {"look_at": {"position": [0, -5, 1], "target": [0, 0, 1]}},
    "materials": [{"name": "White"}, {"name": "Lamp", "color": [0, 0, 0], "emission": [5, 5, 5]}],
    "meshes": [{"name": "Floor", "vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
                "triangles": [[0, 1, 2], [0, 2, 3]], "material": "White"}],
    "spheres": [{"name": "Ball", "center": [0, 0, 1], "radius": 0.5, "material": "White"}],
    "quads": [{"name": "Light", "corners": [[-.5, -.5, 3], [.5, -.5, 3], [.5, .5, 3], [-.5, .5, 3]],
               "material": "Lamp"}],
}


def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "engine", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, env=dict(os.environ, PYTHONPATH=ROOT), timeout=120)


def edited(*path_and_value):
    """The base scene with the value at ``path`` replaced (None as the value deletes the key)."""
    *path, value = path_and_value
    data = copy.deepcopy(SCENE)
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is None:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return json.dumps(data)


SCENE_CASES = [
    # materials
    ("color-word", edited("materials", 0, "color", "red"), "Material 'White': color must be 3 numbers, got 'red'"),
    ("color-short", edited("materials", 0, "color", [1, 2]), "Material 'White': color must be 3 numbers"),
    ("color-negative", edited("materials", 0, "color", [-1, 0, 0]), "Material 'White': color must be 3 finite non-negative"),
    ("emission-overflow", edited("materials", 1, "emission", [3.5e38, 0, 0]), "Material 'Lamp': emission 3.5e+38 is too large"),
    ("kind", edited("materials", 0, "kind", "metal"), "Material 'White': unknown kind 'metal'"),
    ("ior-text", edited("materials", 0, "ior", "1.5"), "Material 'White': ior must be a number"),
    ("ior-negative", edited("materials", 0, "ior", -1), "Material 'White': IOR must be positive"),
    ("material-name-missing", edited("materials", 0, "name", None), "Material #0: name is missing"),
    ("material-name-number", edited("materials", 0, "name", 5), "name must be a string, got 5"),
    ("materials-not-list", edited("materials", {}), "Scene 'T': materials must be a list"),
    ("material-not-object", edited("materials", [5]), "Material #0: must be a JSON object, got 5"),
    # camera
    ("lens-text", edited("camera", "lens", "50"), "Camera 'Camera': lens must be a number, got '50'"),
    ("lens-tiny", edited("camera", "lens", 1e-300), "Camera 'Camera': lens must be from 0.001 to"),
    ("lens-zero", edited("camera", "lens", 0), "Camera 'Camera': lens must be positive"),
    ("sensor-fit", edited("camera", "sensor_fit", "WIDE"), "Camera 'Camera': unknown sensor fit 'WIDE'"),
    ("shift-text", edited("camera", "shift_x", "a"), "Camera 'Camera': shift_x must be a number"),
    ("matrix-shape", edited("camera", {"matrix": [[1, 0], [0, 1]]}), "Camera 'Camera': matrix must be 4 rows of 4 numbers"),
    ("look-at-text", edited("camera", "look_at", "position", "here"), "look_at: position must be 3 numbers"),
    ("look-at-degenerate", edited("camera", "look_at", "target", [0, -5, 1]), "Camera 'Camera': transform must be a finite"),
    ("camera-not-object", edited("camera", 5), "Camera 'Camera': must be a JSON object, got 5"),
    # scene
    ("resolution-words", edited("resolution", ["a", "b"]), "Scene 'T': resolution must be 2 integers"),
    ("resolution-fraction", edited("resolution", [16.5, 16]), "Scene 'T': resolution must be 2 integers"),
    ("resolution-three", edited("resolution", [16, 16, 16]), "Scene 'T': resolution must be 2 integers"),
    ("resolution-zero", edited("resolution", [0, 8]), "Scene 'T': resolution must be positive"),
    ("resolution-huge", edited("resolution", [100000, 100000]), "Scene 'T': resolution 100000x100000 is too large"),
    ("background-word", edited("background", "black"), "Scene 'T': background must be 3 numbers"),
    ("background-overflow", edited("background", [1e31, 0, 0]), "Scene 'T': background 1e+31 is too large"),
    ("name-number", edited("name", 3), "name must be a string, got 3"),
    # meshes
    ("vertices-text", edited("meshes", 0, "vertices", "abc"), "Object 'Floor': vertices must be a list of [x, y, z] numbers"),
    ("vertices-2d", edited("meshes", 0, "vertices", [[0, 0], [1, 1]]), "Object 'Floor': vertices must be a list of [x, y, z]"),
    ("vertices-ragged", edited("meshes", 0, "vertices", [[0, 0, 0], [1, 1]]), "Object 'Floor': vertices must be a list"),
    ("vertex-word", edited("meshes", 0, "vertices", [[0, 0, "a"]] * 4), "Object 'Floor': vertices must be a list"),
    ("vertex-overflow", edited("meshes", 0, "vertices", [[0, 0, 1e35]] * 4), "Object 'Floor': vertex coordinate 1e+35 is too large"),
    ("triangles-fraction", edited("meshes", 0, "triangles", [[0, 1, 2.5]]), "Object 'Floor': triangles must be a list of [x, y, z] integers"),
    ("triangles-range", edited("meshes", 0, "triangles", [[0, 1, 9]]), "Object 'Floor': triangle indices out of range"),
    ("triangles-missing", edited("meshes", 0, "triangles", None), "Object 'Floor': triangles is missing"),
    ("material-ids-short", edited("meshes", 0, "material_ids", []), "Object 'Floor': 0 material ids for 2 triangles"),
    ("material-ids-long", edited("meshes", 0, "material_ids", [0, 0, 0]), "Object 'Floor': 3 material ids for 2 triangles"),
    ("material-ids-npz", edited("meshes", 0, "material_ids", "@ids"), "Object 'Floor': material_ids: array 'ids' not found"),
    ("material-unknown", edited("meshes", 0, "material", "nope"), "Object 'Floor': unknown material 'nope'"),
    ("material-index", edited("meshes", 0, "material", 7), "Object 'Floor': material index 7 out of range"),
    ("material-bool", edited("meshes", 0, "material", True), "Object 'Floor': material must be a material name or index"),
    # spheres and quads
    ("radius-text", edited("spheres", 0, "radius", "big"), "Object 'Ball': radius must be a number"),
    ("radius-overflow", edited("spheres", 0, "radius", 1e154), "Object 'Ball': sphere radius 1e+154 is too large"),
    ("radius-negative", edited("spheres", 0, "radius", -1), "Object 'Ball': sphere radius must be positive"),
    ("center-short", edited("spheres", 0, "center", [0, 0]), "Object 'Ball': center must be 3 numbers"),
    ("corners-shape", edited("quads", 0, "corners", [[0, 0, 0]] * 3), "Object 'Light': corners must be 4 rows of 3 numbers"),
    # files that are not scene files
    ("deep-nesting", "[" * 100000 + "]" * 100000, "is nested too deeply"),
    ("not-json", "{format: tncg15}", "is not valid JSON"),
    ("json-list", "[1, 2]", "is not a tncg15-scene file"),
    ("blend-bytes", b"BLENDER-v500REND\xff\xfe\x00\x88" * 10, "is not a text (JSON) file"),
    ("exr-bytes", b"v/1\x01\x02\x00\x00\x00\xe9channels", "is not a text (JSON) file"),
]


@pytest.mark.parametrize("name, content, fragment", SCENE_CASES, ids=[c[0] for c in SCENE_CASES])
def test_bad_scene_file(tmp_path, name, content, fragment):
    scene = tmp_path / "scene.json"
    (scene.write_bytes if isinstance(content, bytes) else scene.write_text)(content)
    (tmp_path / "out.exr").write_bytes(OLD_OUTPUT)
    before = snapshot(tmp_path)
    r = run("render", scene, "-o", tmp_path / "out.exr", "--stats-json", tmp_path / "s.json", "--samples", "1")
    assert_one_line(r, 2, fragment)
    assert snapshot(tmp_path) == before


def test_corrupt_npz_beside_the_scene(tmp_path):
    (tmp_path / "scene.json").write_text(edited("meshes", 0, "material_ids", "@ids"))
    (tmp_path / "scene.npz").write_bytes(b"PK\x03\x04 this is no zip archive")
    before = snapshot(tmp_path)
    r = run("render", tmp_path / "scene.json", "-o", tmp_path / "out.exr")
    assert_one_line(r, 2, "cannot read arrays")
    assert snapshot(tmp_path) == before


OPTION_CASES = [
    ("seed-negative", ["--seed", "-1"], "argument --seed: must be from 0 to"),
    ("seed-2^31", ["--seed", str(2**31)], "argument --seed: must be from 0 to 2,147,483,647"),
    ("samples-2^31", ["--samples", str(2**31)], "argument --samples: must be from 1 to"),
    ("samples-word", ["--samples", "many"], "argument --samples: not an integer"),
    ("threads-many", ["--threads", "5000"], "argument --threads: must be from 0 to 1,024"),
    ("tile-small", ["--tile-size", "4"], "argument --tile-size: must be from 8"),
    ("resolution-huge", ["--resolution", "70000", "8"], "argument --resolution: must be from 1 to 65,536"),
    ("output-directory", ["-o", "{dir}"], "is a directory"),
    ("output-jpg", ["-o", "{dir}/a.jpg"], "unknown image extension '.jpg'"),
    ("output-tif", ["-o", "{dir}/a.tif"], "unknown image extension '.tif'"),
    ("output-no-extension", ["-o", "{dir}/image"], "unknown image extension '(none)'"),
    ("output-empty", ["-o", ""], "not a file name"),
    ("png-not-png", ["--png", "{dir}/b.exr"], "--png '{dir}/b.exr': must end in .png"),
    ("png-is-output", ["-o", "{dir}/a.png", "--png", "{dir}/a.png"], "is also the target of -o"),
    ("stats-is-output", ["--stats-json", "{dir}/out.exr"], "is also the target of -o"),
    ("stats-is-scene", ["--stats-json", "{dir}/scene.json"], "is an input file; refusing to overwrite it"),
    ("output-is-scene", ["{dir}/scene.exr", "-o", "{dir}/scene.exr"], "is an input file"),
    ("output-is-npz", ["--stats-json", "{dir}/scene.npz"], "is an input file"),
    ("output-under-file", ["-o", "{dir}/scene.json/a.exr"], "is not a directory"),
    ("stats-unwritable", ["--stats-json", "/proc/tncg15/s.json"], "cannot make directory '/proc/tncg15'"),
    ("png-read-only", ["--png", "{dir}/locked.png"], "--png '{dir}/locked.png': is read-only"),
    ("stats-device", ["--stats-json", "/dev/null"], "exists and is not a regular file"),
]


@pytest.mark.parametrize("name, args, fragment", OPTION_CASES, ids=[c[0] for c in OPTION_CASES])
def test_bad_option(tmp_path, name, args, fragment):
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    (tmp_path / "scene.exr").write_text(json.dumps(SCENE))        # a scene file with an image's name
    np.savez(tmp_path / "scene.npz", ids=np.zeros(2, np.int64))
    (tmp_path / "out.exr").write_bytes(OLD_OUTPUT)
    (tmp_path / "locked.png").write_bytes(OLD_OUTPUT)
    os.chmod(tmp_path / "locked.png", 0o444)
    args = [a.replace("{dir}", str(tmp_path)) for a in args]
    scene = [] if args and args[0].endswith("scene.exr") else [str(tmp_path / "scene.json")]
    output = [] if "-o" in args else ["-o", str(tmp_path / "out.exr")]
    before = snapshot(tmp_path)
    r = run("render", *scene, *output, *args, "--samples", "1")
    assert_one_line(r, 2, fragment.replace("{dir}", str(tmp_path)))
    assert snapshot(tmp_path) == before


def test_blender_relative_output_is_beside_the_scene(tmp_path):
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    r = run("render", tmp_path / "scene.json", "-o", "//renders/rel.exr", "--samples", "1", "--quiet")
    assert r.returncode == 0, r.stderr
    assert read_image(str(tmp_path / "renders" / "rel.exr")).shape == (8, 8, 3)


def test_outputs_are_written_whole_with_no_temporary_left(tmp_path):
    (tmp_path / "out.png").write_bytes(OLD_OUTPUT)
    r = run("render", "-o", tmp_path / "out.exr", "--png", tmp_path / "out.png", "--stats-json",
            tmp_path / "s.json", "--samples", "1", "--resolution", "16", "8", "--quiet")
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(tmp_path)) == ["out.exr", "out.png", "s.json"]
    assert read_image(str(tmp_path / "out.png")).shape == (8, 16, 3)
    assert json.loads((tmp_path / "s.json").read_text())["resolution"] == [16, 8]




def test_disk_full_is_one_line_and_leaves_the_old_file(tiny_disk):
    (tiny_disk / "out.exr").write_bytes(OLD_OUTPUT)
    before = snapshot(tiny_disk)
    r = run("render", "-o", tiny_disk / "out.exr", "--samples", "1", "--resolution", "128", "128", "--quiet")
    assert_one_line(r, 1, "cannot write -o")
    assert snapshot(tiny_disk) == before                      # no partial file, no temporary left
    assert "wrote" not in r.stdout


def test_memory_estimate_refuses_before_allocating():
    from engine.scene.builtin import cornell_scene
    scene = cornell_scene((16384, 16384))
    settings = RenderSettings(threads=2)
    need = estimate_bytes(scene, settings)
    assert need > 16384 * 16384 * 24                           # at least the image and its variance
    with pytest.raises(SceneError, match=r"Scene '.*': a 16384x16384 render needs about .* GB of memory, "
                                         r"only 1.0 GB is available"):
        check_memory(scene, settings, available=2**30)
    assert check_memory(cornell_scene((64, 64)), settings, available=2**30) < 2**30


# ------------------------------------------------------------------------------------- signals
def start_render(tmp_path, *extra):
    """A render that takes a while (about 5 s on 2 cores); returns once the first work unit is done."""
    proc = subprocess.Popen([sys.executable, "-m", "engine", "render", "-o", str(tmp_path / "out.exr"),
                             "--samples", "4096", "--resolution", "64", "64", "--tile-size", "16",
                             "--threads", "2", *extra], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=dict(os.environ, PYTHONPATH=ROOT))
    seen = b""
    while not re.search(rb"Sample [1-9]\d*/", seen):
        chunk = os.read(proc.stderr.fileno(), 4096)
        assert chunk, f"the render ended early: {seen[-2000:]!r}"
        seen += chunk
    return proc


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_stop_signal_writes_finished_tiles(tmp_path, signum, code):
    proc = start_render(tmp_path)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)                      # a guard against a hang, not a timing
    err = err.decode()
    assert proc.returncode == code and "Traceback" not in err, err[-2000:]
    image = read_image(str(tmp_path / "out.exr"))
    tiles = image.reshape(4, 16, 4, 16, 3).mean(axis=(1, 3, 4))
    assert (tiles > 0).sum() >= 1 and (tiles == 0).sum() >= 1      # finished tiles kept, the rest not traced


def test_killed_render_leaves_no_worker(tmp_path):
    proc = start_render(tmp_path)
    workers = children(proc.pid)
    assert len(workers) == 2
    proc.kill()
    proc.wait(timeout=10)
    deadline = time.time() + 15                        # a guard against a hang: they die within ms
    while any(map(alive, workers)) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(map(alive, workers))
    assert not os.path.exists(tmp_path / "out.exr")


@pytest.mark.parametrize("option", ["-o", "--png", "--stats-json"])
def test_an_output_onto_a_texture_of_the_scene_file_is_refused(tmp_path, option):
    from engine.film.image_files import write_png
    from tests.scene.test_texture_fields import write_scene
    (tmp_path / "images").mkdir()
    write_png(str(tmp_path / "images" / "checker.png"), np.full((2, 2, 3), 0.5, np.float32))
    scene = write_scene(tmp_path, [{"name": "Checker", "path": "images/checker.png"}], {"texture": "Checker"})
    before = snapshot(tmp_path)
    target = tmp_path / "images" / "checker.png"
    output = [] if option == "-o" else ["-o", tmp_path / "out.exr"]
    r = run("render", scene, *output, option, target, "--samples", "1")
    assert_one_line(r, 2, f"{option} '{target}': is an input file; refusing to overwrite it "
                          "(the file of the scene's texture 'Checker')")
    assert snapshot(tmp_path) == before
    control = run("render", scene, "-o", tmp_path / "out.exr", "--samples", "1")
    assert control.returncode == 0, control.stderr           # the scene itself renders


def _limited_memory():
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))     # main read /dev/zero until the OOM killer


@pytest.mark.slow       # two command lines (about 0.7 s each); the same check in-process: the test below
@pytest.mark.parametrize("kind", ["/dev/zero", "fifo"])
def test_a_scene_that_is_not_a_regular_file_is_refused_before_reading(tmp_path, kind):
    """`render /dev/zero` read until the machine ran out of memory; a FIFO without a writer waited forever."""
    path = kind
    if kind == "fifo":
        path = tmp_path / "scene.json"
        os.mkfifo(path)
    r = subprocess.run([sys.executable, "-m", "engine", "render", str(path), "-o", str(tmp_path / "out.exr")],
                       cwd=ROOT, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=ROOT), timeout=60,
                       preexec_fn=_limited_memory)
    assert_one_line(r, 2, f"scene '{path}' is not a regular file")


def test_directories_huge_files_and_device_arrays_are_refused(tmp_path):
    from engine.scene.files import LARGEST_JSON, load_scene
    (tmp_path / "dir.json").mkdir()
    with pytest.raises(SceneError, match="is not a regular file"):
        load_scene(str(tmp_path / "dir.json"))
    with open(tmp_path / "huge.json", "wb") as fh:                     # sparse: takes no disk
        fh.truncate(LARGEST_JSON + 1)
    with pytest.raises(SceneError, match=r"huge.json' is 256 MiB: a scene file is at most 256 MiB"):
        load_scene(str(tmp_path / "huge.json"))
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    os.symlink("/dev/zero", tmp_path / "scene.npz")
    with pytest.raises(SceneError, match=r"arrays '.*scene.npz' is not a regular file"):
        load_scene(str(tmp_path / "scene.json"))
