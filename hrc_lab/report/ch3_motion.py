"""Report sections of the Ch.3 motion experiments: Table 3.1 (the two-level planner correcting a human's errors)
and Fig. 3.10 (neural dynamic planner vs. the full-observation actor)."""

from __future__ import annotations

import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hrc_lab.report.headline import results_frame  # noqa: E402
from hrc_lab.report.plan import Pick, Plan, Row, Study  # noqa: E402
from hrc_lab.report.runs import amount, keyed, over_seeds, setting_number, setting_values, spread  # noqa: E402
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_results  # noqa: E402

# (scenario, object) rows of Table 3.1 and their keys in thesis_results.yaml; each case's objects in the order
# they are moved
ROWS = [
    ("one_object_case1", "blue", ("one_object", "case1_blue")),
    ("one_object_case2", "red", ("one_object", "case2_red")),
    ("two_object_case1", "blue", ("two_objects", "case1_blue")),
    ("two_object_case1", "red", ("two_objects", "case1_red")),
    ("two_object_case2", "red", ("two_objects", "case2_red")),
    ("two_object_case2", "blue", ("two_objects", "case2_blue")),
]
THRESHOLDS = ("0.08", "0.06")
METHODS = {"tc_vi": "`tc_vi` (the thesis')", "tc_vi_indexed": "`tc_vi_indexed`", "tc_vi_object": "★ `tc_vi_object`"}
# the per-stage metrics of hrc_lab.experiments.ch3_motion.stage_metrics, kept in the section's CSV per object
STAGE_METRIC = re.compile(r"stage\d_(right|repeat|pick_xy_m|pick_z_m|subgoal_xy_m|subgoal_z_m|moved_error_m)")
DIAGNOSTICS = ("fail_pick", "fail_collision", "fail_horizon", "subgoals_capped", "planning_ms")


def result_row(method: str, group: str, key: str) -> str:
    """The ``results`` row of one planner's one Table 3.1 object, e.g. ``tc_vi:two_objects.case1_red``."""
    return f"{method}:{group}.{key}"


def stage_of(scenario: str, colour: str) -> int:
    """The picking stage (1 or 2) that moves ``colour`` in ``scenario``."""
    return [c for s, c, _ in ROWS if s == scenario].index(colour) + 1


def _object_results(part: pd.DataFrame, row: str, colour: str) -> list[dict]:
    """SR at both thresholds and steps of one planner's one object; the steps are one count per object (the
    same trials, scored at both thresholds)."""
    records = []
    for threshold in THRESHOLDS:
        records.append({"row": row, "column": f"sr_at_{threshold}", **_stat(part, f"sr_{colour}_{threshold}")})
        records.append({"row": row, "column": f"steps_at_{threshold}", **_stat(part, f"steps_{colour}")})
    return records


def _stat(part: pd.DataFrame, metric: str) -> dict:
    mean, std = spread(part, metric)
    return {"mean": mean, "std": std, "n": int(part[metric].notna().sum()) if metric in part else 0}


