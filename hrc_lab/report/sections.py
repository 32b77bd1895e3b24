"""Report sections: one builder per table or figure, keyed by the ``table`` tag of its runs (the plans that gather
them into reports: :mod:`hrc_lab.report.plans`)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import pandas as pd

from hrc_lab.report.headline import results_frame
from hrc_lab.report.thesis import seeds_of


@dataclass
class Section:
    title: str
    markdown: str
    table: pd.DataFrame
    figures: dict = field(default_factory=dict)  # file name -> matplotlib figure
    artifacts: dict = field(default_factory=dict)  # file name -> (MLflow run id, artifact path) to copy
    sources: str = ""  # which sweeps (and variant) the section read, set by hrc_lab.report.build.section_of
    # one row per (method, thesis column): mean, std, n, or a claim's text and met (hrc_lab.report.headline)
    results: pd.DataFrame = field(default_factory=lambda: results_frame([]))


SECTIONS: dict[str, Callable[[pd.DataFrame], Section]] = {}


def register_section(table: str):
    """Register ``builder(runs) -> Section`` as the section of the runs tagged ``table``. It renders inside
    :func:`hrc_lab.report.thesis.seeds_of`, so that a section built from one seed prints its cells without a
    spread."""

    def decorator(builder):
        @functools.wraps(builder)
        def build(runs: pd.DataFrame) -> Section:
            with seeds_of(runs):
                return builder(runs)

        SECTIONS[table] = build
        return build

    return decorator


REPORT_MODULES = ("ch3_motion", "ch3_rl", "ch4_reasoning", "ch4_motion", "ch4_tamp", "ch5_planner", "ch5_perception",
                  "ch5_hrc", "ch6_grasp", "ch6_robot", "data")


def report_modules() -> list:
    """The report modules, imported: each registers its sections and defines its report's ``PLAN``."""
    import importlib

    return [importlib.import_module(f"hrc_lab.report.{name}") for name in REPORT_MODULES]


def load_sections() -> None:
    report_modules()
