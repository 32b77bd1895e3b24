"""Data and models shared by the jobs of a sweep, built once under ``<paths.runs_dir>/cache``."""

from __future__ import annotations

import fcntl
from collections.abc import Callable
from pathlib import Path


def cached(path: Path, build: Callable[[Path], object]) -> Path:
    """Build ``path`` once (under a file lock, so parallel jobs wait for the first one) and return it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            build(path)
    return path
