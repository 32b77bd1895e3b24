"""hrc_lab: configuration-driven experiments for machine-learning control of collaborative robots (Ma, 2024)."""

from hrc_lab.kernels import pin_cpu_kernels

pin_cpu_kernels()  # before any torch kernel runs (hrc_lab.kernels)
