"""The Ch.3 guided-RL report (hrc_lab/report/ch3_rl.py): the curve summaries (each subtask's last epochs or its
whole curve), the Fig. 3.13 / 3.12 sections and their claims, Fig. 3.9's results, from small frames of runs whose
metric histories are monkeypatched. (A tiny Fig. 3.13 job built into the report: tests/test_ch3_rl.py.)"""

from __future__ import annotations

import re

import matplotlib.pyplot as plt
import pandas as pd
import pytest

from hrc_lab.report import ch3_rl
from hrc_lab.report.ch3_rl import PLAN, by_subtask, curves_section, epochs_sr, fig_3_9, guided_claim, hybrid_claim
from hrc_lab.report.headline import thesis_rows

FINAL = ("final_success_rate", "final_policy_success_rate", "best_success_rate", "final_distance",
         "final_grip_rate", "final_collision_rate")


def _rows(markdown: str, start: str) -> list[str]:
    return [re.sub(" +", " ", line) for line in markdown.splitlines() if line.startswith(start)]


def test_epoch_sr_pools_each_subtasks_last_epochs_or_its_whole_curve():
    """Epoch k * epochs + e is epoch e of subtask k: the last epochs, or all of them (the area under the learning
    curve over its length, how fast an arm learns), are pooled per subtask, then averaged over subtasks."""
    runs = pd.DataFrame({"run_id": ["a"], "param.protocol.epochs": ["2"]})
    curve = pd.DataFrame({"run_id": ["a"] * 4, "step": [1, 2, 3, 4], "value": [0.0, 0.4, 0.6, 1.0]})
    assert epochs_sr(runs, curve)["a"] == pytest.approx((0.2 + 0.8) / 2)
    assert epochs_sr(runs, curve, last=1)["a"] == pytest.approx((0.4 + 1.0) / 2)


def test_sr_by_subtask_keeps_each_value_in_its_subtasks_place():
    """A subtask no row logged reads "–" before a later subtask's value, and is left off after the last value."""
    columns = ["s0", "s1", "s2"]
    assert by_subtask(pd.DataFrame({"s0": [float("nan")] * 2, "s1": [0.2, 0.4], "s2": [float("nan")] * 2},
                                   columns=columns)) == "– / 0.30"
    assert by_subtask(pd.DataFrame({"s0": [0.9, 0.7], "s1": [0.1, 0.3]}, columns=columns)) == "0.80 / 0.20"
    assert by_subtask(pd.DataFrame({"s0": [float("nan")]}, columns=columns)) == "–"


def _curve_runs(scenario: str, lams=("0", "0.7", "1"), finals=(0.0, 0.9, 0.8)) -> pd.DataFrame:
    return pd.DataFrame([{"run_id": f"{scenario}{lam}{seed}", "scenario": scenario, "seed": seed,
                          "param.rl.lam": lam, "param.protocol.epochs": "2", **{c: final for c in FINAL}}
                         for lam, final in zip(lams, finals) for seed in (0, 1)])


def test_a_curves_section_gives_each_lambda_a_row_its_results_and_a_tidy_csv(monkeypatch):
    """Two-object runs get each subtask's final-policy SR beside the plan's; the results are the final policies'
    SR per λ and experiment; the CSV holds the curve and every summary with its spread."""
    runs = _curve_runs("two_object_case1").assign(final_policy_success_rate_subtask0=0.9,
                                                  final_policy_success_rate_subtask1=0.5)
    curve = pd.DataFrame([{"run_id": run, "step": step, "value": 0.25 * step} for run in runs.run_id
                          for step in (1, 2, 3, 4)])
    monkeypatch.setattr(ch3_rl, "histories", lambda runs, metric: curve)
    section = curves_section(runs, "t", "intro", "x.png")
    plt.close("all")
    hybrid = _rows(section.markdown, "| two object case1 | 0.7 |")
    assert len(hybrid) == 1 and "| 0.90 ± 0.00 | 0.90 / 0.50 |" in hybrid[0]
    assert "| 0.62 ± 0.00 |" in hybrid[0]  # SR over epochs: each subtask's mean (0.375, 0.875) averaged
    assert len(_rows(section.markdown, "| experiment ")[0].split("|")) - 2 <= 8
    results = section.results.set_index(["row", "column"])
    assert results.loc[("0.7", "two_objects"), "mean"] == 0.9 and results.loc[("0.7", "two_objects"), "n"] == 2
    csv = section.table
    assert set(csv.metric) >= {"success_rate", "final_policy_success_rate", "final_collision_rate"}
    assert csv[(csv.metric == "success_rate") & (csv.lam == "1")].epoch.tolist() == [1, 2, 3, 4]
    # one-subtask runs: no by-subtask column
    one = curves_section(_curve_runs("one_object_case1"), "t", "intro", "x.png")
    plt.close("all")
    assert "by subtask" not in one.markdown


