"""The thesis' published numbers (a copy of shared/reference/thesis_results.yaml, transcribed from Ma, 2024)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import yaml

REFERENCE = Path(__file__).resolve().parents[1] / "reference" / "thesis_results.yaml"


@lru_cache
def thesis_results() -> dict:
    return yaml.safe_load(REFERENCE.read_text())


def fmt(mean: float | None, std: float | None = None, digits: int = 2) -> str:
    """ "0.96 ± 0.01", "0.96" without a spread, "–" for a missing value."""
    if mean is None or mean != mean:  # None or NaN
        return "–"
    if std is None or std != std:
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"
