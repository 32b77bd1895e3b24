"""Report sections: one builder per table or figure (keyed by the ``table`` tag of its runs), and the topics
(report files) that gather them."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import pandas as pd


@dataclass
class Section:
    title: str
    markdown: str
    table: pd.DataFrame
    figures: dict = field(default_factory=dict)  # file name -> matplotlib figure
    artifacts: dict = field(default_factory=dict)  # file name -> (MLflow run id, artifact path) to copy


SECTIONS: dict[str, Callable[[pd.DataFrame], Section]] = {}


def register_section(table: str):
    def decorator(builder):
        SECTIONS[table] = builder
        return builder

    return decorator


# report file -> (title, [(MLflow experiment, table tag), ...])
TOPICS = {
    "ch4_reasoning": (
        "Ch.4 reasoning module (GraphSAGE importance ranking) vs. baselines",
        [
            ("ch4/table_4_1", "table_4_1"),
            ("ch4/fig_4_7", "fig_4_7"),
            ("ch4/practical", "practical"),
            ("ch4/fig_4_9", "fig_4_9"),
        ],
    ),
}


def load_sections() -> None:
    from hrc_lab.report import ch4_reasoning, ch5_planner  # noqa: F401  (registration)
