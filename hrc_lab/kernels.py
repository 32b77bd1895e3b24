"""The CPU kernels every hrc_lab process computes with, pinned to one instruction set so that a network can train
to the same weights on other x86-64 CPUs with AVX2, not only on the machine that made a report.

torch picks its CPU kernels at run time from the instructions the CPU has: oneDNN's convolutions, MKL's matrix
products and ATen's element-wise ops each take the widest vector path available (AVX-512 on one machine, AVX2 on
another), and the paths round differently. Training amplifies the last-bit differences: 8 steps of the Ch.6
detector's own fit from the same seed gave four different sets of weights under this project's 2-core AMD EPYC's
widest paths (AVX-512), an AVX2-only CPU's, an SSE4.1-only CPU's and MKL's COMPATIBLE branch
(``scripts/cpu_kernel_paths.py``, ``reports/benchmarks/cpu_kernels.md``). Pinning oneDNN and ATen to AVX2 and MKL to
its AVX2 branch in strict mode (MKL's *conditional numerical reproducibility*) fixes the path: it gives, bit for bit,
the AVX2-only CPU's weights, and on that machine it cost nothing (0.18 s per detector step pinned, 0.21 s on the
widest paths). Measured on one machine by capping the libraries; two real machines were not compared.

The settings are environment variables the libraries read at their first call, so :func:`pin_cpu_kernels` runs when
``hrc_lab`` is imported, before any kernel (``import hrc_lab`` first in a script or notebook of your own). A value
already in the environment wins, and ``HRC_LAB_CPU_KERNELS=native`` pins nothing: the machine's widest kernels,
its own numbers. Every MLflow run records what was in force (tag ``cpu_kernels``), and the trained-model caches key
on it. Thread counts must match too (``num_threads``, 1 by default). Not pinned on other architectures (the
settings name x86 instruction sets).
"""

from __future__ import annotations

import os
import platform
from collections.abc import MutableMapping

PINNED: dict[str, str] = {
    "ONEDNN_MAX_CPU_ISA": "AVX2",  # convolutions (Ch.5, Ch.6 detectors)
    "MKL_CBWR": "AVX2,STRICT",  # matrix products (linear layers, LSTMs)
    "ATEN_CPU_CAPABILITY": "avx2",  # element-wise ops and reductions
}
X86 = ("x86_64", "amd64", "i686", "i386")
SWITCH = "HRC_LAB_CPU_KERNELS"  # "native": pin nothing; "pinned" (or unset): PINNED


def pin_cpu_kernels(environ: MutableMapping[str, str] = os.environ, machine: str | None = None) -> None:
    """Set each of :data:`PINNED` in ``environ`` unless it is already set (on x86 machines, unless
    ``HRC_LAB_CPU_KERNELS=native``)."""
    choice = environ.get(SWITCH, "pinned")
    if choice not in ("pinned", "native"):
        raise ValueError(f"{SWITCH} must be 'pinned' or 'native', got {choice!r}")
    if choice == "native" or (machine or platform.machine()).lower() not in X86:
        return
    for name, value in PINNED.items():
        environ.setdefault(name, value)


def cpu_kernels(environ: MutableMapping[str, str] = os.environ) -> str:
    """The kernel settings in force, e.g. ``ONEDNN_MAX_CPU_ISA=AVX2 MKL_CBWR=AVX2,STRICT ATEN_CPU_CAPABILITY=avx2``
    (``native`` for one that is not set): a tag of every run and a part of every trained-model cache key."""
    return " ".join(f"{name}={environ.get(name, 'native')}" for name in PINNED)
