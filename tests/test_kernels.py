"""hrc_lab.kernels: the CPU kernels are pinned when hrc_lab is imported, a user's own setting wins, and the
trained-model caches key on what is in force."""

import os
import subprocess
import sys

import pytest

from hrc_lab.grasp.configs import DetectorConfig
from hrc_lab.grasp.detector_cache import detector_cache_key
from hrc_lab.kernels import PINNED, SWITCH, cpu_kernels, pin_cpu_kernels


def test_pinning_fills_what_is_unset_and_keeps_what_is_set():
    environ = {"MKL_CBWR": "COMPATIBLE"}
    pin_cpu_kernels(environ, machine="x86_64")
    assert environ == {**PINNED, "MKL_CBWR": "COMPATIBLE"}
    assert cpu_kernels(environ) == "ONEDNN_MAX_CPU_ISA=AVX2 MKL_CBWR=COMPATIBLE ATEN_CPU_CAPABILITY=avx2"


@pytest.mark.parametrize("environ, machine", [({SWITCH: "native"}, "x86_64"), ({}, "aarch64")])
def test_nothing_is_pinned_natively_or_off_x86(environ, machine):
    before = dict(environ)
    pin_cpu_kernels(environ, machine=machine)
    assert environ == before
    assert cpu_kernels(environ) == " ".join(f"{name}=native" for name in PINNED)


def test_an_unknown_switch_value_names_the_variable():
    with pytest.raises(ValueError, match=f"{SWITCH} must be 'pinned' or 'native', got 'avx2'"):
        pin_cpu_kernels({SWITCH: "avx2"}, machine="x86_64")


def test_importing_hrc_lab_pins_before_torch_runs():
    environ = {k: v for k, v in os.environ.items() if k not in {*PINNED, SWITCH}}
    code = f"import hrc_lab, os; print(' '.join(os.environ.get(k, '-') for k in {list(PINNED)!r}))"
    out = subprocess.run([sys.executable, "-c", code], env=environ, capture_output=True, text=True, check=True)
    expected = " ".join(PINNED.values()) if os.uname().machine.lower() in ("x86_64", "amd64") else "- - -"
    assert out.stdout.strip() == expected


def test_the_detector_cache_keys_on_the_kernels(monkeypatch):
    key = detector_cache_key(DetectorConfig(), ["a", "b", "c"], [1, 2])
    monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", "AVX512_CORE")
    assert detector_cache_key(DetectorConfig(), ["a", "b", "c"], [1, 2]) != key
