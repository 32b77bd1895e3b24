"""Report sections of the Ch.3 motion experiments: Table 3.1 (the two-level planner correcting a human's errors)
and Fig. 3.10 (neural dynamic planner vs. the full-observation actor)."""

from __future__ import annotations

import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.plan import Plan, Study  # noqa: E402
from hrc_lab.report.runs import (  # noqa: E402
    NOT_LOGGED,
    amount,
    keyed,
    mean_std,
    over_seeds,
    setting,
    setting_values,
    spread,
)
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_fmt, thesis_results  # noqa: E402

# (scenario, object) rows of Table 3.1 and their keys in thesis_results.yaml
ROWS = [
    ("one_object_case1", "blue", ("one_object", "case1_blue")),
    ("one_object_case2", "red", ("one_object", "case2_red")),
    ("two_object_case1", "blue", ("two_objects", "case1_blue")),
    ("two_object_case1", "red", ("two_objects", "case1_red")),
    ("two_object_case2", "red", ("two_objects", "case2_red")),
    ("two_object_case2", "blue", ("two_objects", "case2_blue")),
]
THRESHOLDS = ("0.08", "0.06")
CONTROLLERS = {"ndp": "Neural dynamic planner (Δ only)", "ndp_direction": "NDP, direction-only outputs",
               "actor": "Full-observation actor π(r, s)"}


# the per-stage metrics of hrc_lab.experiments.ch3_motion.stage_metrics
STAGE_METRIC = re.compile(r"stage\d_(right|repeat|pick_xy_m|pick_z_m|subgoal_xy_m|subgoal_z_m|moved_error_m)")
METHODS = {"tc_vi": "the thesis' planner",
           "tc_vi_indexed": "the same with the sub-goal index in its label (not in the thesis: the thesis' planner "
                            "infers its progress through a stage from r)",
           "tc_vi_object": "★ hrc_lab's: tc_vi_indexed observing the stage's object and green relative to r and "
                           "planning each sub-goal relative to the stage's object (green when placing)"}


