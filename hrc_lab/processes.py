"""Which process is which: a live process' identity that outlives PID reuse (used by the runs' ``process_start``
tag, ``hrc-lab-runs stale`` and ``hrc-lab-server stop``), which machine it runs on (the runs' ``cpu`` tags,
``hrc-lab-reproduce``'s summary), which code it runs (the runs' ``commit`` tag, the reports' headers), and the
one way hrc_lab signals and stops a process group (``hrc-lab-server``'s MLflow server, ``hrc-lab-reproduce``'s
steps)."""

from __future__ import annotations

import functools
import os
import platform
import signal
import subprocess
import time
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


def alive(pid: int | None, start: str | None) -> bool:
    """Whether ``pid`` is still the process whose :func:`process_start` was ``start``."""
    return pid is not None and start is not None and process_start(pid) == start


def group_members(pgid: int) -> list[int]:
    """Live (non-zombie) processes of process group ``pgid``."""
    members = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] != "Z":
                members.append(int(entry.name))
    return members


def signal_group(pgid: int, signum: int) -> bool:
    """Send ``signum`` to process group ``pgid`` (0: only check it exists); False when no process of it is left."""
    try:
        os.killpg(pgid, signum)
    except ProcessLookupError:
        return False
    return True


def stop_group(pid: int, start: str | None, timeout: float = 20) -> None:
    """SIGTERM the process group led by ``pid`` (if it is still our process: ``start``), SIGKILL after
    ``timeout`` s."""
    if not alive(pid, start):
        return
    signal_group(pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not signal_group(pid, 0) or (not alive(pid, start) and not group_members(pid)):
            return
        time.sleep(0.2)
    signal_group(pid, signal.SIGKILL)


def machine_identity() -> dict[str, str]:
    """Tags that say what a job's wall times and float rounding depend on: the CPU (``cpu``: its model name and
    family/model/stepping as /proc/cpuinfo gives them), the cores this process may use, and the instruction set torch
    dispatches its CPU kernels to (``cpu_capability``, e.g. AVX2 or AVX512), and the kernel settings in force
    (``cpu_kernels``, :mod:`hrc_lab.kernels`): two machines of the same size can differ several times in speed,
    and, with the kernels not pinned, a job's numbers within their seed spread (docs/reproduce.md, "Wall times
    depend on the machine")."""
    import torch

    from hrc_lab.kernels import cpu_kernels

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
    return {"cpu": name, "cpu_cores": str(cores), "cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "cpu_kernels": cpu_kernels()}


REPOSITORY = Path(__file__).resolve().parents[1]  # the checkout hrc_lab is imported from (an editable install's)
CODE = ("hrc_lab", "conf", "pyproject.toml")  # what a job's results depend on (not reports/, docs/, tests/)


@functools.cache
def code_identity() -> dict[str, str]:
    """Tags that say which code a job ran: ``commit``, the git commit of the checkout hrc_lab is imported from, and
    ``commit_dirty``, "true" when a tracked file of the code a job runs (:data:`CODE`) differed from it when the
    process started ("unknown" for both outside a git checkout). A report names the commits its runs ran at, so a
    run of edited code never passes for the commit's; the reports a plan rebuilds in the checkout are not code."""
    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(REPOSITORY), *args], capture_output=True, text=True, timeout=20)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return {"commit": "unknown", "commit_dirty": "unknown"}
    status = git("status", "--porcelain", "--untracked-files=no", "--", *CODE)
    return {"commit": commit, "commit_dirty": "unknown" if status is None else str(bool(status)).lower()}
