"""The Ch.3 motion report (hrc_lab/report/ch3_motion.py): Table 3.1's and Fig. 3.10's sections from small frames of
runs (their table, CSV and results), the thesis rows they open the report with, and a tiny Table 3.1 job built
into the report end to end."""

from __future__ import annotations

import re

import matplotlib.pyplot as plt
import pandas as pd
import pytest

from hrc_lab.report.ch3_motion import PLAN, fig_3_10, result_row, table_3_1
from hrc_lab.report.headline import opening_tables, thesis_rows


def _table_3_1_runs(**changes) -> pd.DataFrame:
    rows = [{"method": method, "scenario": "two_object_case1", "seed": seed, "run_id": f"{method}{seed}",
             "sr_blue_0.08": 0.6 + 0.1 * seed, "sr_blue_0.06": 0.5, "sr_red_0.08": red, "sr_red_0.06": red,
             "steps_blue": 40.0 + seed, "steps_red": 50.0, "fail_pick": 0.9, "stage1_right": 1.0,
             "stage2_right": 0.6 + 0.2 * seed, "stage2_pick_xy_m": 0.08, "stage2_moved_error_m": 0.03, **changes}
            for method, red in (("tc_vi", 0.0), ("tc_vi_object", 0.7)) for seed in (0, 1)]
    return pd.DataFrame(rows)


def test_table_3_1_section_tabulates_each_planner_and_gives_the_opening_rows_their_results():
    section = table_3_1(_table_3_1_runs())
    plt.close("all")
    lines = [re.sub(" +", " ", line) for line in section.markdown.splitlines() if line.startswith("| two object")]
    assert len(lines) == 2  # one line per (case, object), one column per planner
    assert "| blue " in lines[0] and "0.64" in lines[0] and "0.65 ± 0.05" in lines[0]
    assert "| red " in lines[1] and "0.00 ± 0.00" in lines[1] and "0.70 ± 0.00" in lines[1]
    assert max(len(line.split("|")) - 2 for line in lines) <= 8
    results = section.results.set_index(["row", "column"])
    red = result_row("tc_vi_object", "two_objects", "case1_red")
    assert results.loc[(red, "sr_at_0.08"), "mean"] == pytest.approx(0.7) and results.loc[(red, "sr_at_0.08"), "n"] == 2
    # one count of steps per object, scored at both thresholds
    blue = result_row("tc_vi", "two_objects", "case1_blue")
    assert results.loc[(blue, "steps_at_0.08"), "mean"] == results.loc[(blue, "steps_at_0.06"), "mean"] == 40.5
    # the CSV keeps where each object's own picking stage went: red is moved second
    csv = section.table.set_index(["method", "object"])
    assert csv.loc[("tc_vi", "red"), "pick_right"] == pytest.approx(0.7)
    assert csv.loc[("tc_vi", "blue"), "pick_right"] == 1.0 and csv.loc[("tc_vi", "red"), "fail_pick"] == 0.9
    assert "placement_oracle" not in section.markdown


def test_table_3_1_section_with_the_placement_oracle_says_which_part_c_x_went_for():
    section = table_3_1(_table_3_1_runs(**{"param.protocol.placement_oracle": "True"}))
    plt.close("all")
    assert "set onto its goal before the next stage" in section.markdown
    assert "c(x) picked the expert's part at 0.70 of the second stages" in section.markdown


def test_table_3_1_rows_compare_steps_as_fewer_is_better():
    """The opening table's Table 3.1 row: SR within the thesis' spread or above, steps within it or fewer."""
    thesis_steps = 43.11  # two objects, case 1, red: thesis_results.yaml ch3.table_3_1
    results = {"table_3_1": pd.DataFrame(
        [{"row": result_row(method, "two_objects", "case1_red"), "column": column, "mean": mean, "std": 0.0, "n": 3}
         for method, steps in (("tc_vi", thesis_steps + 10), ("tc_vi_object", thesis_steps - 10))
         for column, mean in (("sr_at_0.08", 0.7), ("sr_at_0.06", 0.7), ("steps_at_0.08", steps),
                              ("steps_at_0.06", steps))])}
    rows = thesis_rows(PLAN, results)
    red = rows[(rows.name == "Two objects, case 1: red") & (rows.kind != "thesis")].set_index(["kind", "column"])
    assert red.loc[("as written", "sr_at_0.08"), "met"] and not red.loc[("as written", "steps_at_0.08"), "met"]
    assert red.loc[("★", "steps_at_0.08"), "met"] and red.loc[("★", "steps_at_0.06"), "met"]
    table = "\n".join(opening_tables(PLAN, rows))
    assert "| Two objects, case 1: red | thesis | 0.61 ± 0.02 | 0.51 ± 0.04 | 43.11 ± 3.31 |" in table
    assert "[★ tc_vi_object ✓](#table_3_1)" in table and "(#table_3_1_oracle)" in table


