"""`python -m mcrt_addon render` never writes an input, never loses an earlier output, ends every bad
input with one line (exit 2) and every stop signal cleanly (130/143, finished tiles written).

Each case runs the command line as a subprocess in a directory holding the .blend and an earlier
render, and checks that every file there is byte-identical afterwards."""
import os
import shutil
import signal
import subprocess
import sys

import bpy
import numpy as np
import pytest

from conftest import REPO
from tests.file_safety import OLD_OUTPUT, assert_one_line, snapshot
from rendering import read_exr

CORNELL = os.path.join(REPO, "sample_blends", "cornell.blend")


def cli(*args, env=None):
    env = dict(env or os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return [sys.executable, "-m", "mcrt_addon", *map(str, args)], env


def run_cli(*args, env=None):
    command, env = cli(*args, env=env)
    return subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture
def workdir(tmp_path):
    shutil.copy(CORNELL, tmp_path / "scene.blend")
    (tmp_path / "out.exr").write_bytes(OLD_OUTPUT)
    (tmp_path / "locked.png").write_bytes(OLD_OUTPUT)
    os.chmod(tmp_path / "locked.png", 0o444)
    (tmp_path / "text.blend").write_text("not a blend file")
    with open(CORNELL, "rb") as fh:
        (tmp_path / "truncated.blend").write_bytes(fh.read(3000))
    return tmp_path


CASES = [
    ("output-is-the-blend", ["-o", "{dir}/scene.blend"], "is an input file; refusing to overwrite it"),
    ("png-is-the-blend", ["--png", "{dir}/scene.blend"], "is an input file"),
    ("stats-is-the-blend", ["--stats-json", "{dir}/scene.blend"], "is an input file; refusing to overwrite it"),
    ("stats-is-the-blend-relative", ["--stats-json", "//scene.blend"], "is an input file"),
    ("stats-is-the-output", ["--stats-json", "{dir}/out.exr"], "is also the target of -o"),
    ("png-is-the-output", ["-o", "{dir}/a.png", "--png", "{dir}/a.png"], "is also the target of -o"),
    ("output-jpg", ["-o", "{dir}/a.jpg"], "unknown image extension '.jpg'"),
    ("output-directory", ["-o", "{dir}"], "is a directory"),
    ("output-read-only", ["-o", "{dir}/locked.png"], "is read-only"),
    ("stats-unwritable", ["--stats-json", "/proc/tncg15/s.json"], "cannot make directory"),
    ("not-a-blend", ["file:text.blend"], "is not a .blend file"),
    ("truncated-blend", ["file:truncated.blend"], "Failed to read blend file"),
    ("missing-blend", ["file:nope.blend"], "no such file"),
    ("seed-negative", ["--seed", "-1"], "argument --seed: must be from 0 to"),
    ("seed-2^31", ["--seed", str(2**31)], "argument --seed: must be from 0 to 2,147,483,647"),
    ("samples-2^31", ["--samples", str(2**31)], "argument --samples: must be from 1"),
    ("frame-2^31", ["--frame", str(2**31)], "argument --frame: must be from"),
    ("resolution-huge", ["--resolution", "70000", "8"], "argument --resolution: must be from 1 to 65,536"),
]


# Cases that check code both command lines share (the integer limits, engine/film/output.py) and that
# tests/cli/test_bad_input.py checks faster on the tracer's command line: `make test-slow` here.
SHARED = {"stats-is-the-output", "png-is-the-output", "output-jpg", "output-directory", "stats-unwritable",
          "seed-negative", "seed-2^31", "samples-2^31", "resolution-huge",
          # the input-file guard for the other flags (output-is-the-blend stays in `make test`), a read-only
          # output (tests/cli/test_bad_input.py) and a file that is not a .blend (truncated-blend stays):
          # `make test` was at 4:40 of its 5 minutes
          "png-is-the-blend", "stats-is-the-blend", "stats-is-the-blend-relative", "output-read-only", "not-a-blend"}


@pytest.mark.parametrize("name, args, fragment", [
    pytest.param(*case, id=case[0], marks=[pytest.mark.slow] if case[0] in SHARED else []) for case in CASES])
def test_bad_input_is_one_line_and_touches_nothing(workdir, name, args, fragment):
    args = [a.replace("{dir}", str(workdir)) for a in args]
    blend = str(workdir / "scene.blend")
    if args[0].startswith("file:"):
        blend, args = str(workdir / args[0][5:]), args[1:]
    output = [] if "-o" in args else ["-o", str(workdir / "out.exr")]
    before = snapshot(workdir)
    r = run_cli("render", blend, *output, *args, "--samples", "1", "--resolution", "8", "8")
    assert_one_line(r, 2, fragment)
    assert snapshot(workdir) == before


def test_failed_render_keeps_the_earlier_output(tmp_path, empty_scene):
    """No camera: Blender refuses; the earlier image is still there (it used to be deleted first)."""
    blend = tmp_path / "nocam.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    (tmp_path / "out.exr").write_bytes(OLD_OUTPUT)
    before = snapshot(tmp_path)
    r = run_cli("render", blend, "-o", tmp_path / "out.exr", "--resolution", "8", "8")
    assert r.returncode == 1 and "camera" in r.stderr.lower() and "Traceback" not in r.stderr, r.stderr
    assert snapshot(tmp_path) == before


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_png_output_is_png_and_relative_paths_are_beside_the_blend(workdir):
    r = run_cli("render", workdir / "scene.blend", "-o", "//renders/a.png", "--stats-json", "//renders/s.json",
                "--samples", "1", "--resolution", "16", "8")
    assert r.returncode == 0, r.stderr[-2000:]
    with open(workdir / "renders" / "a.png", "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    assert sorted(os.listdir(workdir / "renders")) == ["a.png", "s.json"]


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_no_copy_of_the_scene_is_left_in_the_temporary_directory(workdir, tmp_path):
    tmp = tmp_path / "tmpdir"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    # Blender's temporary directory is inside TMPDIR, so an empty TMPDIR afterwards means no quit.blend
    # and no private directory was left anywhere (no look at a shared /tmp another test may write to).
    where = subprocess.run([sys.executable, "-c", "import bpy; print(bpy.app.tempdir)"], env=env,
                           capture_output=True, text=True, timeout=300)
    assert where.returncode == 0 and where.stdout.strip().startswith(str(tmp) + os.sep), where
    r = run_cli("render", workdir / "scene.blend", "-o", workdir / "new.exr", "--samples", "1",
                "--resolution", "8", "8", env=env)
    assert r.returncode == 0, r.stderr[-2000:]
    assert os.listdir(tmp) == []                         # no quit.blend, no private directory left


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
def test_disk_full_is_one_line_and_keeps_the_earlier_output(tiny_disk):
    (tiny_disk / "out.exr").write_bytes(OLD_OUTPUT)
    before = snapshot(tiny_disk)
    r = run_cli("render", CORNELL, "-o", tiny_disk / "out.exr", "--samples", "1", "--resolution", "128", "128")
    assert_one_line(r, 1, "cannot write -o")
    assert snapshot(tiny_disk) == before


@pytest.mark.slow          # 3-40 s (subprocesses, built zips): make test-slow, which .ci/run runs too
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_stop_signal_writes_the_finished_tiles(workdir, signum, code):
    command, env = cli("render", workdir / "scene.blend", "-o", workdir / "out.exr", "--samples", "4000",
                       "--resolution", "128", "128", "--threads", "2")
    proc = subprocess.Popen(command, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    seen = b""
    while b"% TNCG15 MC" not in seen:                    # the first progress line: a unit finished
        chunk = os.read(proc.stdout.fileno(), 4096)
        assert chunk, seen[-2000:]
        seen += chunk
    proc.send_signal(signum)
    out, _ = proc.communicate(timeout=60)
    out = (seen + out).decode()
    assert proc.returncode == code, out[-2000:]
    assert "Traceback" not in out
    image = read_exr(str(workdir / "out.exr"))
    tiles = image.reshape(2, 64, 2, 64, -1)[..., :3].mean(axis=(1, 3, 4))
    assert image.shape[:2] == (128, 128) and (tiles > 0).any() and np.isfinite(image).all()