@register_section("table_3_1")
def table_3_1(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch3"]["table_3_1"]
    rows, csv = [], []
    methods = [m for m in METHODS if m in set(runs.method)] + sorted(set(runs.method) - set(METHODS))
    for method in methods:
        for scenario, colour, (group, key) in ROWS:
            part = runs[(runs.scenario == scenario) & (runs.method == method)]
            if part.empty:
                continue
            ref = thesis[group][key]
            row = {"planner": method, "case": scenario.replace("_", " "), "object": colour}
            entry = {"method": method, "scenario": scenario, "object": colour, "seeds": len(part)}
            for threshold in THRESHOLDS:
                mean, std = spread(part, f"sr_{colour}_{threshold}")
                row[f"SR δr={threshold}"] = f"{fmt(mean, std)} ({thesis_fmt(*ref[f'sr_at_{threshold}'])})"
                entry |= {f"sr_{threshold}_mean": mean, f"sr_{threshold}_std": std,
                          f"thesis_sr_{threshold}": ref[f"sr_at_{threshold}"][0]}
            steps_mean, steps_std = spread(part, f"steps_{colour}")
            row["steps"] = (f"{fmt(steps_mean, steps_std, digits=1)} ({ref['steps_at_0.08'][0]:.1f} / "
                            f"{ref['steps_at_0.06'][0]:.1f})")
            entry |= {"steps_mean": steps_mean, "steps_std": steps_std}
            rows.append(row)
            csv.append(entry)
    fail_columns = [c for c in runs.columns if c.startswith("fail_")]
    failures = runs.groupby(["method", "scenario"])[fail_columns + [c for c in ("subgoals_capped",)
                                                                      if c in runs]].mean().round(2)
    text = [
        "Per-object success rate of the two-level planner (task classifier c(x), task-conditioned VI sub-goal "
        f"planner with {amount(runs, 'protocol.subgoals_per_stage', 're-sampled sub-goals per stage')}, neural "
        f"dynamic planner with at most {amount(runs, 'protocol.max_steps_per_subgoal', 'steps')} per sub-goal), "
        f"trained on {amount(runs, 'protocol.demos', 'scripted-expert demonstrations')} per case and seed, "
        f"correcting the human's misplacements in {amount(runs, 'protocol.trials', 'trials')} per case and seed in "
        "the robosuite cell: an object succeeds when it ends within δr of its goal and no "
        "forbidden contact happened. Steps: control steps the robot spent on the object (thesis: at δr 0.08 / 0.06). "
        f"{over_seeds(runs, start=True)}; thesis values in brackets. Planners: "
        + "; ".join(f"`{m}` {METHODS.get(m, m)}" for m in methods) + ".",
        "",
        pd.DataFrame(rows).to_markdown(index=False) if rows else "(no rows)",
    ]
    if "True" in setting_values(runs, "protocol.placement_oracle"):
        text += ["", "**Diagnosis, not a result**: with `protocol.placement_oracle=True` every released object was "
                     "set exactly onto its goal before the next stage, so the first object's SR is inflated; read the "
                     "second object's." + _oracle_reading(runs)]
    if fail_columns:
        text += ["", "Why trials ended early (share of trials): `pick` the cup did not hold the object after a "
                     "picking stage, `collision` a forbidden contact, `horizon` the episode's step limit ran out. "
                     "`subgoals_capped` (where logged): the share of sub-goals the dynamic planner had not reached "
                     "when their step cap ran out; the next sub-goal is then planned from where the arm is, as the "
                     "thesis' cap reads, and the trial goes on.", "",
                 failures.reset_index().to_markdown(index=False)]
    stage_columns = sorted(c for c in runs.columns if STAGE_METRIC.fullmatch(c))
    if stage_columns:
        stages = runs.groupby(["method", "scenario"])[stage_columns].mean().round(3)
        text += ["", "Where each picking stage went (mean over seeds): `stageK_right` the share of stage-K starts "
                     "whose object was the expert's, `stageK_repeat` the share that went back for an object already "
                     "moved; `stageK_pick_xy_m` / `_pick_z_m` the median horizontal distance and height (m) of the "
                     "cup's lip from that object's top-face centre where the picking stage ended (the cup grips "
                     "within the 5 cm face, so within about 0.025 m of its centre); `stageK_subgoal_xy_m` / "
                     "`_subgoal_z_m` (where logged) the same of the stage's last planned sub-goal, the planner's share "
                     "of the offset; `stage2_moved_error_m` the median "
                     "distance of the first object from its goal when the second picking stage started.", "",
                 stages.reset_index().to_markdown(index=False)]
    if "planning_ms" in runs:
        text += ["", f"Sub-goal planning latency: **{runs.planning_ms.mean():.2f} ms** per sub-goal on one CPU core."]
    return Section("Table 3.1: the two-level planner corrects a human's errors", "\n".join(text), pd.DataFrame(csv),
                   {"table_3_1.png": _plot_table(pd.DataFrame(csv))} if csv else {})


def _plot_table(frame: pd.DataFrame, threshold: str = "0.08"):
    """Success rate at ``threshold`` per case and object, one bar per planner, the thesis as dashes."""
    firsts = frame.drop_duplicates(["scenario", "object"])
    cases = list(zip(firsts.scenario, firsts.object))
    methods = list(dict.fromkeys(frame.method))
    width = 0.8 / len(methods)
    fig, ax = plt.subplots(figsize=(7, 3.4))
    x = np.arange(len(cases))
    for k, method in enumerate(methods):
        part = frame[frame.method == method].set_index(["scenario", "object"]).reindex(cases)
        ax.bar(x + (k - (len(methods) - 1) / 2) * width, part[f"sr_{threshold}_mean"], width,
               yerr=part[f"sr_{threshold}_std"], capsize=2, label=method)
    ax.scatter(x, firsts[f"thesis_sr_{threshold}"], marker="_", s=400, color="black", linewidths=2, zorder=3,
               label="thesis")
    ax.set_xticks(x, [f"{s.replace('_object_', ' obj ')}\n{o}" for s, o in cases], fontsize=7)
    ax.set_ylabel(f"success rate, δr = {threshold} m")
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def curve_columns(runs: pd.DataFrame, controller: str) -> list[tuple[int, str]]:
    """(step, column) of the logged mean-distance curve ``curve_<controller>_<step>``, sorted by step."""
    pattern = re.compile(rf"curve_{controller}_(\d+)$")
    return sorted((int(m.group(1)), c) for c in runs.columns if (m := pattern.match(c)))


@register_section("fig_3_10")
def fig_3_10(runs: pd.DataFrame) -> Section:
    ref = thesis_results()["ch3"]["text"]
    steps_logged, converged = setting(runs, "protocol.steps"), setting(runs, "protocol.converged_m")
    final_column = f"‖Δ‖ after {steps_logged} steps (m)" if steps_logged != NOT_LOGGED else "‖Δ‖ at the last step (m)"
    reached_column = "reached `protocol.converged_m`" if converged == NOT_LOGGED else f"reached < {converged} m"
    rows, csv = [], []
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for controller, label in CONTROLLERS.items():
        columns = curve_columns(runs, controller)
        if not columns:
            continue
        steps = np.array([s for s, _ in columns])
        values = runs[[c for _, c in columns]].to_numpy(dtype=float)
        mean, std = np.nanmean(values, 0), np.nanstd(values, 0)
        ax.plot(steps, mean, label=label)
        ax.fill_between(steps, mean - std, mean + std, alpha=0.2)
        reached = mean_std(runs.assign(all="all"), ["all"], f"reached_{controller}")
        converge = mean_std(runs.assign(all="all"), ["all"], f"steps_to_converge_{controller}")
        final = mean_std(runs.assign(all="all"), ["all"], f"final_m_{controller}")
        get = lambda s: (s.iloc[0]["mean"], s.iloc[0]["std"]) if len(s) else (np.nan, np.nan)  # noqa: E731
        rows.append({"controller": label, final_column: fmt(*get(final), digits=3),
                     reached_column: fmt(*get(reached)),
                     "steps to get there": fmt(*get(converge), digits=1)})
        csv += [{"controller": controller, "step": int(s), "mean_m": m, "std_m": d}
                for s, m, d in zip(steps, mean, std)]
    ax.axhline(ref["ndp_converges_below_m"], color="black", linestyle="--", linewidth=1,
               label=f"thesis: NDP < {ref['ndp_converges_below_m']} m in ~{ref['ndp_steps_to_converge']} steps")
    ax.set_xlabel("control step")
    ax.set_ylabel("|Δ| = |s − r| (m)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    text = [
        "Distance from the cup's lip to a random sub-goal over "
        f"{amount(runs, 'protocol.steps', 'control steps')} from the initial pose "
        f"({amount(runs, 'protocol.trials', 'trials')} per seed), for controllers trained on the same error-correction "
        f"demonstrations ({amount(runs, 'protocol.demos_per_case', 'per case')}); 'reached' counts trials that got "
        f"below {keyed(runs, 'protocol.converged_m', 'm')}; curves: mean over trials, {_band(runs)}. Thesis "
        f"(Fig. 3.10): the NDP gets below "
        f"{ref['ndp_converges_below_m']} m in about {ref['ndp_steps_to_converge']} steps; the full-observation actor "
        "does not converge.",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no curves)",
    ]
    return Section("Fig. 3.10: neural dynamic planner vs. full-observation actor", "\n".join(text),
                   pd.DataFrame(csv), {"fig_3_10.png": fig})


