"""Report section of the Ch.4 TAMP system in the robot cell: Table 4.3 (ours vs DRL vs RM+RRT-Connect)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from hrc_lab.report.plots import success_bars
from hrc_lab.report.runs import NOT_LOGGED, amount, keyed, mean_std, over_seeds, setting
from hrc_lab.report.sections import Section, register_section
from hrc_lab.report.thesis import fmt, fmt_seeds, thesis_cells, thesis_fmt, thesis_results, thesis_value
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


DRL_TRAINING = {"demo_success_rate": "demonstrations packed", "train_success_rate": "SR",
                "train_grip_rate": "a part held", "train_moved_rate": "a goal object moved > 2 cm",
                "train_collision_rate": "collided"}


def _drl_training(runs: pd.DataFrame, cells: list[str]) -> list[str]:
    """How the DRL agent's own exploration reached the parts, from its last logged training episodes."""
    columns = [c for c in DRL_TRAINING if c in runs]
    if runs.empty or not columns:
        return []
    table = runs.groupby("cell")[columns].mean().reindex([c for c in cells if c in set(runs.cell)])
    table = table.rename(columns=DRL_TRAINING).round(2)
    if "drl_train_s" in runs:
        table["training wall time, min"] = (runs.groupby("cell").drl_train_s.mean() / 60).round(1)
    return ["", "DRL training: the share of the last 20 training episodes (exploration noise on) in which the "
                "agent packed the order, held a part at some step, moved a goal object more than 2 cm from its "
                "start, or collided; and the share of the scripted demonstrations put in its replay buffer that "
                "packed the order. HER relabels goals with positions the objects reached, so an episode in which "
                "no goal object moved teaches only 'leave everything where it is'.", "",
            table.reset_index().to_markdown(index=False)]


