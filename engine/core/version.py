"""The tracer's name, version and build: a worker or cluster of another version or build is refused.

ENGINE_VERSION is set by hand; BUILD_HASH is computed at import: the sha256 of this package's
source (every engine/**/*.py, sorted by path, path and contents), so a worker running another
checkout, or a copy in an add-on zip that differs by one line, is told apart although its
ENGINE_VERSION is the same.  Each copy hashes its own files.  The handshakes compare both
(engine/pools/transport.py hello, engine/pools/dask_cluster.py).  The hash is not in the render's
stats (it changes with every commit; images do not)."""
import hashlib
from pathlib import Path

ENGINE_NAME = "TNCG15 MC"
ENGINE_VERSION = "0.2.0"          # workers of another version are refused (engine/pools/dask_cluster.py)


def source_hash(package: Path) -> str:
    """sha256 (hex) over the sorted *.py files under `package`: relative path and contents."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        digest.update(path.relative_to(package).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()


BUILD_HASH = source_hash(Path(__file__).resolve().parent.parent)


def short_build(build) -> str:
    """The first 12 hex digits of a build hash, for messages ("unknown" for a worker without one)."""
    return build[:12] if isinstance(build, str) and build else "unknown"
