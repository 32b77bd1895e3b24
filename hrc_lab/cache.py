"""Data and models shared by the jobs of a sweep, built once under ``<paths.runs_dir>/cache``: the one cache
helper of hrc_lab (a key from the settings a file depends on, a lock, an atomic write)."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any


def cache_key(settings: Any, length: int = 12) -> str:
    """A short hash of everything a cached file depends on (JSON with sorted keys; other objects as ``str``)."""
    return hashlib.sha1(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:length]


def cached(path: Path, build: Callable[[Path], object]) -> Path:
    """Build ``path`` (a file, or a directory ``build`` fills) once and return it. Parallel jobs wait on a file lock
    for the first one; ``build`` writes a partial file or directory that is renamed into place when complete, so a
    job killed mid-build leaves nothing behind that a later job would take for a finished one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            partial = path.with_name(f"{path.stem}.partial{os.getpid()}{path.suffix}")
            try:
                build(partial)
                os.replace(partial, path)
            finally:
                if partial.is_dir():
                    shutil.rmtree(partial)
                else:
                    partial.unlink(missing_ok=True)
    return path
