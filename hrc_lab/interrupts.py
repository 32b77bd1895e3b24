"""SIGTERM and SIGINT as an exception, so a killed job unwinds through its MLflow run (marked KILLED) and exits
with the shell's code for the signal (143, 130) instead of looking successful."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

SIGNALS = (signal.SIGTERM, signal.SIGINT)


class RunInterrupted(BaseException):
    """Raised in the job when it receives SIGTERM or SIGINT. A ``BaseException``, like ``KeyboardInterrupt``, so
    that library code catching ``Exception`` does not swallow it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.signal_name = signal.Signals(signum).name
        super().__init__(f"interrupted by {self.signal_name}")

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