@register_section("table_3_1")
def table_3_1(runs: pd.DataFrame) -> Section:
    thesis = thesis_results()["ch3"]["table_3_1"]
    methods = [m for m in METHODS if m in set(runs.method)] + sorted(set(runs.method) - set(METHODS))
    rows, csv, results = [], [], []
    for scenario, colour, (group, key) in ROWS:
        if not (runs.scenario == scenario).any():
            continue
        row = {"case": scenario.replace("_", " "), "object": colour,
               "thesis": f"{thesis[group][key]['sr_at_0.08'][0]:.2f}"}
        for method in methods:
            part = runs[(runs.scenario == scenario) & (runs.method == method)]
            if part.empty:
                continue
            row[METHODS.get(method, f"`{method}`")] = fmt(*spread(part, f"sr_{colour}_0.08"))
            results += _object_results(part, result_row(method, group, key), colour)
            stage = f"stage{stage_of(scenario, colour)}_"
            entry = {"method": method, "scenario": scenario, "object": colour, "seeds": len(part)}
            for threshold in THRESHOLDS:
                entry |= {f"sr_{threshold}_mean": spread(part, f"sr_{colour}_{threshold}")[0],
                          f"sr_{threshold}_std": spread(part, f"sr_{colour}_{threshold}")[1],
                          f"thesis_sr_{threshold}": thesis[group][key][f"sr_at_{threshold}"][0]}
            entry |= {"steps_mean": spread(part, f"steps_{colour}")[0], "steps_std": spread(part, f"steps_{colour}")[1]}
            entry |= {f"pick_{c.removeprefix(stage)}": float(part[c].mean()) for c in part
                      if c.startswith(stage) and STAGE_METRIC.fullmatch(c)}
            entry |= {c: float(part[c].mean()) for c in DIAGNOSTICS if c in part}
            csv.append(entry)
        rows.append(row)
    text = [
        f"Per-object success at δr {THRESHOLDS[0]} m, the planner correcting the human's misplacements "
        f"({amount(runs, 'protocol.trials', 'trials')} per case and seed, "
        f"{amount(runs, 'protocol.demos', 'demonstrations')} per case, at most "
        f"{amount(runs, 'protocol.max_steps_per_subgoal', 'steps')} per sub-goal): within δr of its goal, no "
        f"forbidden contact. {over_seeds(runs, start=True)}. δr 0.06 and steps: the opening table; failures and "
        "picks: the CSV.",
        *([_oracle_reading(runs)] if _oracle_reading(runs) else []),
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no rows)",
    ]
    frame = pd.DataFrame(csv)
    return Section("Table 3.1: the two-level planner corrects a human's errors", "\n".join(text), frame,
                   {"table_3_1.png": _plot_table(frame)} if csv else {}, results=results_frame(results))


def _oracle_reading(runs: pd.DataFrame) -> str:
    """With ``protocol.placement_oracle`` (each released part set onto its goal before the next stage, where every
    demonstration's second stage starts): which part c(x) went for at the second stage."""
    if "True" not in setting_values(runs, "protocol.placement_oracle"):
        return ""
    right = spread(runs, "stage2_right")[0]
    return ("Every released part was set onto its goal before the next stage (`protocol.placement_oracle`): read "
            f"the second objects; c(x) picked the expert's part at {fmt(right)} of the second stages.")


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


CONTROLLERS = {"ndp": "neural dynamic planner D(Δ)", "ndp_direction": "NDP, direction-only outputs",
               "actor": "full-observation actor π(r, s)"}


def curve_columns(runs: pd.DataFrame, controller: str) -> list[tuple[int, str]]:
    """(step, column) of the logged mean-distance curve ``curve_<controller>_<step>``, sorted by step."""
    pattern = re.compile(rf"curve_{controller}_(\d+)$")
    return sorted((int(m.group(1)), c) for c in runs.columns if (m := pattern.match(c)))


def first_below(curve: np.ndarray, steps: np.ndarray, below: float) -> float:
    """The first step at which ``curve`` (one run's mean ‖Δ‖ per step) is below ``below``; NaN if never."""
    hit = np.flatnonzero(curve < below)
    return float(steps[hit[0]]) if len(hit) else float("nan")


