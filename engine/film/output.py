"""Output files of a render: checked before tracing, never an input, written atomically.

Both command lines (``python -m engine render`` and ``python -m mcrt_addon render``) use this:

* ``check_outputs()`` runs before any tracing.  A target is refused when it is a file the render
  reads (``refuse_inputs()``: the scene file and its NPZ, a scene file's textures, a .blend, its
  linked libraries and image textures), the same file as another output, a directory, not a regular file, read-only, in a
  directory that cannot be made or written, or an image whose extension is not ``.exr``
  (linear float) or ``.png`` (sRGB 8-bit).  Missing directories are made here.
* ``write_image()`` / ``write_text()`` write to a hidden temporary file beside the target,
  check the write (OpenImageIO's errors, the image read back), fsync it and only then rename
  it over the target.  On any failure the temporary file is removed and an existing target is
  left exactly as it was; the caller gets one ``OutputError`` line.
* A temporary file is named ``.NAME.HOST-PID-XXXXXXXX.partEXT`` after the target, this machine and
  the writing process.  One that a killed render left (SIGKILL, a power cut) is removed by the next
  ``check_outputs()`` of that target: its process is gone (same host, the PID no longer runs), or
  it has no HOST-PID (an older engine's) and is more than a day old (``remove_stale_parts``).
"""
from __future__ import annotations

import contextlib
import os
import re
import socket
import tempfile
import time
from dataclasses import dataclass

import numpy as np

IMAGE_FORMATS = {".exr": "exr", ".png": "png"}


class OutputError(Exception):
    """An output that cannot or must not be written; the message names the option and the path."""


@dataclass(frozen=True)
class Output:
    option: str       # the command-line option, named in messages ("-o", "--png", "--stats-json")
    path: str         # absolute
    kind: str         # "exr", "png" or "json"

    def describe(self) -> str:
        return f"{self.option} '{self.path}'"


def resolve_path(path: str, base_dir: str | None = None) -> str:
    """Absolute path; Blender's ``//`` prefix is relative to ``base_dir`` (default: here)."""
    if path.startswith("//"):
        return os.path.abspath(os.path.join(base_dir or os.getcwd(), path[2:]))
    return os.path.abspath(os.path.expanduser(path))


def image_kind(option: str, path: str, required: str | None = None) -> str:
    ext = os.path.splitext(path)[1].lower()
    kind = IMAGE_FORMATS.get(ext)
    if kind is None:
        known = " or ".join(IMAGE_FORMATS)
        raise OutputError(f"{option} '{path}': unknown image extension '{ext or '(none)'}' "
                          f"(use {known}; .exr is linear float, .png sRGB 8-bit)")
    if required is not None and kind != required:
        raise OutputError(f"{option} '{path}': must end in .{required}")
    return kind


def _same_file(a: str, b: str) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _check_writable_dir(output: Output) -> None:
    directory = os.path.dirname(output.path)
    try:
        os.makedirs(directory, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"{output.describe()}: '{directory}' is not a directory") from None
    except OSError as exc:
        raise OutputError(f"{output.describe()}: cannot make directory '{directory}': {exc.strerror}") from None
    try:                      # a real probe: os.access() says yes to root on a read-only mount
        fd, probe = tempfile.mkstemp(prefix=".tncg15-probe-", dir=directory)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{output.describe()}: directory '{directory}' is not writable: "
                          f"{exc.strerror}") from None


UNTAGGED_PART_SECONDS = 24 * 3600        # a temporary file without HOST-PID older than this is stale


def _name_max(directory: str) -> int:
    """The longest file name (bytes) the file system of `directory` takes."""
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def _part_stem(name: str, directory: str, tag: str) -> str:
    """`name`, cut so that the temporary ".STEM.TAG" + 8 random + ".partEXT" fits in a file name."""
    ext = os.path.splitext(name)[1]
    room = _name_max(directory) - len(f"..{tag}12345678.part{ext}".encode())
    stem = name
    while len(stem.encode()) > max(room, 0):
        stem = stem[:-1]
    return stem


def _part_prefix(name: str, directory: str) -> str:
    tag = f"{socket.gethostname()}-{os.getpid()}-"
    return f".{_part_stem(name, directory, tag)}.{tag}"


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:                          # EPERM: it runs, as another user
        return True
    return True


def remove_stale_parts(path: str) -> list[str]:
    """Remove the temporary files of target `path` that killed renders left (module docstring);
    returns their paths.  Those of a render still running, here or on another host, stay."""
    directory, name = os.path.split(path)
    ext = os.path.splitext(name)[1]
    stem = _part_stem(name, directory, f"{socket.gethostname()}-{os.getpid()}-")
    tagged = re.compile(re.escape(f".{stem}.") + r"(?P<host>.+)-(?P<pid>\d+)-[^.]+" + re.escape(f".part{ext}") + "$")
    untagged = re.compile(re.escape(f".{name}.") + r"[^.]+" + re.escape(f".part{ext}") + "$")
    removed = []
    try:
        entries = os.listdir(directory)
    except OSError:
        return removed
    host = socket.gethostname()
    for entry in entries:
        full = os.path.join(directory, entry)
        match = tagged.match(entry)
        try:
            if match:
                stale = match["host"] == host and not _running(int(match["pid"]))
            else:
                stale = bool(untagged.match(entry)) and time.time() - os.lstat(full).st_mtime > UNTAGGED_PART_SECONDS
            if stale and os.path.isfile(full) and not os.path.islink(full):
                os.unlink(full)
                removed.append(full)
        except OSError:                      # gone meanwhile, or not ours to remove
            continue
    return removed


