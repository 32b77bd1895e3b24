"""The Ch.4 motion report (hrc_lab/report/ch4_motion.py): Table 4.2's section from runs as the experiment logs them,
its results (SR and R² rows) against the thesis' rows, and the report built end to end from a tiny job."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from hrc_lab.report.ch4_motion import PLAN, r2_row
from hrc_lab.report.headline import thesis_rows
from hrc_lab.report.sections import SECTIONS, load_sections


def _runs() -> pd.DataFrame:
    return pd.DataFrame({"method": ["tc_vi", "tc_vi", "mlp"], "cell": ["4of5"] * 3, "seed": [0, 1, 0],
                         "sr": [0.9, 0.8, 0.2], "r2": [0.99, 0.97, 0.6], "fail_collision": [0.1, 0.2, 0.8],
                         "planning_ms": [0.3, 0.5, 0.2], "pick_span_x_m": [0.35] * 3, "pick_span_y_m": [0.15] * 3,
                         "goal_span_x_m": [0.35] * 3, "goal_span_y_m": [0.28] * 3,
                         "param.protocol.cv_folds": ["3"] * 3, "param.protocol.demos": ["20"] * 3,
                         "param.env.sim.success_threshold": ["0.06"] * 3})


def test_table_4_2_section_states_its_conditions_and_writes_sr_and_r2_results():
    load_sections()
    section = SECTIONS["table_4_2"](_runs())
    text = re.sub(r" +", " ", section.markdown)
    assert "| Ours (task-conditioned VI) | 0.85 ± 0.05 (R² 0.98) |" in text
    assert "| MLP | 0.20 ± 0.00 (R² 0.60) |" in text
    assert "δr 0.06 m" in text and "3-fold cross-validated R²; trained on 20 scripted demonstrations" in text
    assert "Positions span picking 0.35 × 0.15 m, goals 0.35 × 0.28 m (Sec. 4.4.3: 0.3 × 0.15, 0.35 × 0.2)" in text
    assert "Ours plans a sub-goal in 0.40 ms (thesis 1.3 ms)" in text
    results = section.results.set_index(["row", "column"])
    assert results.loc[("tc_vi", "4of5"), "mean"] == pytest.approx(0.85)
    assert results.loc[(r2_row("tc_vi"), "4of5"), "mean"] == pytest.approx(0.98)
    table = section.table.set_index("method")
    assert table.loc["mlp", "fail_collision"] == 0.8 and table.loc["tc_vi", "thesis_r2"] == 0.97  # diagnostics: CSV
    assert "Positions span" not in SECTIONS["table_4_2"](_runs().drop(columns="goal_span_x_m")).markdown


def test_the_opening_table_reads_sr_and_r2_per_method():
    """Every row of the plan finds its result: SR rows the method's, R² rows the method's R² row; R² rows are in the
    report's opening table only, not the scoreboard."""
    load_sections()
    runs = pd.DataFrame({"method": [m for m in ("tc_vi", "vi", "gpr", "mlp") for _ in range(4)], "seed": 0,
                         "cell": ["2of3", "3of3", "3of5", "4of5"] * 4, "sr": 0.5, "r2": 0.9})
    rows = thesis_rows(PLAN, {"table_4_2": SECTIONS["table_4_2"](runs).results})
    ours = rows[rows.kind == "as written"]
    assert len(ours) == 32 and ours["mean"].tolist() == [0.5] * 16 + [0.9] * 16
    assert set(rows[rows.table == "Table 4.2, R²"].headline) == {False}
    mlp = ours[(ours.name == "MLP") & (ours.table == "Table 4.2, SR")]
    assert mlp.met.all()  # above the thesis' 0.06-0.26: within or above


def test_table_4_2_job_end_to_end(run_job, job_report):
    job = run_job("experiment=ch4/table_4_2", "hydra.mode=RUN", "env=package_to_order_2of3", "seed=0",
                  "trainer.max_epochs=1", "motion.steps=10", "motion.ndp.steps=10", "motion.classifier.steps=10",
                  "protocol.demos=3", "protocol.trials=2")
    report = job_report(job, "ch4_motion")
    opening = report.split("## The thesis' results beside ours")[1].split("\n## ")[0]
    assert "| MLP | thesis | 0.26 ± 0.04 | 0.12 ± 0.02 | 0.08 ± 0.02 | 0.06 ± 0.02 |  |" in opening
    assert "**Table 4.2, R²**" in opening and f"(R² {job.metrics['r2']:.2f})" in report
