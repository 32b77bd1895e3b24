"""Report section of the Ch.4 motion module: Table 4.2 (sub-goal regressors, R^2 and closed-loop success), and the
report's plan."""

from __future__ import annotations

import pandas as pd

from hrc_lab.report.ch4_conditions import position_spans
from hrc_lab.report.headline import from_stats, results_frame
from hrc_lab.report.plan import Pick, Plan, Row, Study
from hrc_lab.report.plots import success_bars
from hrc_lab.report.runs import amount, mean_std, over_seeds, setting, spread
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, markdown_table, thesis_cells, thesis_results, thesis_value

CELLS = ["2of3", "3of3", "3of5", "4of5"]
METHODS = ["tc_vi", "vi", "gpr", "mlp"]
LABELS = {"tc_vi": "Ours (task-conditioned VI)", "vi": "VI", "gpr": "GPR", "mlp": "MLP"}
THESIS_KEYS = {"tc_vi": "ours", "vi": "vi", "gpr": "gpr", "mlp": "mlp"}
R2 = "r2"  # the results' row suffix of a method's R² (its SR's row is the method)


def r2_row(method: str) -> str:
    """The results' row of ``method``'s cross-validated R² (columns: the cells), e.g. "tc_vi r2"."""
    return f"{method} {R2}"


@register_section("table_4_2")
def table_4_2(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["table_4_2"]
    sr, r2 = mean_std(runs, ["method", "cell"], "sr"), mean_std(runs, ["method", "cell"], "r2")
    cells = thesis_cells(runs.cell, CELLS)
    methods = [m for m in METHODS if m in set(runs.method)]
    failures = [c for c in runs.columns if c.startswith("fail_")]
    rows, csv = [], []
    for method in methods:
        ref = thesis[THESIS_KEYS[method]]
        row = {"method": LABELS[method]}
        for cell in cells:
            part = runs[(runs.method == method) & (runs.cell == cell)]
            (sr_mean, sr_std), (r2_mean, r2_std) = spread(part, "sr"), spread(part, "r2")
            ref_sr = thesis_value(ref["sr"], thesis["columns"], cell) or (None, None)  # None: a cell not run
            row[cell] = f"{fmt(sr_mean, sr_std)} (R² {fmt(r2_mean)})" if len(part) else "–"
            csv.append({"method": method, "cell": cell, "seeds": len(part), "r2_mean": r2_mean, "r2_std": r2_std,
                        "sr_mean": sr_mean, "sr_std": sr_std, "thesis_r2": thesis_value(ref["r2"], thesis["columns"],
                                                                                        cell),
                        "thesis_sr": ref_sr[0],
                        **{key: float(part[key].mean()) for key in ("sr_case1", "sr_case2", "planning_ms",
                                                                     "steps_per_object", *failures) if key in part}})
        rows.append(row)
    text = (f"Success rate of {amount(runs, 'protocol.trials', 'closed-loop trials')} (CASE 1 and 2 alternating, "
            f"ground-truth reasoning outputs, δr {setting(runs, 'env.sim.success_threshold')} m) with, in brackets, "
            f"the sub-goal regressor's {setting(runs, 'protocol.cv_folds')}-fold cross-validated R²; trained on "
            f"{amount(runs, 'protocol.demos', 'scripted demonstrations')}, one packing arrangement per selection; "
            f"{over_seeds(runs)}.")
    spans = position_spans(runs)
    text += f" {spans[0].upper()}{spans[1:]}." if spans else ""
    ours = runs[runs.method == "tc_vi"]
    if "planning_ms" in ours and ours.planning_ms.notna().any():
        text += (f" Ours plans a sub-goal in {ours.planning_ms.mean():.2f} ms (thesis "
                 f"{thesis_results()['ch4']['text']['subgoal_planning_ms_per_subgoal']} ms).")
    text += " Failure causes per cell: the CSV."
    table = pd.DataFrame(csv)
    results = from_stats(sr) + [{**record, "row": r2_row(record["row"])} for record in from_stats(r2)]
    return Section("Table 4.2: sub-goal regressors and the motion module",
                   f"{text}\n\n{markdown_table(pd.DataFrame(rows))}", table,
                   {"table_4_2.png": success_bars(table, cells, methods, LABELS, "Table 4.2")},
                   results=results_frame(results))


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
WHY = {  # why each method's SR differs from the thesis' (the opening table)
    "tc_vi": "3of5: forbidden contacts (`fail_collision` in the CSV), as for the MLP",
    "vi": "",
    "gpr": "the thesis' \"RBF kernel\" read as one length scale ([one per input](#gpr_ard))",
    "mlp": "our MLP fits its demonstrations ([shorter training](#mlp_short_training))",
}
PLAN = Plan(
    topic="ch4_motion",
    title="Ch.4 motion module: task-conditioned sub-goal planner and NDP vs. VI, GPR, MLP",
    note="Closed-loop trials run in our robosuite UR5e cell, not the thesis' CoppeliaSim UR10; demonstrations "
         "come from the scripted expert.",
    studies=(
        Study("ch4/table_4_2"),
        Study("ch4/table_4_2", ("motion=mlp", "motion.steps=300"), key="mlp_short_training",
              title="Table 4.2's MLP with a shorter training",
              question="Does an MLP that fits its demonstrations less fail in closed loop as the thesis' MLP does?"),
        Study("ch4/table_4_2", ("motion=gpr", "seed=0", "motion.gpr_kernel=ard"), key="gpr_ard",
              title="Table 4.2's GPR with one RBF length scale per input (ARD)",
              question="How much does the GPR row depend on how the thesis' \"RBF kernel\" is read?"),
    ),
    rows=(
        *(Row("Table 4.2, SR", LABELS[m], f"ch4.table_4_2.{THESIS_KEYS[m]}.sr", Pick("table_4_2", m), why=WHY[m])
          for m in METHODS),
        *(Row("Table 4.2, R²", LABELS[m], f"ch4.table_4_2.{THESIS_KEYS[m]}.r2", Pick("table_4_2", r2_row(m)),
              headline=False) for m in METHODS),
    ),
)
