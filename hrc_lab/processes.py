"""Which process is which: a live process' identity that outlives PID reuse (used by the runs' ``process_start``
tag, ``hrc-lab-runs stale`` and ``hrc-lab-server stop``), and which machine it runs on (the runs' ``cpu`` tags,
``hrc-lab-reproduce``'s summary)."""

from __future__ import annotations

import os
import platform
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


def machine_identity() -> dict[str, str]:
    """Tags that say what a job's wall times and float rounding depend on: the CPU (``cpu``: its model name and
    family/model/stepping as /proc/cpuinfo gives them), the cores this process may use, and the instruction set torch
    dispatches its CPU kernels to (``cpu_capability``, e.g. AVX2 or AVX512): two machines of the same size can
    differ several times in speed, and a job's numbers within their seed spread (docs/reproduce.md, "Wall times
    depend on the machine")."""
    import torch

    fields: dict[str, str] = {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            fields.setdefault(key.strip(), value.strip())
    except OSError:  # not Linux
        pass
    name = fields.get("model name") or platform.processor() or platform.machine()
    if "cpu family" in fields:
        model, stepping = fields.get("model", "?"), fields.get("stepping", "?")
        name += f" (family {fields['cpu family']} model {model} stepping {stepping})"
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {"cpu": name, "cpu_cores": str(cores), "cpu_capability": torch.backends.cpu.get_cpu_capability()}
