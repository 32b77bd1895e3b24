"""Issue 49, item 1: every report section renders the part counts, cells and goal counts its runs have, also those
the thesis has no column for (a user's own ``5of6``, ``env.max_objects=7``, ``4goals``), with "–" where the thesis'
value would be; the thesis' own columns keep their values. Each builder is called directly on a small frame of runs
without ``param.logger.tracking_uri``, so no MLflow histories or tables are read."""

from __future__ import annotations

import math
import re

import matplotlib.pyplot as plt
import pandas as pd
import pytest

import hrc_lab.report.ch5_hrc
from hrc_lab.report.sections import SECTIONS, Section, load_sections
from hrc_lab.report.thesis import thesis_cells, thesis_value


def build(name: str, runs: pd.DataFrame) -> Section:
    load_sections()
    section = SECTIONS[name](runs)
    plt.close("all")
    return section


def rows(markdown: str) -> list[str]:
    """The markdown's table rows with their padding removed: "| 7 | 0.50 ± 0.10 (–) |"."""
    return [re.sub(r" +", " ", line) for line in markdown.splitlines() if line.startswith("|")]


def row_of(markdown: str, start: str) -> str:
    hits = [line for line in rows(markdown) if line.startswith(start)]
    assert len(hits) == 1, (start, rows(markdown))
    return hits[0]


def is_missing(value) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def test_thesis_cells_and_thesis_value():
    assert thesis_cells(["10of12", "5of6", "3of5", "2of3", float("nan")], ["2of3", "3of3", "3of5", "4of5"]) == [
        "2of3", "3of5", "5of6", "10of12"]
    assert thesis_cells([7, 3, 5], [3, 4, 5, 6]) == [3, 5, 7]
    assert thesis_value([0.962, 0.901, 0.864, 0.806], ["3", "4", "5", "6"], 4) == 0.901
    assert thesis_value([0.962, 0.901, 0.864, 0.806], ["3", "4", "5", "6"], 7) is None
    assert thesis_value(None, ["2of3"], "2of3") is None  # a method the thesis has no row for


# --- Ch.6: part counts (the crash of issue 49: protocol.object_counts=[3,7]) ---


def test_table_6_2_single_renders_a_part_count_the_thesis_has_no_column_for():
    runs = pd.DataFrame({"method": ["gnn_att", "gnn_att", "gnn_lstm"], "seed": [0, 1, 0], "run_id": ["a", "b", "c"],
                         "acc_3": [0.9, 0.8, 0.7], "acc_7": [0.5, 0.5, 0.4]})
    section = build("table_6_2_single", runs)
    header = rows(section.markdown)[0]
    assert "3 objects" in header and "7 objects" in header
    assert row_of(section.markdown, "| GNN_Att |") == "| GNN_Att | 0.850 ± 0.050 | 0.500 ± 0.000 |"
    assert row_of(section.markdown, "| GNN_LSTM |") == "| GNN_LSTM | 0.700 ± 0.000 | 0.400 ± 0.000 |"
    assert sorted(set(section.table.objects)) == [3, 7]
    assert sorted(set(section.results.column)) == ["3", "7"]  # the opening table reads the thesis' columns only


def test_table_6_2_robot_renders_a_part_count_the_thesis_has_no_column_for():
    runs = pd.DataFrame({"method": ["gnn_att"] * 2, "seed": [0, 1], "run_id": ["a", "b"], "acc_3": [0.9, 0.8],
                         "acc_7": [0.5, 0.5], "fail_slip_7": [0.5, 0.5]})
    section = build("table_6_2_robot", runs)
    assert row_of(section.markdown, "| GNN_Att: delivered") == "| GNN_Att: delivered | 0.850 ± 0.050 | 0.500 ± 0.000 |"
    assert row_of(section.markdown, "| failed: slip |") == "| failed: slip | – | 0.500 ± 0.000 |"
    assert sorted(set(section.results.column)) == ["3", "7"]


# --- Ch.4: cells (a user's own 5of6 was dropped from the table) ---


