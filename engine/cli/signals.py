"""SIGINT / SIGTERM on a command-line render: stop like Esc, keep what is finished.

The first signal only sets a flag that the render loop polls (``render(should_cancel=...)``,
about every 0.1 s): tiles in flight finish their paths, the finished image is written and the
command exits with 128 + the signal number (130 for Ctrl-C, 143 for SIGTERM).  A second signal
ends the process at once with the same code.  Forked workers ignore SIGINT (a terminal's
Ctrl-C reaches the whole process group) and die with their parent (engine/pools/local.py).
"""
from __future__ import annotations

import os
import signal
import sys

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
    def __init__(self, prog: str):
        self.prog = prog
        self.signum = None

    def install(self) -> "StopRequest":
        for signum in STOP_SIGNALS:
            signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, frame):
        name = signal.Signals(signum).name
        if self.signum is not None:
            os.write(2, f"{self.prog}: {name} again: stopping now\n".encode())
            os._exit(128 + signum)
        self.signum = signum
        os.write(2, f"\n{self.prog}: {name}: stopping; finished tiles will be written "
                    f"(send it again to quit at once)\n".encode())

    def requested(self) -> bool:
        return self.signum is not None

    @property
    def exit_code(self) -> int:
        return 128 + self.signum if self.signum is not None else 0

    def report_exit(self) -> int:
        """Exit code after a stopped render (0 when no signal came)."""
        if self.signum is not None:
            sys.stderr.write(f"{self.prog}: stopped by {signal.Signals(self.signum).name}\n")
        return self.exit_code
