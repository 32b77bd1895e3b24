"""The thesis' published numbers (a copy of shared/reference/thesis_results.yaml, transcribed from Ma, 2024)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from functools import lru_cache
from pathlib import Path

import yaml

REFERENCE = Path(__file__).resolve().parents[1] / "reference" / "thesis_results.yaml"


@lru_cache
def thesis_results() -> dict:
    return yaml.safe_load(REFERENCE.read_text())


# True while a report section built from the runs of one seed is rendered (set by
# hrc_lab.report.sections.register_section): its cells have no spread to show.
_ONE_SEED: ContextVar[bool] = ContextVar("one_seed", default=False)


@contextmanager
def seeds_of(runs) -> Iterator[None]:
    """Render a section of ``runs`` (a frame with a ``seed`` column): while inside, :func:`fmt` leaves out the spread
    when the runs have one seed, so that such a section prints "0.96", not "0.96 ± 0.00"."""
    token = _ONE_SEED.set("seed" in runs and runs["seed"].nunique() == 1)
    try:
        yield
    finally:
        _ONE_SEED.reset(token)


def one_seed() -> bool:
    """Whether the section being rendered was built from the runs of one seed (see :func:`seeds_of`)."""
    return _ONE_SEED.get()


def fmt(mean: float | None, std: float | None = None, digits: int = 2) -> str:
    """One of our cells: "0.96 ± 0.01" (mean ± std over seeds), "0.96" without a spread or in a section built from
    one seed (:func:`seeds_of`), "–" for a missing value. The thesis' own values: :func:`thesis_fmt`."""
    return _mean_std_text(mean, None if one_seed() else std, digits)


def fmt_seeds(mean: float | None, std: float | None, seeds: int, section_seeds: int) -> str:
    """:func:`fmt` for a cell built from ``seeds`` of the section's ``section_seeds`` seeds: a cell with fewer says
    how many ("0.38 [1 of 2 seeds]"; none: "–"), and one seed has no spread to print (not "0.38 ± 0.00")."""
    text = fmt(mean, std if seeds > 1 else None)
    return text if seeds in (0, section_seeds) else f"{text} [{seeds} of {section_seeds} seeds]"


def markdown_table(frame, index: bool = False, **kwargs) -> str:
    """``frame.to_markdown`` for a table of :func:`fmt` cells. In a section of one seed its text columns are not
    read as numbers, so that a cell "0.60" stays "0.60" (tabulate would print 0.6; elsewhere the cell's "±" keeps
    it text); columns of numbers are laid out as ``to_markdown`` does."""
    if one_seed():
        text = [i + index for i in range(frame.shape[1]) if frame.iloc[:, i].map(lambda v: isinstance(v, str)).all()]
        if text:
            kwargs["disable_numparse"] = text
    return frame.to_markdown(index=index, **kwargs)


def thesis_fmt(mean: float | None, std: float | None = None, digits: int = 2) -> str:
    """A thesis value with the thesis' own spread: "0.96 ± 0.01", "0.96" without one, "–" for a missing value."""
    return _mean_std_text(mean, std, digits)


def _mean_std_text(mean: float | None, std: float | None, digits: int) -> str:
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


def thesis_row(path: str, columns: Sequence[str] = ()) -> tuple[list[str], list[tuple[float | None, float | None]]]:
    """The thesis' values at the dotted ``path`` of ``thesis_results.yaml`` (e.g. ``ch4.table_4_3.ours.sr``) as
    (columns, [(mean, std or None), ...]). A row is a list laid out as the nearest enclosing ``columns`` list, a
    mapping of column -> value, or one value (column ""); a value is a number or ``[mean, std]``. ``columns``
    picks and orders the columns (default: all of the row's)."""
    node: object = thesis_results()
    layout: list[str] = []
    for part in path.split("."):
        if isinstance(node, dict) and "columns" in node:
            layout = [str(column) for column in node["columns"]]
        if not isinstance(node, dict) or part not in node:
            raise KeyError(f"thesis_results.yaml has no {path!r} (at {part!r})")
        node = node[part]
    if isinstance(node, dict):
        values = {str(key): value for key, value in node.items()}
    elif isinstance(node, list) and layout and len(node) == len(layout):
        values = dict(zip(layout, node, strict=True))
    else:
        values = {"": node}
    wanted = [str(column) for column in columns] or list(values)
    missing = [column for column in wanted if column not in values]
    if missing:
        raise KeyError(f"thesis_results.yaml {path!r} has no column(s) {missing} (it has {list(values)})")
    return wanted, [_pair(values[column]) for column in wanted]


def _pair(value) -> tuple[float | None, float | None]:
    if isinstance(value, list | tuple):
        mean, std = (list(value) + [None, None])[:2]
        return (None if mean is None else float(mean), None if std is None else float(std))
    return (None if value is None else float(value), None)