def _check_target(output: Output) -> None:
    if not os.path.lexists(output.path):
        return
    if os.path.isdir(output.path):
        raise OutputError(f"{output.describe()}: is a directory")
    if not os.path.isfile(output.path):
        raise OutputError(f"{output.describe()}: exists and is not a regular file")
    if not os.stat(output.path).st_mode & 0o222:
        raise OutputError(f"{output.describe()}: is read-only")


def refuse_inputs(outputs, inputs) -> None:
    """One OutputError when an output is a file the render reads.  ``inputs``: paths, or (path,
    what it is) pairs ("a library linked by the .blend"), named in the message."""
    for output in outputs:
        for source in inputs:
            path, what = source if isinstance(source, tuple) else (source, None)
            if path and _same_file(output.path, path):
                raise OutputError(f"{output.describe()}: is an input file; refusing to overwrite it"
                                  + (f" ({what})" if what else ""))


def check_outputs(requested, inputs=(), base_dir: str | None = None) -> list[Output]:
    """``requested``: (option, path or None, kind) with kind "image" (by extension), "png" or
    "json".  ``inputs``: files that must never be written (see refuse_inputs; the inputs known only
    once the scene is read, its textures or a .blend's libraries, are checked then).  ``base_dir``: what a Blender-style
    ``//`` prefix is relative to (the .blend's or the scene file's directory).  Returns the
    outputs to write."""
    outputs = []
    for option, path, kind in requested:
        if path is None:
            continue
        if not path or path.endswith(("/", os.sep)):
            raise OutputError(f"{option} '{path}': not a file name")
        absolute = resolve_path(path, base_dir)
        if os.path.isdir(absolute):
            raise OutputError(f"{option} '{absolute}': is a directory")
        refuse_inputs([Output(option, absolute, kind)], inputs)
        if kind in ("image", "png"):
            kind = image_kind(option, absolute, None if kind == "image" else "png")
        outputs.append(Output(option, absolute, kind))
    for i, output in enumerate(outputs):
        for other in outputs[:i]:
            if _same_file(output.path, other.path):
                raise OutputError(f"{output.describe()}: is also the target of {other.option}")
        _check_target(output)
        _check_writable_dir(output)
        name = os.path.basename(output.path)
        if len(name.encode()) > _name_max(os.path.dirname(output.path)):
            raise OutputError(f"{output.describe()}: the file name is {len(name.encode())} bytes long; this file "
                              f"system takes at most {_name_max(os.path.dirname(output.path))}")
        remove_stale_parts(output.path)
    return outputs


def _fsync_directory(directory: str) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _new_file_mode(path: str) -> int:
    if os.path.exists(path):
        return os.stat(path).st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def replaced_atomically(output: Output):
    """Yield a temporary path beside ``output.path``; rename it into place when the block ends
    without an exception, else remove it (the target is untouched either way until then)."""
    directory, name = os.path.split(output.path)
    ext = os.path.splitext(name)[1]
    try:
        fd, tmp = tempfile.mkstemp(prefix=_part_prefix(name, directory), suffix=f".part{ext}", dir=directory)
        os.close(fd)
    except OSError as exc:
        raise OutputError(f"cannot write {output.describe()}: {exc.strerror}") from None
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.chmod(tmp, _new_file_mode(output.path))
        os.replace(tmp, output.path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise OutputError(f"cannot write {output.describe()}: {exc.strerror or exc}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_directory(directory)


def write_image(output: Output, image: np.ndarray, metadata=()) -> None:
    """EXR (linear float, with `metadata` as header attributes) or PNG (sRGB), checked by reading the
    written file back."""
    from .image_files import read_image, write_exr, write_png
    image = np.asarray(image)
    with replaced_atomically(output) as tmp:
        if output.kind != "exr":
            write_png(tmp, image)
        elif metadata:
            write_exr(tmp, image, metadata)
        else:
            write_exr(tmp, image)
        if read_image(tmp).shape[:2] != image.shape[:2]:
            raise OSError(f"the written image does not read back as {image.shape[1]}x{image.shape[0]}")


def write_text(output: Output, text: str) -> None:
    with replaced_atomically(output) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)


def write_multilayer(output: Output, image: np.ndarray, passes: dict, metadata=()) -> None:
    """A multi-layer EXR (Combined and the passes, Blender's channel names: engine/film/passes.py),
    atomically and checked as write_image."""
    from .passes import exr_channels, read_multilayer_exr, write_multilayer_exr
    with replaced_atomically(output) as tmp:
        write_multilayer_exr(tmp, image, passes, metadata)
        if sorted(read_multilayer_exr(tmp)) != sorted(exr_channels(passes)):
            raise OSError("the written EXR does not read back with its channels")
