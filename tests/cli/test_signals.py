"""engine/cli/signals.py: the first SIGINT/SIGTERM only asks the render to stop, a second one ends the
process at once; both exit with 128 + the signal number.  Real signals, sent to a child process."""
import os
import select
import signal
import subprocess
import sys
import time

import pytest

from engine.cli.signals import StopRequest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
HANG = 60.0          # seconds: a guard against a hang, not a timing requirement

# A stand-in for a render loop: polls the stop request as the tracer does between batches, and
# (with "stubborn") never stops by itself, so only a second signal can end it.
CHILD = """
import sys, time
from engine.cli.signals import StopRequest
stop = StopRequest("prog").install()
print("ready", flush=True)
while not stop.requested() or sys.argv[1] == "stubborn":
    time.sleep(0.01)
print("finished tiles written", flush=True)
sys.exit(stop.report_exit())
"""


def start(mode):
    proc = subprocess.Popen([sys.executable, "-c", CHILD, mode], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    wait_for(proc.stdout, "ready\n")
    return proc


def wait_for(stream, text):
    """Read the pipe (unbuffered, so nothing is read ahead) until ``text`` has come."""
    seen, deadline = b"", time.monotonic() + HANG
    while text.encode() not in seen:
        ready, _, _ = select.select([stream], [], [], max(0.0, deadline - time.monotonic()))
        assert ready, f"the child process hangs; it wrote {seen!r}"
        chunk = os.read(stream.fileno(), 4096)
        assert chunk, f"the child process closed the pipe; it wrote {seen!r}"
        seen += chunk
    return seen.decode()


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_first_signal_asks_to_stop_and_the_loop_finishes(signum, code):
    proc = start("polite")
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=HANG)
    name = signal.Signals(signum).name
    assert proc.returncode == code
    assert out == "finished tiles written\n"          # the loop ran on to its end: nothing was cut off
    assert f"prog: {name}: stopping; finished tiles will be written" in err
    assert f"prog: stopped by {name}" in err
    assert "stopping now" not in err


def test_second_signal_ends_the_process_at_once():
    proc = start("stubborn")
    proc.send_signal(signal.SIGINT)
    wait_for(proc.stderr, "prog: SIGINT: stopping")          # the first one was handled ...
    assert proc.poll() is None                               # ... and did not end the process
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=HANG)
    assert proc.returncode == 130
    assert out == ""                                         # it never reached the end of its loop
    assert err == "prog: SIGINT again: stopping now\n"


def test_without_a_signal_nothing_is_requested(capsys):
    stop = StopRequest("prog")
    assert not stop.requested() and stop.exit_code == 0
    assert stop.report_exit() == 0
    assert capsys.readouterr().err == ""


def test_install_replaces_the_handlers_and_the_flag_is_set_in_process():
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        stop = StopRequest("prog").install()
        assert all(signal.getsignal(s) == stop._handle for s in old)
        signal.raise_signal(signal.SIGTERM)
        assert stop.requested() and stop.exit_code == 143
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