@register_section("fig_3_10")
def fig_3_10(runs: pd.DataFrame) -> Section:
    below = setting_number(runs, "protocol.converged_m")
    below = thesis_results()["ch3"]["fig_3_10"]["ndp"][0] if below is None else below
    rows, csv, results = [], [], []
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for controller, label in CONTROLLERS.items():
        columns = curve_columns(runs, controller)
        if not columns:
            continue
        steps = np.array([s for s, _ in columns])
        values = runs[[c for _, c in columns]].to_numpy(dtype=float)  # one row per run (seed): its mean over trials
        per_run = pd.DataFrame({"lowest": np.nanmin(values, 1), "at": steps[np.nanargmin(values, 1)],
                                "first": [first_below(v, steps, below) for v in values], "last": values[:, -1]})
        mean, std = values.mean(0), values.std(0)
        ax.plot(steps, mean, label=label)
        ax.fill_between(steps, mean - std, mean + std, alpha=0.2)
        rows.append({"controller": label, "lowest mean ‖Δ‖ (m)": fmt(*spread(per_run, "lowest"), digits=3),
                     "at step": fmt(*spread(per_run, "at"), digits=1),
                     f"first step below {below:g} m": fmt(*spread(per_run, "first"), digits=1),
                     f"mean ‖Δ‖ at step {steps[-1]} (m)": fmt(*spread(per_run, "last"), digits=3),
                     f"trials that got below {below:g} m": fmt(*spread(runs, f"reached_{controller}"))})
        csv += [{"controller": controller, "step": int(s), "mean_m": m, "std_m": d}
                for s, m, d in zip(steps, mean, std)]
        results += [{"row": controller, "column": "below_m", **_stat(per_run, "lowest")},
                    {"row": controller, "column": "steps", **_stat(per_run, "first")}]
        if controller == "actor":
            lowest = float(per_run.lowest.mean())
            results.append({"row": controller, "column": "", "met": bool(lowest >= below),
                            "text": f"lowest mean ‖Δ‖ {lowest:.3f} m (step {per_run['at'].mean():.0f}), "
                                    f"{per_run['last'].mean():.3f} m at step {steps[-1]}"})
    ax.axhline(below, color="black", linestyle="--", linewidth=1, label=f"{below:g} m")
    ax.set_xlabel("control step")
    ax.set_ylabel("mean |Δ| = |s − r| (m)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    text = [
        "Mean distance from the cup's lip to a random sub-goal over the control steps from the initial pose "
        f"({amount(runs, 'protocol.trials', 'trials')} per seed), for controllers trained on the same "
        f"error-correction demonstrations ({amount(runs, 'protocol.demos_per_case', 'per case')}); each seed's "
        f"curve is its mean over trials, {over_seeds(runs)} ({keyed(runs, 'protocol.converged_m', 'm')}).",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no curves)",
    ]
    return Section("Fig. 3.10: neural dynamic planner vs. full-observation actor", "\n".join(text),
                   pd.DataFrame(csv), {"fig_3_10.png": fig}, results=results_frame(results))


FIRST = "our loop's misses are failed picks: a part it picks ends within both thresholds"
SECOND = ("the first part, placed a little off its goal where no demonstration starts, misleads c(x) and the "
          "planner ([placement oracle](#table_3_1_oracle))")


def _table_3_1_rows() -> tuple[Row, ...]:
    rows = []
    for scenario, colour, (group, key) in ROWS:
        second = stage_of(scenario, colour) == 2
        name = f"{'One object' if group == 'one_object' else 'Two objects'}, case {key[4]}: {colour}"
        rows.append(Row("Table 3.1", name, f"ch3.table_3_1.{group}.{key}",
                        Pick("table_3_1", result_row("tc_vi", group, key)),
                        star=Pick("table_3_1", result_row("tc_vi_object", group, key), "tc_vi_object"),
                        columns=("sr_at_0.08", "sr_at_0.06", "steps_at_0.08", "steps_at_0.06"),
                        lower=("steps_at_0.08", "steps_at_0.06"),
                        why=SECOND if second else FIRST))
    return tuple(rows)


TWO_OBJECTS = "error_correction_two_object_case1,error_correction_two_object_case2"

# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch3_motion",
    title="Ch.3 two-level LfD motion planner: error correction (Table 3.1) and the NDP (Fig. 3.10)",
    note="Trials run in our robosuite UR5e error-correction cells, not the thesis' CoppeliaSim UR10; "
         "demonstrations come from a scripted expert, segmented into stages by PELT change points. Steps: one "
         "count per object, scored at both thresholds.",
    studies=(
        Study("ch3/table_3_1"),
        Study("ch3/fig_3_10"),
        Study("ch3/table_3_1", ("motion=tc_vi", f"env={TWO_OBJECTS}", "protocol.placement_oracle=True"),
              key="table_3_1_oracle",
              title="Table 3.1, the thesis' planner with each placed part set onto its goal",
              question="Do the thesis' planner's second objects fail because the first part is left off its goal, "
                       "where no demonstration starts the second stage?"),
    ),
    rows=(
        *_table_3_1_rows(),
        Row("Fig. 3.10", "Neural dynamic planner D(Δ): lowest mean ‖Δ‖, first step below", "ch3.fig_3_10.ndp",
            Pick("fig_3_10", "ndp"), higher=False, why="robosuite's UR5e cell, not the thesis' UR10"),
        Row("Fig. 3.10", "Full-observation actor π(r, s)", "", Pick("fig_3_10", "actor"),
            claim="its predicted actions remain constant: it does not converge"),
    ),
)
