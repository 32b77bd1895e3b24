"""The Ch.5 planner report (hrc_lab/report/ch5_planner.py): Fig. 5.7's section and its thesis row from a tiny job,
and Table 5.2's planner columns from the runs' metrics and params."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from hrc_lab.report.sections import SECTIONS, load_sections


def opening_of(report: str) -> str:
    return report.split("## The thesis' results beside ours")[1].split("\n## ")[0]


def test_fig_5_7_job_end_to_end(run_job, job_report):
    """A tiny Fig. 5.7 job at three goals (beside λ the schema trains a planner on the thesis' 143 scenarios): the
    section's table has a row per training set and the best possible, and the opening table puts the 143-scenario
    success rate beside the thesis' 0.963."""
    job = run_job("experiment=ch5/fig_5_7", "hydra.mode=RUN", "env=ato_3goals", "seed=0", "trainer.max_epochs=2",
                  "reasoning.steps=40", "protocol.ratios=[0.5]")
    sr = job.metrics["sr_n143"]
    assert 0 <= sr <= 1 and job.metrics["n_scenarios"] == 186
    report = job_report(job, "ch5_planner")
    opening = re.sub(r" +", " ", opening_of(report))
    assert "| Trained on 143 of 186 scenarios (3 goals) | thesis | 0.96 |" in opening
    assert f"| | [as written (1 seed)](#fig_5_7) | {sr:.2f} |" in opening.replace("|  |", "| |")
    section = re.sub(r" +", " ", report.split("## fig_5_7 (this test's settings)")[1])
    assert "| λ=0.5 | " in section and "| 143 scenarios | " in section and "| best possible | " in section
    assert "186 at 3goals" in section and "40 steps" in section
    assert "## table_5_2_planner\n\nNot run yet: `hrc-lab experiment=ch5/table_5_2_planner" in report  # no runs


def test_table_5_2_planner_reads_its_settings_and_gives_the_thesis_columns():
    load_sections()
    planner = pd.DataFrame({"cell": ["3goals", "3goals"], "seed": [0, 1], "sg_acc": [0.9, 0.8], "sc_acc": [0.8, 0.6],
                            "n_assembly_events": [40, 42], "n_screw_events": [12, 10], "latency_ms": [2.0, 3.0],
                            "param.protocol.sessions": ["20", "20"]})
    section = SECTIONS["table_5_2_planner"](planner)
    assert "20 generated sessions per goal count" in section.markdown and "2.1 ms on a GPU" in section.markdown
    assert "| 3 | 85.0 ± 5.0 | 70.0 ± 10.0 | 41 / 11 | 2.50 |" in re.sub(r" +", " ", section.markdown)
    results = section.results.set_index("column")
    assert results.loc["semantic_guidance", "mean"] == pytest.approx(85.0)
    assert results.loc["semantic_control", "std"] == pytest.approx(10.0)
    assert set(results["row"]) == {"3goals"} and set(results["n"]) == {2}
    old = SECTIONS["table_5_2_planner"](planner.drop(columns="param.protocol.sessions")).markdown
    assert "`protocol.sessions` not logged" in old