def test_fig_3_13_claim_holds_only_when_the_hybrid_ends_above_both_other_arms():
    results = pd.DataFrame([{"row": lam, "column": column, "mean": mean} for column, values in
                            (("one_object", (0.0, 0.9, 0.8)), ("two_objects", (0.0, 0.85, 0.9)))
                            for lam, mean in zip(("0", "0.7", "1"), values)])
    claim = hybrid_claim(results)
    assert claim["text"] == "λ 0 / 0.7 / 1: one object 0.00 / 0.90 / 0.80; two objects 0.00 / 0.85 / 0.90"
    assert claim["met"] is False  # two objects: full guidance ahead
    results.loc[(results.column == "two_objects") & (results.row == "1"), "mean"] = 0.5
    assert hybrid_claim(results)["met"] is True
    assert hybrid_claim(results[results.row != "0"])["met"] is None  # an arm missing: not compared


def test_fig_3_12_claim_reads_the_unguided_arm_of_the_default_runs_where_an_ablation_has_none(monkeypatch):
    curve = pd.DataFrame([{"run_id": run, "step": 1, "value": value}
                          for run, value in (("g0", 0.4), ("g1", 0.2), ("u0", 0.0), ("u1", 0.1))])
    monkeypatch.setattr(ch3_rl, "histories", lambda runs, metric: curve[curve.run_id.isin(runs.run_id)])
    runs = pd.DataFrame({"run_id": ["g0", "g1"], "scenario": ["place", "place"], "seed": [0, 1],
                         "param.rl.lam": ["1", "1"], "param.protocol.epochs": ["1", "1"]})
    default = pd.DataFrame({"run_id": ["u0", "u1"], "scenario": ["place", "place"], "seed": [0, 1],
                            "param.rl.lam": ["0", "0"], "param.protocol.epochs": ["1", "1"]})
    monkeypatch.setattr(ch3_rl, "default_runs_of", lambda runs: default)
    claim = guided_claim(runs)
    assert claim["met"] is True
    assert claim["text"] == "SR over epochs, guided / unguided: place 0.30 / 0.05 (unguided: the default study's runs)"
    monkeypatch.setattr(ch3_rl, "default_runs_of", lambda runs: pd.DataFrame())
    assert guided_claim(runs)["met"] is None  # nothing to compare with


def test_fig_3_9_results_are_the_guided_95th_percentile_per_task(monkeypatch):
    monkeypatch.setattr(ch3_rl, "histories", lambda runs, metric: pd.DataFrame(columns=["run_id", "step", "value"]))
    runs = pd.DataFrame([{"run_id": f"{task}{seed}", "scenario": task, "seed": seed, "param.protocol.within_m": "0.15",
                          "param.motion.ndp.mode": "direction", "p95_distance_guided": p95,
                          "p95_distance_unguided": 0.3, "within_0.15_guided": 1.0}
                         for task, p95 in (("place", 0.12), ("stack", 0.2)) for seed in (0, 1)])
    section = fig_3_9(runs)
    plt.close("all")
    rows = thesis_rows(PLAN, {"fig_3_9": section.results})
    guided = rows[(rows.table == "Fig. 3.9") & (rows.kind == "as written")].set_index("column")
    assert guided.loc["place", "mean"] == 0.12 and guided.loc["place", "met"]
    assert not guided.loc["stack", "met"]  # above the thesis' 0.15 m
    assert "| place | guided | – | 0.120 ± 0.000 | 1.00 ± 0.00 |" in "\n".join(_rows(section.markdown, "| place"))
