"""engine/film/output.py in-process: a write that fails half-way leaves the old file and no temporary;
a successful one replaces the target whole (works without root, unlike the tmpfs test)."""
import os

import numpy as np
import pytest

from engine.film import image_files as film
from engine.film.image_files import read_image
from engine.film.output import Output, OutputError, check_outputs, write_image, write_text
from tests.file_safety import OLD_OUTPUT


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "out.exr"
    target.write_bytes(OLD_OUTPUT)

    def half_written(path, image):
        with open(path, "wb") as fh:
            fh.write(b"v/1\x01 half an EXR")
        raise OSError("No space left on device")
    monkeypatch.setattr(film, "write_exr", half_written)
    with pytest.raises(OutputError, match=r"cannot write -o '.*out.exr': No space left on device"):
        write_image(Output("-o", str(target), "exr"), np.ones((4, 4, 3), np.float32))
    assert os.listdir(tmp_path) == ["out.exr"] and target.read_bytes() == OLD_OUTPUT


def test_successful_write_replaces_the_target_and_keeps_its_mode(tmp_path):
    target = tmp_path / "out.png"
    target.write_bytes(OLD_OUTPUT)
    os.chmod(target, 0o640)
    [output] = check_outputs([("--png", str(target), "png")])
    write_image(output, np.full((3, 5, 3), 0.5, np.float32))
    assert read_image(str(target)).shape == (3, 5, 3)
    assert os.stat(target).st_mode & 0o777 == 0o640 and os.listdir(tmp_path) == ["out.png"]
    write_text(Output("--stats-json", str(tmp_path / "s.json"), "json"), "{}")
    assert (tmp_path / "s.json").read_text() == "{}"


def test_temporaries_of_killed_renders_are_removed_by_the_next_render(tmp_path):
    """A SIGKILLed render leaves its hidden temporary file; the next check_outputs of that target
    removes it when its writer is gone (this host, a PID that no longer runs) or, without a host and
    PID (an older engine's), when it is more than a day old.  A running writer's file stays."""
    import socket
    import subprocess
    import sys
    import time
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = socket.gethostname()
    names = {
        "killed": f".out.exr.{host}-{dead.pid}-abcd1234.part.exr",
        "running": f".out.exr.{host}-{os.getpid()}-abcd1234.part.exr",
        "other host": f".out.exr.elsewhere-{dead.pid}-abcd1234.part.exr",
        "old untagged": ".out.exr.k2j4_x8q.part.exr",
        "new untagged": ".out.exr.q8x_4j2k.part.exr",
        "other target": f".other.exr.{host}-{dead.pid}-abcd1234.part.exr",
    }
    for name in names.values():
        (tmp_path / name).write_bytes(b"half an EXR")
    two_days_ago = time.time() - 2 * 86400
    os.utime(tmp_path / names["old untagged"], (two_days_ago, two_days_ago))
    check_outputs([("-o", str(tmp_path / "out.exr"), "image")])
    left = set(os.listdir(tmp_path))
    assert names["killed"] not in left and names["old untagged"] not in left
    assert {names["running"], names["other host"], names["new untagged"], names["other target"]} <= left


def test_a_temporary_names_its_host_and_process(tmp_path, monkeypatch):
    import socket
    seen = []

    def record(path, image, *args):
        seen.append(os.path.basename(path))
        raise OSError("stopped here")
    monkeypatch.setattr(film, "write_exr", record)
    with pytest.raises(OutputError):
        write_image(Output("-o", str(tmp_path / "out.exr"), "exr"), np.ones((2, 2, 3), np.float32))
    assert seen[0].startswith(f".out.exr.{socket.gethostname()}-{os.getpid()}-") and seen[0].endswith(".part.exr")


def test_a_name_too_long_for_the_file_system_is_refused_before_rendering(tmp_path):
    """300 characters passed the check and failed after the render ("File name too long"); a 250-character
    name, which the file system takes, failed too: its temporary's name was longer than 255 bytes."""
    with pytest.raises(OutputError, match=r"the file name is 304 bytes long; this file system takes at most 255"):
        check_outputs([("-o", str(tmp_path / ("a" * 300 + ".exr")), "image")])
    [output] = check_outputs([("--stats-json", str(tmp_path / ("b" * 250 + ".json")), "json")])
    write_text(output, "{}")
    assert os.listdir(tmp_path) == ["b" * 250 + ".json"]
