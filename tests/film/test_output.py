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
