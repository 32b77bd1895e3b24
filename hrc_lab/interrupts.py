"""SIGTERM and SIGINT as an exception, so a killed job unwinds through its MLflow run (marked KILLED) and exits
with the shell's code for the signal (143, 130) instead of looking successful."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Iterator
from typing import NoReturn

SIGNALS = (signal.SIGTERM, signal.SIGINT)


class RunInterrupted(BaseException):
    """Raised in the job when it receives SIGTERM or SIGINT. A ``BaseException``, like ``KeyboardInterrupt``, so
    that library code catching ``Exception`` does not swallow it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.signal_name = signal.Signals(signum).name
        self.killed_run_id: str | None = None  # the MLflow run it ended (set by the run's tracker), None before one
        super().__init__(f"interrupted by {self.signal_name}")

    def __reduce__(self):  # pickled with the run it ended, e.g. when a launcher's worker sends it to its parent
        return type(self), (self.signum,), {"killed_run_id": self.killed_run_id}

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


@contextlib.contextmanager
def signals_raise() -> Iterator[None]:
    """Within the block, the first SIGTERM/SIGINT raises :class:`RunInterrupted`; later ones are ignored while
    the job cleans up. The previous handlers come back afterwards. Main thread only (Python's rule for signals).
    Lightning chains its own SIGTERM handler in front of this one during a fit, so it still sees the signal."""
    received: list[int] = []

    def handler(signum, frame) -> None:
        if received:
            return
        received.append(signum)
        raise RunInterrupted(signum)

    previous = {signum: signal.signal(signum, handler) for signum in SIGNALS}
    try:
        yield
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)


def exit_interrupted(err: RunInterrupted) -> NoReturn:
    """End the process with the signal's exit code once the interrupted job has unwound. In a launcher's worker
    process (joblib's loky workers under ``hydra/launcher=joblib``) the worker loop catches ``SystemExit`` like any
    task error and waits for the next task from a parent the same signal has ended, so the worker would outlive the
    sweep: there the process ends at once (``os._exit``, streams flushed first), and a launcher whose parent is
    alive sees a terminated worker, never a finished job."""
    if multiprocessing.parent_process() is None:
        sys.exit(err.exit_code)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(err.exit_code)
