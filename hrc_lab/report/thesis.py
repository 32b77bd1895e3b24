"""The thesis' published numbers (a copy of shared/reference/thesis_results.yaml, transcribed from Ma, 2024)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
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


def thesis_cells(present: Iterable, listed: Sequence) -> list:
    """The cells (part counts, goal counts, methods ...) in ``present``, those the thesis lists in ``listed`` first
    and in its order, then the ones it does not list, sorted: a report renders every cell its runs have, e.g. a
    user's own ``5of6`` after the thesis' four, numbers in them by value ("5of6" before "10of12"). Missing values
    (None, NaN) are no cell."""
    present = {value for value in present if value is not None and value == value}
    return [value for value in listed if value in present] + sorted(present - set(listed), key=_natural)


def _natural(value) -> list:
    """A sort key that orders the numbers in ``str(value)`` by value: "4goals" before "10goals"."""
    return [int(part) if i % 2 else part for i, part in enumerate(re.split(r"(\d+)", str(value)))]


def thesis_value(values: Sequence | None, columns: Sequence, key) -> object | None:
    """The thesis' value for ``key`` in a row ``values`` laid out as ``columns`` (a table's ``columns`` list, e.g.
    ``["3", "4", "5", "6"]``; keys are compared as strings, so a part count may be an int), or None when the thesis
    has no such column (a count, cell or goal it did not run) or no such row (``values`` None)."""
    names = [str(column) for column in columns]
    if values is None or str(key) not in names:
        return None
    i = names.index(str(key))
    return values[i] if i < len(values) else None