def test_table_4_1_renders_a_cell_the_thesis_has_no_column_for():
    runs = pd.DataFrame({"method": ["ours", "ours"], "cell": ["5of6", "3of5"], "seed": [0, 0], "sr": [0.8, 1.0],
                         "latency_ms_batch1": [1.0, 1.0], "latency_ms_batched": [0.1, 0.1]})
    section = build("table_4_1", runs)
    assert rows(section.markdown)[0] == "| method | 3of5 | 5of6 |"
    assert row_of(section.markdown, "| Ours |") == "| Ours | 1.00 (1.00) | 0.80 (–) |"  # one seed: no spread
    thesis = section.table.set_index("cell").thesis_mean
    assert thesis["3of5"] == 1.0 and is_missing(thesis["5of6"])


def test_table_4_2_renders_a_cell_the_thesis_has_no_column_for():
    runs = pd.DataFrame({"method": ["tc_vi"] * 2, "cell": ["3of5", "5of6"], "seed": [0, 0], "sr": [0.9, 0.7],
                         "r2": [0.99, 0.95], "fail_pick": [0.1, 0.3], "planning_ms": [0.3, 0.3],
                         "steps_per_object": [40.0, 40.0]})
    section = build("table_4_2", runs)
    assert rows(section.markdown)[0] == "| method | 3of5 | 5of6 |"
    assert row_of(section.markdown, "| Ours (task-conditioned VI) |") == (
        "| Ours (task-conditioned VI) | 0.90 (R² 0.99) | 0.70 (R² 0.95) |")
    table = section.table.set_index("cell")
    assert table.thesis_sr["3of5"] == 0.92 and table.thesis_r2["3of5"] == 0.97
    assert is_missing(table.thesis_sr["5of6"]) and is_missing(table.thesis_r2["5of6"])


def test_table_4_3_renders_a_cell_the_thesis_has_no_column_for():
    runs = pd.DataFrame({"method": ["ours", "ours", "ours_hrc"], "cell": ["3of5", "5of6", "3of5"], "seed": [0, 0, 0],
                         "run_id": ["a", "b", "c"], "sr": [0.9, 0.6, 0.95], "sr_case1": [1.0, 0.7, 1.0],
                         "sr_case2": [0.8, 0.5, 0.9], "fail_pick": [0.1, 0.4, 0.05],
                         "planning_ms_per_object": [8.0, 9.0, 8.5], "steps_per_object": [40.0, 45.0, 41.0],
                         "execution_s_per_object": [12.0, 13.0, 12.5]})
    section = build("table_4_3", runs)
    header = rows(section.markdown)[0]
    assert header.startswith("| system | 3of5 | 5of6 |")
    assert row_of(section.markdown, "| Ours (Algorithm 2) |").startswith("| Ours (Algorithm 2) | 0.90 | 0.60 |")
    assert row_of(section.markdown, "| ★ Ours with hrc_lab's reasoning module (beyond the thesis) |").startswith(
        "| ★ Ours with hrc_lab's reasoning module (beyond the thesis) | 0.95 | – |")  # a cell it did not run
    thesis = section.table[section.table.system == "ours"].set_index("cell").thesis_sr
    assert thesis["3of5"] == 0.92 and is_missing(thesis["5of6"])


def test_table_4_3_cell_of_fewer_seeds_names_its_count_and_prints_no_spread_of_one():
    runs = pd.DataFrame({"method": ["drl"] * 3, "cell": ["2of3", "2of3", "3of3"], "seed": [0, 1, 0],
                         "run_id": ["a", "b", "c"], "sr": [0.3, 0.5, 0.38], "sr_case1": [0.1, 0.2, 0.2],
                         "sr_case2": [0.5, 0.8, 0.56]})
    section = build("table_4_3", runs)
    row = row_of(section.markdown, "| DRL (DDPG + HER) |")
    assert row.startswith("| DRL (DDPG + HER) | 0.40 ± 0.10 | 0.38 [1 of 2 seeds] |")
    table = section.table.set_index("cell")  # per case: the CSV
    assert table.sr_case1.tolist() == pytest.approx([0.15, 0.2])
    assert table.sr_case2.tolist() == pytest.approx([0.65, 0.56])