def _fig_3_10_runs() -> pd.DataFrame:
    # two seeds' mean-distance curves over 4 steps: the NDP falls below 0.02 m, the actor never does
    curves = {"ndp": [(0.2, 0.05, 0.015, 0.018), (0.2, 0.03, 0.019, 0.01)],
              "actor": [(0.2, 0.1, 0.05, 0.09), (0.2, 0.08, 0.06, 0.1)]}
    rows = []
    for seed in (0, 1):
        row = {"seed": seed, "run_id": f"r{seed}", "param.protocol.converged_m": "0.02",
               "reached_ndp": 0.9, "reached_actor": 0.1}
        for name, values in curves.items():
            row |= {f"curve_{name}_{step:02d}": value for step, value in enumerate(values[seed])}
        rows.append(row)
    return pd.DataFrame(rows)


def test_fig_3_10_section_reads_each_seed_s_curve_for_the_lowest_distance_and_the_first_step_below():
    section = fig_3_10(_fig_3_10_runs())
    plt.close("all")
    results = section.results.set_index(["row", "column"])
    assert results.loc[("ndp", "below_m"), "mean"] == pytest.approx((0.015 + 0.01) / 2)
    assert results.loc[("ndp", "steps"), "mean"] == pytest.approx((2 + 2) / 2)
    assert results.loc[("ndp", "steps"), "n"] == 2
    assert pd.isna(results.loc[("actor", "steps"), "mean"])  # never below: no step
    claim = results.loc[("actor", "")]
    assert claim["met"] and "lowest mean ‖Δ‖ 0.055 m (step 2), 0.095 m at step 3" in claim["text"]
    ndp = next(re.sub(" +", " ", line) for line in section.markdown.splitlines()
               if line.startswith("| neural dynamic planner"))
    assert "| 2.5 ± 0.5 | 2.0 ± 0.0 " in ndp and "| 0.90 ± 0.00 |" in ndp  # at step, first step below
    rows = thesis_rows(PLAN, {"fig_3_10": section.results})
    ndp_rows = rows[(rows.table == "Fig. 3.10") & (rows.kind == "as written") & (rows.text == "")]
    assert ndp_rows.met.all()  # lower and fewer than the thesis' 0.02 m and 15 steps


def test_table_3_1_job_end_to_end(run_job, job_report):
    job = run_job("experiment=ch3/table_3_1", "hydra.mode=RUN", "env=error_correction_two_object_case1",
                  "motion=tc_vi_object", "seed=0", "trainer.max_epochs=1", "motion.steps=20", "motion.ndp.steps=20",
                  "motion.classifier.steps=20", "protocol.demos=2", "protocol.trials=2")
    report = job_report(job, "ch3_motion")
    opening = report.split("## The thesis' results beside ours")[1].split("\n## ")[0]
    lines = opening.splitlines()
    blue = lines.index("| Two objects, case 1: blue | thesis | 0.64 ± 0.01 | 0.54 ± 0.03 | 41.35 ± 2.16 | 48.35 ± 4.61 "
                       "|  |")
    assert lines[blue + 2].startswith("|  | [★ tc_vi_object (1 seed)](#table_3_1) | "
                                      f"{job.metrics['sr_blue_0.08']:.2f} | {job.metrics['sr_blue_0.06']:.2f} |")
    assert "Not run yet: `hrc-lab experiment=ch3/fig_3_10 hydra/launcher=joblib`" in report