@register_section("table_4_3")
def table_4_3(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch4"]["table_4_3"]
    cells = thesis_cells(runs.cell, CELLS)
    systems = [s for s in SYSTEMS if s in set(runs.method)]
    stats = {key: mean_std(runs, ["method", "cell"], key) for key in ("sr", "sr_case1", "sr_case2")}
    rows, csv = [], []
    for system in systems:
        row = {"system": LABELS[system]}
        for cell in cells:
            # None: not run (or a system the thesis does not have)
            ref = thesis_value(thesis.get(system, {}).get("sr"), thesis["columns"], cell) or (None, None)
            mean, std, seeds = _stat(stats["sr"], system, cell)
            row[f"{cell} SR"] = f"{fmt_seeds(mean, std, seeds, runs.seed.nunique())} ({thesis_fmt(*ref)})"
            c1, c2 = _stat(stats["sr_case1"], system, cell)[0], _stat(stats["sr_case2"], system, cell)[0]
            row[f"{cell} CASE 1 / 2"] = f"{fmt(c1)} / {fmt(c2)}"
            csv.append({"system": system, "cell": cell, "seeds": seeds, "sr_mean": mean, "sr_std": std, "sr_case1": c1,
                        "sr_case2": c2, "thesis_sr": ref[0],
                        "planning_ms_per_object": _mean(runs, system, "planning_ms_per_object", cell),
                        "steps_per_object": _mean(runs, system, "steps_per_object", cell),
                        "execution_s_per_object": _mean(runs, system, "execution_s_per_object", cell)})
        rows.append(row)
    frame = pd.DataFrame(csv)

    timing = []
    for system in systems:
        ref = thesis.get(system, {})
        ref_plan = (f"{ref['planning_ms'][0]} ± {ref['planning_ms'][1]} ms" if "planning_ms" in ref else
                    f"{ref['planning_s'][0]} ± {ref['planning_s'][1]} s" if "planning_s" in ref else "–")
        ref_exec = f"{ref['execution_s'][0]} ± {ref['execution_s'][1]} s" if "execution_s" in ref else "–"
        timing.append({
            "system": LABELS[system],
            "planning per object, ms (median)": fmt(_mean(runs, system, "planning_ms_per_object")),
            "thesis planning": ref_plan,
            "steps per object": fmt(_mean(runs, system, "steps_per_object")),
            "execution per object, s (simulated)": fmt(_mean(runs, system, "execution_s_per_object")),
            "thesis execution": ref_exec,
        })
    ratio_line = ""
    if {"ours", "rm_rrt_connect"} <= set(systems):
        ratios = [frame[(frame.system == "rm_rrt_connect") & (frame.cell == c)].planning_ms_per_object.iloc[0]
                  / frame[(frame.system == "ours") & (frame.cell == c)].planning_ms_per_object.iloc[0]
                  for c in cells]
        ratio_line = (f"**Planning time RRT-Connect / ours: {np.nanmean(ratios):.0f}×** (per cell "
                      f"{', '.join(f'{c} {r:.0f}×' for c, r in zip(cells, ratios))}; the same trials, both "
                      f"including the reasoning module's two decisions per object; thesis 9.6 s / 7.8 ms ≈ 1230×).")
    # a run logs the failure reasons that occurred; one it did not log did not occur in its trials
    failures = runs[[*(f"fail_{f}" for f in FAILURES if f"fail_{f}" in runs), "method"]].fillna(0.0)
    failures = failures.groupby("method").mean().reindex(systems).rename(index=LABELS).round(2)
    failures = failures.loc[:, (failures != 0).any()]
    by_case = [f"fail_{kind}_case{c}" for kind in ("reasoning", "motion") for c in (1, 2)]
    by_case = runs.groupby(["method", "cell"])[[k for k in by_case if k in runs]].mean().round(2)
    text = [
        f"Success rate (SR) of {amount(runs, 'protocol.trials', 'trials')} per cell (CASE 1 and CASE 2 alternating, "
        f"the same scenes for every system), δr = {keyed(runs, 'env.sim.success_threshold', 'm')}; "
        f"{over_seeds(runs)}, thesis values in brackets. Ours and RM+RRT-Connect learn from CASE 1 "
        f"only (reasoning module: {amount(runs, 'protocol.min_demos', 'task episodes')} as Table 4.1; motion module: "
        f"{amount(runs, 'protocol.demos', 'robot demonstrations')}, {demonstrated_goals(runs)}); DRL trains "
        f"{amount(runs, 'protocol.drl_iterations', 'cycles')} of the HER reference implementation (thesis: 5000 "
        f"iterations) on both cases, {amount(runs, 'rl.episodes_per_cycle', 'episodes')} and "
        f"{amount(runs, 'rl.gradient_steps', 'gradient steps')} per cycle, with "
        f"{amount(runs, 'protocol.drl_demos', 'scripted-expert demonstrations')}.",
        "",
        pd.DataFrame(rows).to_markdown(index=False),
        "",
        pd.DataFrame(timing).to_markdown(index=False),
        "",
        ratio_line,
        "",
        "Why trials failed (share of trials). Reasoning: `wrong_stage`, `wrong_object` (not selected, packed or "
        "absent), `wrong_slot`; motion: `pick`, `placement` (> δr from the slot), `collision` (Eq. 4.7), `horizon`, "
        "RRT-Connect's `ik` and `timeout`; `stages` out of decisions; DRL's `goal` (not packed at the episode's end).",
        "",
        failures.reset_index().to_markdown(index=False),
    ]
    if by_case.shape[1]:
        text += ["", "Reasoning and motion failures per case (share of that case's trials):", "",
                 by_case.rename(index=LABELS, level=0).reset_index().to_markdown(index=False)]
    text += _drl_training(runs[runs.method == "drl"], cells)
    artifacts = {}
    for system in systems:
        part = runs[(runs.method == system) & (runs.cell == "3of5")].sort_values("seed")
        for case in (1, 2):
            if len(part):
                name = f"{system}_3of5_case{case}"
                artifacts[f"{name}_strip.jpg"] = (part.iloc[0].run_id, f"videos/{name}_strip.jpg")
                artifacts[f"{name}.mp4"] = (part.iloc[0].run_id, f"videos/{name}.mp4")
    return Section("Table 4.3: the TAMP system vs DRL vs RM+RRT-Connect", "\n".join(text), frame,
                   {"table_4_3.png": success_bars(frame, cells, systems, LABELS, "Table 4.3", group_col="system")},
                   artifacts)


# how the motion module's robot demonstrations chose their goal configurations (``protocol.motion_demos``)
MOTION_DEMOS = {"fixed": "one packing arrangement per selection as Table 4.2", "all": "their goal configurations "
                "drawn from every slot assignment"}


def demonstrated_goals(runs: pd.DataFrame) -> str:
    """The goal configurations of the motion module's demonstrations in the runs of the systems that train one
    (those built as :class:`hrc_lab.tamp.systems.OursSystem`; ``protocol.motion_demos``; runs from before the key
    had Table 4.2's arrangement, "fixed")."""
    motion_trained = [name for name, (system, _) in SYSTEMS.items() if system == "OursSystem"]
    trained = runs[runs["method"].isin(motion_trained)] if "method" in runs else runs
    if trained.empty:
        return "no system of these runs trains one"
    value = setting(trained, "protocol.motion_demos")
    if value == NOT_LOGGED:
        value = "fixed"
    return " or ".join(MOTION_DEMOS.get(v, f"`protocol.motion_demos` {v}") for v in value.split(" or "))