# --- Ch.5: goal counts (a 4-goal product was dropped; "10goals" read the thesis' 1-goal row) ---


def ch5_runs(cells: list[str]) -> pd.DataFrame:
    n = len(cells)
    return pd.DataFrame({"cell": cells, "seed": [0] * n, "run_id": [f"r{i}" for i in range(n)],
                         "method": ["hand_lstm_fcn"] * n, "n_sessions": [5.0] * n, "n_fast_sessions": [0.0] * n,
                         "ad_acc": [0.9] * n, "sg_acc": [0.8] * n, "sc_acc": [0.7] * n, "ad_acc_fast": [0.5] * n,
                         "sg_acc_fast": [0.5] * n, "sc_acc_fast": [0.5] * n, "robot_commands": [2.0] * n,
                         "robot_refused_rate": [0.0] * n, "robot_placement_sr": [1.0] * n, "complete_rate": [1.0] * n,
                         "n_assembly_events": [40.0] * n, "n_screw_events": [12.0] * n, "latency_ms": [2.0] * n,
                         "sr_lam0.5": [0.6] * n, "sr_lam1.0": [0.9] * n, "sr_ceiling": [0.95] * n,
                         "n_scenarios": [62.0 * int(cell.split("goal")[0]) for cell in cells]})


def test_table_5_2_renders_a_goal_count_the_thesis_has_no_column_for():
    section = build("table_5_2", ch5_runs(["1goal", "4goals", "10goals"]))
    for goals in (1, 4, 10):
        assert row_of(section.markdown, f"| {goals} |").startswith(f"| {goals} | 5 | 90.0 | 80.0 | 70.0 |")
    assert set(section.table.cell) == set(section.results.row) == {"1goal", "4goals", "10goals"}


def test_table_5_2_planner_renders_a_goal_count_the_thesis_has_no_column_for():
    section = build("table_5_2_planner", ch5_runs(["3goals", "4goals"]))
    assert row_of(section.markdown, "| 3 |").startswith("| 3 | 80.0 | 70.0 |")
    assert row_of(section.markdown, "| 4 |").startswith("| 4 | 80.0 | 70.0 |")
    assert set(section.results.row) == {"3goals", "4goals"}


def test_fig_5_7_renders_a_goal_count_the_thesis_has_no_column_for():
    section = build("fig_5_7", ch5_runs(["4goals", "3goals"]))
    assert row_of(section.markdown, "| trained on |") == "| trained on | 3goals | 4goals |"
    assert row_of(section.markdown, "| λ=0.5 |") == "| λ=0.5 | 0.60 | 0.60 |"
    assert row_of(section.markdown, "| best possible |") == "| best possible | 0.95 | 0.95 |"
    assert set(section.table.cell) == {"3goals", "4goals"}


def test_hrc_session_renders_a_goal_count_the_thesis_has_no_column_for(monkeypatch: pytest.MonkeyPatch):
    tables = {"hrc_sessions": pd.DataFrame({"run_id": ["r0", "r1"], "session": [0, 0], "sg_acc": [1.0, 1.0],
                                            "sc_acc": [1.0, 1.0], "complete": [True, True]}),
              "robot_help": pd.DataFrame(columns=["run_id", "session", "reason"])}
    monkeypatch.setattr(hrc_lab.report.ch5_hrc, "run_tables", lambda runs, name: tables[name])
    section = build("hrc_session", ch5_runs(["2goals", "4goals"]))
    assert row_of(section.markdown, "| 2 |").startswith("| 2 | 90.0 | 80.0 | 70.0 |")
    assert row_of(section.markdown, "| 4 |").startswith("| 4 | 90.0 | 80.0 | 70.0 |")
    assert set(section.results.row) == {"2goals", "4goals"} and "session 0 of `2goals`" in section.markdown
