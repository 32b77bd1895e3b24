"""The Ch.6 grasp report (hrc_lab/report/ch6_grasp.py): a tiny Table 6.1 job end to end (its section and the opening
table's thesis rows), and each section's table, results and CSV from the runs' metrics and params."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from test_grasp import TINY_CH6

from hrc_lab.report.ch6_grasp import PLAN
from hrc_lab.report.sections import SECTIONS, load_sections


def opening_of(report: str) -> str:
    return re.sub(r" +", " ", report.split("## The thesis' results beside ours")[1].split("\n## ")[0])


def test_table_6_1_job_end_to_end(run_job, job_report):
    """A tiny GNN_Att job (ground-truth boxes, so that the tiny detector's misses leave nodes to score): its
    section's row, and the opening table's GNN_Att row beside the thesis' (as written from this run), the other
    methods' rows without ours."""
    job = run_job("experiment=ch6/table_6_1", *TINY_CH6, "grasp=gnn_att", "grasp.detector.mode=oracle",
                  "protocol.test_images=2")
    oa = [job.metrics[f"oa_{k}"] for k in (1, 2, 3)]
    report = job_report(job, "ch6_grasp")
    opening = opening_of(report)
    assert "| GNN_Att | thesis | 1.00 | 0.91 ± 0.02 | 0.89 ± 0.02 | 0.88 ± 0.02 |" in opening
    cells = " | ".join(f"{value:.2f}" for value in (job.metrics["train_grasp_acc"], *oa))
    assert f"| | [as written (1 seed)](#table_6_1) | {cells} | our detector is trained" in opening
    assert "| GNN_Att w/o WE | thesis | 0.97 | 0.63 ± 0.01 |" in opening
    assert "| GVMRN_RF | thesis | | 0.39 ± 0.02 |" in opening  # no thesis Train_Acc: the column is not compared
    assert "| | [★ GNN_Rel_Att + depth](#table_6_1) | – | – | – | – |" in opening  # not among this job's runs
    section = report.split("## table_6_1 (this test's settings)")[1].split("\n## ")[0]
    assert "4 training scenes" in section and "2 unseen test scenes" in section
    assert f"| GNN_Att | {job.metrics['train_grasp_acc']:.3f} | {oa[0]:.3f} |" in re.sub(r" +", " ", section)
    assert "## table_6_2_single\n\nNot run yet: `hrc-lab experiment=ch6/table_6_2_single" in report


def method_runs(methods: dict[str, list[dict]], **common) -> pd.DataFrame:
    """Runs of each method, one per dict of metrics (its seed: the dict's position)."""
    return pd.DataFrame([{"method": method, "seed": seed, "cell": "clutter", "run_id": f"{method}{seed}", **common,
                          **metrics} for method, per_seed in methods.items() for seed, metrics in enumerate(per_seed)])


def test_table_6_1_section_gives_the_thesis_columns_and_keeps_its_diagnostics_in_the_csv():
    load_sections()
    seed = {"train_detected": 0.97, "train_part_grasp_acc": 0.95, "oa_type_a": 0.6, "oa_type_b": 0.9,
            "geometry_blockers_within_filter": 0.46, **{f"detected_{k}": 0.96 for k in (1, 2, 3)},
            **{f"fit_acc_{k}": 0.85 for k in (1, 2, 3)}}
    runs = method_runs({"gnn_att": [{**seed, "train_grasp_acc": 0.99, "oa_1": 0.7, "oa_2": 0.6, "oa_3": 0.5},
                                    {**seed, "train_grasp_acc": 1.0, "oa_1": 0.8, "oa_2": 0.7, "oa_3": 0.6}],
                        "gnn_rel_att_depth": [{**seed, "train_grasp_acc": 1.0, "oa_1": 0.9, "oa_2": 0.9, "oa_3": 0.9}]},
                       **{"param.grasp.detector.context_scale": "1.8"})
    section = SECTIONS["table_6_1"](runs)
    markdown = re.sub(r" +", " ", section.markdown)
    assert "| GNN_Att | 0.995 ± 0.005 | 0.750 ± 0.050 | 0.650 ± 0.050 | 0.550 ± 0.050 | 0.960 ± 0.000 |" in markdown
    assert "| ★ GNN_Rel_Att + depth (hrc_lab) | 1.000 | 0.900 |" in markdown.replace(" ± 0.000", "")
    results = section.results.set_index(["row", "column"])
    assert results.loc[("gnn_att", "two_types"), "mean"] == pytest.approx(0.65)
    assert results.loc[("gnn_att", "train_acc"), "n"] == 2
    assert set(results.index.get_level_values("column")) == {"train_acc", "one_type", "two_types", "three_types"}
    csv = section.table.set_index(["method", "metric"])
    assert csv.loc[("gnn_att", "oa_type_a"), "mean"] == pytest.approx(0.6)
    assert csv.loc[("gnn_att", "test_oa"), "mean"] == pytest.approx(0.65)  # pooled over the three request sizes
    assert "geometry_blockers_within_filter" in set(csv.index.get_level_values("metric"))
    assert "oa_type_a" not in section.markdown and section.artifacts["geometry.png"] == ("gnn_att0",
                                                                                        "figures/geometry.png")


def test_table_6_1_caption_reads_the_node_features_from_params_or_says_not_logged():
    load_sections()
    runs = method_runs({"gnn_att": [{"oa_1": 0.7}, {"oa_1": 0.8}]}, **{"param.grasp.detector.context_scale": "1.8"})
    assert "enlarged 1.8× (`grasp.detector.context_scale`" in SECTIONS["table_6_1"](runs).markdown
    off = SECTIONS["table_6_1"](runs.assign(**{"param.grasp.detector.context_scale": "0.0"})).markdown
    assert "no enlarged-box feature" in off and "1.8" not in off
    old = SECTIONS["table_6_1"](runs.drop(columns="param.grasp.detector.context_scale")).markdown
    assert "not logged" in old and "1.8" not in old


def test_table_6_2_section_gives_the_thesis_columns_and_the_failures_and_answer_lengths_in_the_csv(monkeypatch):
    from hrc_lab.report import ch6_grasp

    load_sections()
    failures = {"fail_detection_3": 0.1, "fail_graspability_3": 0.2, "fail_solution_3": 0.0, "fail_other_3": 0.0}
    runs = method_runs({"gnn_att": [{"acc_3": 0.7, **failures}, {"acc_3": 0.8, **failures}]},
                       **{"param.protocol.cases": "30"})
    cases = pd.DataFrame({"objects": [3, 3, 3, 3], "correct": [True, True, False, True], "iterations": [1, 1, 2, 1],
                          "help": [False, False, False, True], "rule_requests": [1, 2, 2, 1],
                          "run_id": ["gnn_att0", "gnn_att0", "gnn_att1", "gnn_att1"]})
    monkeypatch.setattr(ch6_grasp, "run_tables", lambda runs, name: cases if name == "table_6_2_single" else None)
    section = SECTIONS["table_6_2_single"](runs)
    assert "| GNN_Att | 0.750 ± 0.050 |" in re.sub(r" +", " ", section.markdown)
    assert "30 scenes per part count" in section.markdown and "graspability" not in section.markdown.split("\n")[-1]
    results = section.results
    assert list(results.column) == ["3"] and results["mean"].iloc[0] == pytest.approx(0.75)
    csv = section.table.set_index(["method", "metric", "objects"])
    assert csv.loc[("gnn_att", "fail_graspability_3", 3), "mean"] == pytest.approx(0.2)
    assert csv.loc[("gnn_att", "requests_per_answer", 3), "mean"] == pytest.approx(1.25)
    assert csv.loc[("gnn_att", "rule_one_request_enough", 3), "mean"] == pytest.approx(0.5)


def test_table_6_3_section_says_whose_data_it_read():
    load_sections()
    runs = method_runs({"gnn_att": [{"ia": 0.5, "ia_3": 0.7, "oa": 0.8}, {"ia": 0.6, "ia_3": 0.8, "oa": 0.9}],
                        "gvmrn_rf": [{"ia": 0.3, "ia_3": 0.4, "oa": 0.6}]},
                       written_by_hrc_lab=1.0, **{"param.protocol.train_images": "427",
                                                  "param.protocol.test_images": "50"})
    section = SECTIONS["table_6_3"](runs)
    assert "| GNN_Att | 0.550 ± 0.050 | 0.750 ± 0.050 | 0.850 ± 0.050 |" in re.sub(r" +", " ", section.markdown)
    assert "our 427 trainval and 50 test rendered scenes" in section.markdown
    assert "not VMRD v2 (31 classes), which cannot be downloaded here" in section.markdown
    assert section.results.set_index("row").loc["gvmrn_rf", "mean"] == pytest.approx(0.3)
    assert set(section.results.column) == {""}  # the thesis' Table 6.3 has one value per method
    theirs = SECTIONS["table_6_3"](runs.assign(written_by_hrc_lab=0.0, classes=31.0,
                                               **{"param.env.vmrd_root": "/data/VMRD", "param.env.image_size": "320"}))
    assert "Data: `/data/VMRD`, 31 classes, letterboxed to 320 px (`env.image_size`)." in theirs.markdown
    assert theirs.title == "Table 6.3: image-based accuracy (a data set in VMRD's layout)"


def fig_6_9_runs(grasp: list[float], solution: list[float]) -> pd.DataFrame:
    """Two seeds of Fig. 6.9 with these IAs per k = 1, 2, 3 (seed 1: +0.02), and on the 3-object images 0.05 more."""
    metrics = {f"types{k}_{stage}{suffix}": [value + extra, value + extra + 0.02]
               for stage, values in (("grasp_ia", grasp), ("solution_ia", solution))
               for k, value in zip((1, 2, 3), values, strict=True) for suffix, extra in (("", 0.0), ("_n3", 0.05))}
    metrics |= {f"types{k}_{name}": [value] * 2 for k in (1, 2, 3)
                for name, value in (("test_images", 50.0), ("objects", 3.0 + k), ("ia", 0.5), ("train_grasp_acc", 1.0))}
    return pd.DataFrame({"method": ["gnn_att"] * 2, "seed": [0, 1], "cell": ["clutter"] * 2, "run_id": ["r0", "r1"],
                         **metrics})


def test_fig_6_9_section_gives_both_stages_per_k_and_judges_the_thesis_statement():
    load_sections()
    section = SECTIONS["fig_6_9"](fig_6_9_runs(grasp=[0.8, 0.78, 0.76], solution=[0.7, 0.5, 0.3]))
    markdown = re.sub(r" +", " ", section.markdown)
    assert "| 2 | 50 | 5 | 0.790 ± 0.010 | 0.510 ± 0.010 | 0.840 ± 0.010 | 0.560 ± 0.010 |" in markdown
    assert "last columns: the 3-object images" in markdown and set(section.figures) == {"fig_6_9.png"}
    (claim,) = section.results.to_dict("records")
    assert claim["text"] == "k 1 → 3: GNN 0.81 → 0.77, LSTM_Att 0.71 → 0.31" and claim["met"] is True
    falls = SECTIONS["fig_6_9"](fig_6_9_runs(grasp=[0.8, 0.5, 0.3], solution=[0.4, 0.4, 0.35]))
    assert falls.results["met"].tolist() == [False]  # the GNN falls more than the solutions: not the thesis' curves
    assert falls.table.groupby("metric").types.apply(list)["solution_ia"] == [1, 2, 3]


def test_the_plan_has_a_row_per_thesis_row_and_its_ablations_ask_a_question():
    rows = {(row.table, row.name) for row in PLAN.rows}
    assert {name for table, name in rows if table == "Table 6.1"} == {
        "GNN_Att", "GNN_Att w/o WE", "GNN_LSTM", "GNN_DF_Att", "GVMRN_RF", "GCN_Att"}
    assert {name for table, name in rows if table == "Table 6.3"} == {"VMRN", "GVMRN_RF", "GNN_Att"}
    ablations = [study for study in PLAN.studies if study.ablation]
    assert len(ablations) <= 6 and all(study.question for study in ablations)
    linked = {key for row in PLAN.rows for key in re.findall(r"\(#(\w+)\)", row.why)}
    assert linked <= {study.key for study in PLAN.studies} and {study.key for study in ablations} <= linked
    assert all(not re.search(r"\b\d", row.why) for row in PLAN.rows)  # no number typed into a why
