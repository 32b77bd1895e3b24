"""Which process is which: a live process' identity that outlives PID reuse (used by the runs' ``process_start``
tag, ``hrc-lab-runs stale`` and ``hrc-lab-server stop``)."""

from __future__ import annotations

from pathlib import Path


def process_start(pid: int) -> str | None:
    """``<boot id>:<start ticks>`` of a live process on this machine, or None when no such process exists (a
    zombie counts as gone): tells our process from a later one given the same PID."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[1].split()
    if fields[0] == "Z":
        return None
    return f"{boot}:{fields[19]}"
