"""The Ch.4 reasoning report (hrc_lab/report/ch4_reasoning.py): its sections from runs as the experiments log them,
their results against the thesis' rows, and the report built end to end from a tiny Table 4.1 job."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from test_reports import DEFAULT_SWEEP, TITLE, log_run, row_of, section_text, store  # noqa: F401

from hrc_lab.report.build import build_topic
from hrc_lab.report.ch4_reasoning import PLAN, point_row, scenario_row, stated_points
from hrc_lab.report.headline import thesis_rows
from hrc_lab.report.sections import SECTIONS, load_sections

HEADS = {"acc_o_pick": 0.6, "acc_o_place": 1.0, "acc_g_pick": 1.0, "acc_g_place": 0.99}
ERRORS = {"pick_error_area": 0.1, "pick_error_packed": 0.05, "pick_error_unselected": 0.3, "pick_error_other": 0.0}


def test_a_section_of_one_seed_prints_no_spread_and_says_so(store, tmp_path):  # noqa: F811
    """Issue 44 item 5: a section whose runs have one seed prints its cells without a "± 0.00" that would read as a
    measured spread, and says in words that it is one seed; the thesis' values and the CSV keep their numbers. With a
    second seed the cells are mean ± std again, a real zero spread included."""
    out = tmp_path / "reports"
    one = section_text(build_topic("ch4_reasoning", store.tracking_uri, out).read_text(), TITLE)
    assert re.sub(r" +", " ", row_of(one)) == "| Ours | 0.70 (1.00) | 0.90 (1.00) |"
    assert "one seed (0): no spread" in one and "mean ± std over seeds" not in one
    table = pd.read_csv(out / "ch4_reasoning" / "table_4_1.csv")
    assert table.sr_std.tolist() == [0.0, 0.0] and table.seeds.tolist() == [1, 1]
    assert table.latency_ms_batch1.tolist() == [1.25, 1.25]  # the diagnostics go to the CSV

    log_run(store, cell="3of5", sweep=DEFAULT_SWEEP, sr=0.7, seed=1)
    log_run(store, cell="4of5", sweep=DEFAULT_SWEEP, sr=0.8, seed=1)
    two = section_text(build_topic("ch4_reasoning", store.tracking_uri, out).read_text(), TITLE)
    assert re.sub(r" +", " ", row_of(two)) == "| Ours | 0.70 ± 0.00 (1.00) | 0.85 ± 0.05 (1.00) |"
    assert "mean ± std over seeds [0, 1]" in two and "one seed" not in two


def test_table_4_1_states_its_training_and_test_conditions():
    """The caption reads the training length, position frame and folds from the runs' params and the position spans
    from their metrics, beside Sec. 4.4.3's ranges; an ablation's frame reads as its own."""
    load_sections()
    runs = pd.DataFrame({"method": ["ours", "mlp"], "cell": ["3of5", "4of5"], "seed": [0, 0], "sr": [1.0, 0.5],
                         "pick_span_x_m": [0.35, 0.34], "pick_span_y_m": [0.15, 0.15], "goal_span_x_m": [0.16, 0.43],
                         "goal_span_y_m": [0.0, 0.28], "latency_ms_batch1": [1.4, 1.0],
                         "param.reasoning.steps": ["1000"] * 2, "param.protocol.n_folds": ["5"] * 2})
    section = SECTIONS["table_4_1"](runs)
    text = section.markdown
    assert "after 1000 training steps (`reasoning.steps`)" in text and "fold k of 5" in text
    assert "positions relative to the table top's centre, in decimetres (`reasoning.position_frame`)" in text
    assert "Positions span picking 0.35 × 0.15 m, goals 0.43 × 0.28 m (Sec. 4.4.3: 0.3 × 0.15, 0.35 × 0.2)" in text
    assert "Ours decides in 1.4 ms at batch 1 (thesis 5 ms)" in text
    assert "| MLP | – (0.96) | 0.50 (0.86) |" in re.sub(r" +", " ", text)  # thesis mean in brackets
    world = SECTIONS["table_4_1"](runs.assign(**{"param.reasoning.position_frame": ["world_m"] * 2})).markdown
    assert "positions in the world frame, in metres (`reasoning.position_frame`)" in world
    assert "Positions span" not in SECTIONS["table_4_1"](runs.drop(columns="pick_span_x_m")).markdown
    results = section.results.set_index(["row", "column"])
    assert results.loc[("mlp", "4of5"), "mean"] == 0.5 and results.loc[("ours", "3of5"), "n"] == 1


def _fig_4_7_runs() -> pd.DataFrame:
    """Two seeds of ours in 3of5 and 4of5 with every λ the thesis states a point at, per-head accuracies logged."""
    rows = []
    for seed in (0, 1):
        for cell in ("3of5", "4of5"):
            row = {"method": "ours", "cell": cell, "seed": seed, "param.protocol.case2_tests": "300"}
            for case, sr in (("case1", 0.2 + 0.2 * seed), ("case2", 0.5)):
                for lam in ("0.6", "0.8", "1.0"):
                    row |= {f"{case}_sr_lam{lam}": sr, f"{case}_n_train_demos_lam{lam}": 96.0,
                            **{f"{case}_{k}_lam{lam}": v for k, v in (HEADS | ERRORS).items()}}
            rows.append(row)
    return pd.DataFrame(rows)


def test_fig_4_7_section_gives_the_thesis_points_and_where_ours_fails():
    """The section's table holds the thesis' stated points (λ of CASE 1's 4of5 point from the thesis' 24 unseen
    configurations), its results one row per (method, case, λ) and the 4of5 claim's text, and one line names the
    weakest head, all computed from the runs; the per-head means go to the CSV."""
    load_sections()
    assert stated_points() == [("case1", "3of5", 0.6), ("case1", "4of5", 0.8), ("case2", "3of5", 1.0),
                               ("case2", "4of5", 1.0)]
    section = SECTIONS["fig_4_7"](_fig_4_7_runs())
    cells = re.sub(r" +", " ", section.markdown)
    assert "| CASE 1 3of5 λ=0.6 | CASE 1 4of5 λ=0.8 | CASE 2 3of5 λ=1 | CASE 2 4of5 λ=1 |" in cells
    assert "| Ours | 0.30 ± 0.10 | 0.30 ± 0.10 | 0.50 ± 0.00 | 0.50 ± 0.00 |" in cells
    assert ("Where ours scores below 0.95, its weakest head: CASE1 (6 points) P_o pick 0.60 (others 0.99 or more), "
            "wrong picks mostly to unselected products (0.30 of picking stages); CASE2 (6 points)") in section.markdown
    results = section.results.set_index(["row", "column"])
    assert results.loc[(point_row("ours", "case1", 0.6), "3of5"), "mean"] == pytest.approx(0.3)
    claim = results.loc[(point_row("ours", "case1", 0.8), "")]
    assert claim["text"] == "0.30 ± 0.10, 96 demonstrations" and not claim["met"]
    assert section.table.set_index(["case", "ratio", "cell"]).loc[("case1", 0.6, "3of5"), "acc_o_pick"] == 0.6
    handled = _fig_4_7_runs()
    handled["case1_sr_lam0.8"] = 1.0
    assert SECTIONS["fig_4_7"](handled).results.set_index(["row", "column"]).loc[
        (point_row("ours", "case1", 0.8), ""), "met"]
    assert "weakest head" not in SECTIONS["fig_4_7"](_fig_4_7_runs().filter(regex="^(?!.*acc_)")).markdown


def test_practical_section_transposes_the_scenarios_and_fills_the_thesis_rows():
    load_sections()
    runs = pd.DataFrame({"method": ["ours", "ours", "mlp"], "seed": [0, 1, 0], "cell": ["3of5"] * 3,
                         "missing_sr": [0.9, 1.0, None], "order_size_3of5_case1_sr": [0.6, 0.8, 0.3],
                         "order_size_3of5_case2_sr": [0.5, 0.5, 0.1], "param.protocol.partial_demos": ["50"] * 3,
                         "param.protocol.train_selected": ["2"] * 3, "param.env.n_objects": ["5"] * 3})
    section = SECTIONS["practical"](runs)
    cells = re.sub(r" +", " ", section.markdown)
    assert "| thesis (ours) | – | 0.97 | 0.97 | 0.91 | 0.92 | 0.86 |" in cells and "trained on 2of5" in cells
    assert "| Ours | n/a | 0.95 ± 0.05 | 0.70 ± 0.10 | 0.50 ± 0.00 | n/a | n/a |" in cells
    assert "| MLP | n/a | n/a | 0.30 ± 0.00 | 0.10 ± 0.00 | n/a | n/a |" in cells  # no input of varying size
    results = section.results.set_index(["row", "column"])
    assert results.loc[(scenario_row("ours", "missing"), ""), "mean"] == pytest.approx(0.95)
    assert results.loc[(scenario_row("mlp", "3of5"), "case2"), "mean"] == pytest.approx(0.1)
    assert (scenario_row("mlp", "missing"), "") not in results.index  # not run: no result


def test_fig_4_9_section_states_the_claim_and_the_spread_over_seeds():
    load_sections()
    runs = pd.DataFrame({"seed": [0, 1], "run_id": ["a", "b"],
                         "case1_picking_importance_I": [0.4, 0.1], "case1_picking_importance_y": [0.3, 0.3],
                         "case1_placing_importance_z": [0.5, 0.5], "case1_placing_importance_y": [0.1, 0.1]})
    section = SECTIONS["fig_4_9"](runs)
    assert "| case1 | picking | 0.30 ± 0.00 | – | 0.25 ± 0.15 |" in re.sub(r" +", " ", section.markdown)
    assert "by less than the spread in case1 picking" in section.markdown
    assert section.results.text.iloc[0] == "largest share picking: y; placing: z" and not section.results.met.iloc[0]
    runs["case1_picking_importance_I"] = [0.6, 0.62]
    decisive = SECTIONS["fig_4_9"](runs)
    assert "leads the next by more than their seed spread in case1 picking (I 0.61 vs y 0.30)" in decisive.markdown
    assert decisive.results.met.iloc[0]  # I at picking, z at placing: the thesis' statement
    assert set(section.table.columns) >= {"importance_mean", "importance_std"}


def test_every_row_of_the_plan_reads_a_result_its_section_writes():
    """Each thesis row's picks name a (row, column) that the section builders write for such runs (a typo in a pick
    leaves the opening table's cell empty)."""
    load_sections()
    fig = SECTIONS["fig_4_7"](_fig_4_7_runs().assign(method="hrc")).results
    fig = pd.concat([fig, fig.assign(row=fig.row.str.replace("hrc", "ours"))])
    practical = pd.DataFrame({"method": ["ours", "hrc"], "seed": [0, 0], "cell": ["3of5"] * 2,
                              "missing_sr": [0.9, 1.0], **{f"order_size_{s}_{c}_sr": [0.5, 1.0]
                                                          for s in ("3of5", "4of5") for c in ("case1", "case2")}})
    table = pd.DataFrame({"method": ["ours", "hrc", "gnn", "gnn_task", "mlp", "rf"] * 4, "seed": 0, "sr": 1.0,
                          "cell": [c for c in ("2of3", "3of3", "3of5", "4of5") for _ in range(6)]})
    results = {"table_4_1": SECTIONS["table_4_1"](table).results, "fig_4_7": fig,
               "practical": SECTIONS["practical"](practical).results,
               "fig_4_9": SECTIONS["fig_4_9"](pd.DataFrame({"seed": [0], "run_id": ["a"],
                                                              "case1_picking_importance_I": [1.0]})).results}
    rows = thesis_rows(PLAN, results)
    ours = rows[rows.kind != "thesis"]
    assert len(ours) and (ours["mean"].notna() | (ours["text"] != "")).all(), ours[["name", "kind", "column"]]


def test_table_4_1_job_end_to_end(run_job, job_report):
    """A tiny Table 4.1 job and the report built from its store: the opening table has the thesis' rows as
    published beside the job's, and the studies the store has no runs of say so."""
    job = run_job("experiment=ch4/table_4_1", "hydra.mode=RUN", "env=package_to_order_3of5", "reasoning=ours",
                  "seed=0", "trainer.max_epochs=1", "reasoning.steps=20", "protocol.min_demos=10")
    report = job_report(job, "ch4_reasoning")
    opening = report.split("## The thesis' results beside ours")[1].split("\n## ")[0]
    assert "| GNN-task | thesis | 0.83 ± 0.01 | 0.72 ± 0.02 | 0.58 ± 0.02 | 0.24 ± 0.03 |  |" in opening
    ours = next(line for line in opening.splitlines() if line.startswith("|  | [as written (1 seed)"))
    assert f"{job.metrics['sr']:.2f}" in ours
    assert "## table_4_1 (this test's settings)" in report and "Not run yet: `hrc-lab experiment=ch4/fig_4_9" in report
