"""The committed reports read in a minute (issue "One reproduction, and reports a person can read"): each is built
from its plan on one store (its header says which), opens with the thesis' tables, and keeps to about 200 lines,
tables of at most 8 columns, captions of at most 3 lines and titles under 100 characters."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hrc_lab.report.plans import PLANS

REPORTS = Path(__file__).resolve().parents[1] / "reports"
MAX_LINES, MAX_COLUMNS, MAX_CAPTION, MAX_TITLE = 220, 8, 480, 100  # a caption: 3 lines of ~160 characters


def _cells(row: str) -> int:
    return len(re.sub(r"\\\|", "", row).strip().strip("|").split("|"))


@pytest.mark.parametrize("topic", sorted(PLANS))
def test_a_report_is_its_plan_on_one_store_and_reads_in_a_minute(topic):
    text = (REPORTS / f"{topic}.md").read_text()
    lines = text.splitlines()
    assert lines[2].startswith(f"Built by `hrc-lab-report {topic}`") and "from the store `" in lines[2]
    assert "at commit `" in lines[3] or lines[3] == "Runs: none finished in this store yet.", \
        "the header names the commit the runs ran at"
    assert len(lines) <= MAX_LINES, f"{len(lines)} lines"
    if PLANS[topic].rows:
        assert lines.index("## The thesis' results beside ours") < next(
            i for i, line in enumerate(lines) if line.startswith("## ") and "thesis' results" not in line)
    for line in lines:
        if line.startswith("## "):
            assert len(line) - 3 < MAX_TITLE, line
        elif line.startswith("|"):
            assert _cells(line) <= MAX_COLUMNS, line[:200]
        elif line and not line.startswith(("![", "[", "<a ", "Reproduce:", "Built by", "Runs:", "**Question.**")):
            assert len(line) <= MAX_CAPTION, line[:200]


def test_every_study_of_a_plan_has_its_section_and_its_table_in_the_report():
    for topic, plan in PLANS.items():
        text = (REPORTS / f"{topic}.md").read_text()
        for study in plan.studies:
            assert f'<a id="{study.key}"></a>' in text, (topic, study.key)
            assert f"Reproduce: `{study.command}`" in text or "Not run yet" in text, (topic, study.key)


def test_the_scoreboard_has_a_row_for_every_headline_row_of_every_plan():
    board = (REPORTS / "README.md").read_text()
    for plan in PLANS.values():
        for row in plan.rows:
            if row.headline:
                assert f"| {row.table}, {row.name}" in board, (plan.topic, row.table, row.name)
