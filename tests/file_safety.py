"""Helpers for the command-line safety tests (tests/cli/test_bad_input.py,
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


def children(pid):
    """Pids whose parent is `pid` (from /proc)."""
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    fields = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                found.append(int(entry))
    return found


def alive(pid):
    """The process exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
