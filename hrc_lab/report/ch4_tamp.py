"""Report section of the Ch.4 TAMP system in the robot cell: Table 4.3 (ours vs DRL vs RM+RRT-Connect)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from hrc_lab.report.headline import from_stats, results_frame
from hrc_lab.report.plan import Pick, Plan, Row, Study, experiment_file
from hrc_lab.report.plots import success_bars
from hrc_lab.report.runs import NOT_LOGGED, amount, keyed, mean_std, over_seeds, setting
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, fmt_seeds, markdown_table, thesis_cells, thesis_results, thesis_value
from hrc_lab.tamp.configs import LABELS, SYSTEMS

CELLS = ["2of3", "3of3", "3of5", "4of5"]
FAILURES = ("wrong_stage", "wrong_object", "wrong_slot", "pick", "placement", "collision", "horizon", "ik",
            "timeout", "stages", "goal")


def _stat(stats: pd.DataFrame, system: str, cell: str) -> tuple[float, float, int]:
    """Mean, spread and number of seeds of one system's metric in one cell."""
    hit = stats[(stats.method == system) & (stats.cell == cell)]
    return (hit.iloc[0]["mean"], hit.iloc[0]["std"], int(hit.iloc[0]["n"])) if len(hit) else (np.nan, np.nan, 0)


def _mean(runs: pd.DataFrame, system: str, metric: str, cell: str | None = None) -> float:
    part = runs[(runs.method == system) & ((runs.cell == cell) if cell else True)]
    return float(part[metric].mean()) if metric in part and len(part) else np.nan


# how the motion module's robot demonstrations chose their goal configurations (``protocol.motion_demos``)
NO_MOTION = "no system of these runs trains one"
MOTION_DEMOS = {"fixed": "one packing arrangement per selection as Table 4.2", "all": "their goal configurations "
                "drawn from every slot assignment"}


def demonstrated_goals(runs: pd.DataFrame) -> str:
    """The goal configurations of the motion module's demonstrations in the runs of the systems that train one
    (those built as :class:`hrc_lab.tamp.systems.OursSystem`; ``protocol.motion_demos``; runs from before the key
    had Table 4.2's arrangement, "fixed")."""
    motion_trained = [name for name, (system, _) in SYSTEMS.items() if system == "OursSystem"]
    trained = runs[runs["method"].isin(motion_trained)] if "method" in runs else runs
    if trained.empty:
        return NO_MOTION
    value = setting(trained, "protocol.motion_demos")
    if value == NOT_LOGGED:
        value = "fixed"
    return " or ".join(MOTION_DEMOS.get(v, f"`protocol.motion_demos` {v}") for v in value.split(" or "))


def _motion_demos(runs: pd.DataFrame) -> str:
    """ ", ours' motion module from 20 demonstrations, their goal configurations ..." ("" when no system of the runs
    trains one)."""
    goals = demonstrated_goals(runs)
    if goals == NO_MOTION:
        return ""
    return f", ours' motion module from {amount(runs, 'protocol.demos', 'demonstrations')}, {goals}"


@register_section("table_4_3")
def table_4_3(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["table_4_3"]
    cells = thesis_cells(runs.cell, CELLS)
    systems = [s for s in SYSTEMS if s in set(runs.method)]
    stats = {key: mean_std(runs, ["method", "cell"], key) for key in ("sr", "sr_case1", "sr_case2")}
    failures = [f"fail_{f}" for f in FAILURES if f"fail_{f}" in runs]
    rows, csv = [], []
    for system in systems:
        row = {"system": LABELS[system]}
        for cell in cells:
            ref = thesis_value(thesis.get(system, {}).get("sr"), thesis["columns"], cell) or (None, None)
            mean, std, seeds = _stat(stats["sr"], system, cell)
            row[cell] = fmt_seeds(mean, std, seeds, runs.seed.nunique())
            part = runs[(runs.method == system) & (runs.cell == cell)]
            csv.append({"system": system, "cell": cell, "seeds": seeds, "sr_mean": mean, "sr_std": std,
                        "sr_case1": _stat(stats["sr_case1"], system, cell)[0],
                        "sr_case2": _stat(stats["sr_case2"], system, cell)[0], "thesis_sr": ref[0],
                        "planning_ms_per_object": _mean(runs, system, "planning_ms_per_object", cell),
                        "steps_per_object": _mean(runs, system, "steps_per_object", cell),
                        "execution_s_per_object": _mean(runs, system, "execution_s_per_object", cell),
                        **{f: float(part[f].fillna(0.0).mean()) for f in failures}})
        row["planning ms / object"] = fmt(_mean(runs, system, "planning_ms_per_object"))
        row["execution s / object"] = fmt(_mean(runs, system, "execution_s_per_object"))
        rows.append(row)
    frame = pd.DataFrame(csv)
    text = [
        f"Success rate of {amount(runs, 'protocol.trials', 'trials')} per cell (CASE 1 and 2 alternating, the same "
        f"scenes for every system), δr {keyed(runs, 'env.sim.success_threshold', 'm')}; {over_seeds(runs)}. Ours "
        f"and RM+RRT-Connect learn from CASE 1 only{_motion_demos(runs)}; DRL trains "
        f"{amount(runs, 'protocol.drl_iterations', 'cycles')} on both cases. Planning: median per object; execution: "
        "simulated. Per case and why trials failed: the CSV.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    figures = {"table_4_3.png": success_bars(frame, cells, systems, LABELS, "Table 4.3", group_col="system")}
    return Section("Table 4.3: the TAMP system vs DRL vs RM+RRT-Connect", "\n".join(text), frame, figures,
                   results=results_frame(from_stats(stats["sr"])))


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
DRL_CYCLES = experiment_file("ch4/table_4_3")["protocol"]["drl_iterations"]  # the DRL row's training as configured
PLAN = Plan(
    topic="ch4_tamp",
    title="Ch.4 TAMP in the robot cell (Algorithm 2): ours vs DRL vs RM+RRT-Connect",
    note="Trials run in our robosuite UR5e cell, not the thesis' CoppeliaSim UR10, so execution time is simulated "
         "(control steps / control rate). RRT-Connect is OMPL's, in the 3-D joint space the neural dynamic planner "
         "acts in; DRL is stable-baselines3's DDPG with its HER buffer on our goal env.",
    studies=(
        Study("ch4/table_4_3"),
        Study("ch4/table_4_3", ("env=package_to_order_3of5", "tamp=ours_hrc", "protocol.motion_demos=fixed"),
              key="fixed_demos", title="★ in 3of5 with Table 4.2's demonstrations (one arrangement per selection)",
              question="Does ★'s motion module need demonstrations over every slot assignment, not Table 4.2's?"),
    ),
    rows=(
        Row("Table 4.3", "Ours (Algorithm 2)", "ch4.table_4_3.ours.sr", Pick("table_4_3", "ours"),
            star=Pick("table_4_3", "ours_hrc", "hrc_lab's reasoning module"),
            why="the thesis' reasoning module misreads CASE 2 scenes"),
        Row("Table 4.3", "DRL (DDPG + HER)", "ch4.table_4_3.drl.sr", Pick("table_4_3", "drl", f"{DRL_CYCLES} cycles"),
            why="trained for a fraction of the thesis' iterations (its count takes hours a job)"),
        Row("Table 4.3", "RM+RRT-Connect", "ch4.table_4_3.rm_rrt_connect.sr", Pick("table_4_3", "rm_rrt_connect"),
            why="the thesis' reasoning module misreads CASE 2 scenes"),
    ),
)
