"""Helpers for the command-line safety tests (tests/tracer/test_cli_bad_input.py,
tests/addon/test_cli_safety.py): file snapshots and the one-line error check."""
import hashlib
import os

OLD_OUTPUT = b"an earlier render that must survive"


def snapshot(directory):
    """Every file under ``directory`` with its content hash: equal before and after = untouched."""
    found = {}
    for base, _, files in os.walk(directory):
        for name in files:
            path = os.path.join(base, name)
            with open(path, "rb") as fh:
                found[os.path.relpath(path, directory)] = hashlib.sha256(fh.read()).hexdigest()
    return found


def assert_one_line(r, code, fragment):
    """Exit ``code``, exactly one non-empty line on stderr containing ``fragment``, no traceback."""
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == code, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr
    assert len(lines) == 1 and fragment in lines[0], r.stderr[-2000:]