def _band(runs: pd.DataFrame) -> str:
    """What the band around Fig. 3.10's curves shows: the spread over seeds, none for one seed."""
    seeds = sorted(runs.seed.unique())
    return f"one seed ({seeds[0]}): no band" if len(seeds) == 1 else f"band: spread over seeds {seeds}"


def _oracle_reading(runs: pd.DataFrame) -> str:
    """What the placement oracle shows about the second objects: their SR and c(x)'s stage-2 choice, here, where
    every demonstration's second stage also started (the first part exactly on its goal)."""
    # each two-object case lists its objects in the order they are moved: the last one kept is the second
    second = {scenario: colour for scenario, colour, _ in ROWS if scenario.startswith("two_object")}
    parts = []
    for scenario, colour in second.items():
        part = runs[runs.scenario == scenario]
        if part.empty or f"sr_{colour}_0.08" not in part or "stage2_right" not in part:
            continue
        parts.append(f"{scenario.replace('_', ' ')}: second object ({colour}) SR "
                     f"{fmt(*spread(part, f'sr_{colour}_0.08'))} at δr 0.08, c(x) right at "
                     f"{part.stage2_right.mean():.2f} of stage-2 starts")
    if not parts:
        return ""
    return (" This is where every demonstration's second stage starts (the scripted expert places exactly); the "
            "default runs start it from wherever the first placement ended (their section's `stage2_moved_error_m`). "
            f"Measured here: {'; '.join(parts)}. A second object that succeeds here and fails in the default rows "
            "fails because the first placement's error is outside what c(x) and the planner were trained on.")


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch3_motion",
    title="Ch.3 two-level LfD motion planner: error correction (Table 3.1) and the NDP (Fig. 3.10)",
    note="Trials run in our robosuite UR5e error-correction cells, not the thesis' CoppeliaSim UR10; "
         "demonstrations come from a scripted expert, segmented into stages by PELT change points.",
    studies=(Study("ch3/table_3_1"), Study("ch3/fig_3_10")),
)
