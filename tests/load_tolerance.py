"""Time limits for tests that must also pass on a loaded 2-core machine (other test runs beside them).

A limit in seconds is a guard against a hang, not a performance figure (those are measured by
`make bench` and printed by the tests that time something).  Where a test checks that something
is prompt (a stop request), the limit scales with a time measured in the same run under the same
load: how long the first work unit took to arrive.
"""
import sys
import threading
import traceback

PROMPT_SHARE = 0.3       # a stop may take this share of the time to the first unit ...
PROMPT_FLOOR = 1.0       # ... and at least this many seconds (the limit on a quiet machine)


def prompt_limit(seconds_to_first_unit: float) -> float:
    """Seconds a stop request may take.  The time to the first finished unit includes rendering one
    unit, so a stop that waits for the units in flight instead of the tracer's next batch takes
    about that long and fails, at any load; measured under a load of 12 on 2 cores: the stop
    0.5 s, the first unit 7 s (limit 2.1 s)."""
    return max(PROMPT_FLOOR, PROMPT_SHARE * seconds_to_first_unit)


def guarded(hang: float, fn):
    """fn() on a thread: its value (or its exception, re-raised here), or a failed test when it has
    not returned within `hang` seconds (a guard against a hang, not a timing check)."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as exc:             # noqa: BLE001 - re-raised on the test's thread
            out["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(hang)
    assert not thread.is_alive(), f"the render hung (no answer in {hang:.0f} s)\n{thread_stacks()}"
    if "error" in out:
        raise out["error"]
    return out["value"]


def thread_stacks() -> str:
    """Every thread's stack now: what a hung render waits on, in the failure's message."""
    names = {t.ident: t.name for t in threading.enumerate()}
    return "\n".join(f"--- thread {names.get(ident, ident)}\n" + "".join(traceback.format_stack(frame))
                     for ident, frame in sys._current_frames().items())
