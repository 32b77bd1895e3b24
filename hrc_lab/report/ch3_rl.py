"""Report sections of the Ch.3 guided-RL experiments (Algorithm 1): Fig. 3.13 (hybrid vs full guidance vs pure
exploration on error correction), Fig. 3.12 (place and stack, NDP guidance vs none), Fig. 3.9 (the goal-state
positional difference in guided vs unguided exploration) and the agent on gymnasium-robotics' Fetch tasks. Curves
come from the runs' per-epoch metric histories (MLflow metrics logged with step = epoch; an epoch is defined in
:mod:`hrc_lab.experiments.ch3_rl`)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from hrc_lab.report.headline import results_frame  # noqa: E402
from hrc_lab.report.plan import Pick, Plan, Row, Study  # noqa: E402
from hrc_lab.report.runs import (  # noqa: E402
    PARAM_PREFIX,
    amount,
    default_runs_of,
    histories,
    keyed,
    over_seeds,
    setting,
    setting_number,
    spread,
)
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_results  # noqa: E402

ARMS = {"0": "pure exploration (λ = 0)", "0.7": "hybrid (λ = 0.7)", "1": "full guidance (λ = 1)"}
LAST_EPOCHS = 3  # "SR, last epochs": the evaluations of a subtask's last 3 epochs pooled (60 episodes at 20 each)
# the thesis' columns of Fig. 3.13 (thesis_results.yaml ch3.fig_3_13) and Fig. 3.9 by the runs' scenario
EXPERIMENTS = {"one_object_case1": "one_object", "two_object_case1": "two_objects"}
# the summaries of a curves section: metric -> its column in the section's table (None: the CSV only)
SUMMARIES = {"final_policy_success_rate": "final policy SR", "last_epochs_success_rate": f"SR, last {LAST_EPOCHS} "
             "epochs", "mean_epochs_success_rate": "SR over epochs", "final_grip_rate": "evaluations that held the "
             "part", "final_collision_rate": "collisions", "final_success_rate": None, "best_success_rate": None,
             "final_distance": None, "final_moved_rate": None, "final_train_success_rate": None,
             "final_train_grip_rate": None, "final_train_distance": None, "mean_guidance_rate": None,
             "mean_env_steps_per_s": None, "mean_updates_per_s": None}


def lam_of(runs: pd.DataFrame) -> pd.Series:
    """The guidance ratio of each run as text ("0", "0.7", "1"), from its logged ``rl.lam``."""
    return runs[f"{PARAM_PREFIX}rl.lam"].astype(float).map(lambda v: f"{v:g}")


def subtask_sr(runs: pd.DataFrame, history: pd.DataFrame, last: int | None = None) -> pd.Series:
    """Per (run, subtask): the mean of ``history`` (one metric's per-epoch values) over the subtask's last ``last``
    epochs (every epoch: None); epoch ``k * epochs + e`` of a run is epoch ``e`` of subtask ``k``
    (:mod:`hrc_lab.experiments.ch3_rl`). Empty for runs that logged no epochs or no curve."""
    column = f"{PARAM_PREFIX}protocol.epochs"
    if column not in runs or history.empty:
        return pd.Series(dtype=float)
    epochs = pd.to_numeric(runs.set_index("run_id")[column], errors="coerce")
    frame = history.assign(epochs=history.run_id.map(epochs)).dropna(subset=["epochs"])
    frame = frame.assign(subtask=(frame.step - 1) // frame.epochs, epoch=(frame.step - 1) % frame.epochs + 1)
    if last is not None:
        frame = frame[frame.epoch > frame.epochs - last]
    return frame.groupby(["run_id", "subtask"]).value.mean()


def epochs_sr(runs: pd.DataFrame, history: pd.DataFrame, last: int | None = None) -> pd.Series:
    """Per run: the mean evaluation SR over each subtask's last ``last`` epochs (every epoch: None), averaged over
    its subtasks (:func:`subtask_sr`). One epoch's 20 evaluation episodes move the SR by about ±0.1; three epochs'
    pooled move it less. Over every epoch it is the area under the learning curve over its length: how fast an arm
    learns, Fig. 3.12's claim."""
    by_subtask = subtask_sr(runs, history, last)
    return by_subtask.groupby("run_id").mean() if len(by_subtask) else by_subtask


def by_subtask(values: pd.DataFrame) -> str:
    """One value per subtask (columns, in order), each the mean over the rows (seeds), as "0.85 / 0.13"; a subtask
    no row has is "–" where a later one has a value (each value stays in its subtask's place) and is left off after
    the last value (a one-subtask row beside two-subtask rows reads "0.80"); "–" when no row has any."""
    means = values.mean()
    last = means.last_valid_index()
    if last is None:
        return "–"
    return " / ".join("–" if pd.isna(v) else f"{v:.2f}" for v in means.loc[:last])


def with_curve_summaries(runs: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``runs`` with their text λ (``lam``) and the curve's summaries (SR over the last epochs and over every
    epoch), and the per-epoch SR history of every run."""
    runs = runs.assign(lam=lam_of(runs))
    history = histories(runs, "success_rate").merge(runs[["run_id", "scenario", "lam", "seed"]], on="run_id")
    runs = runs.assign(last_epochs_success_rate=runs.run_id.map(epochs_sr(runs, history, LAST_EPOCHS)),
                       mean_epochs_success_rate=runs.run_id.map(epochs_sr(runs, history)))
    return runs, history


def curves_section(runs: pd.DataFrame, title: str, intro: str, png: str) -> Section:
    """SR per epoch for every (scenario, λ): each run light, the mean over seeds bold; one table row per
    (scenario, λ) with the final policies' SR (by subtask where a plan has several) and the curve's summaries. The
    CSV is tidy: (scenario, λ, epoch or empty, metric, mean, std, n); its ``results``: one row per λ, one column
    per experiment (:data:`EXPERIMENTS`), the final policies' SR."""
    runs, history = with_curve_summaries(runs)
    final_by_subtask = sorted((c for c in runs if c.startswith("final_policy_success_rate_subtask")
                               and runs[c].notna().any()),
                              key=lambda c: int(c.removeprefix("final_policy_success_rate_subtask")))
    scenarios = sorted(runs.scenario.unique())
    fig, axes = plt.subplots(1, len(scenarios), figsize=(5 * len(scenarios), 3.4), squeeze=False)
    rows, csv, results = [], [], []
    for ax, scenario in zip(axes[0], scenarios):
        for k, lam in enumerate(sorted(runs[runs.scenario == scenario].lam.unique(), key=float)):
            part = history[(history.scenario == scenario) & (history.lam == lam)]
            for _, one in part.groupby("run_id"):
                ax.plot(one.step, one.value, color=f"C{k}", alpha=0.25, linewidth=0.8)
            mean = part.groupby("step").value.mean()
            ax.plot(mean.index, mean.values, color=f"C{k}", linewidth=2, label=ARMS.get(lam, f"λ = {lam}"))
            key = {"scenario": scenario, "lam": lam}
            csv += [{**key, "epoch": int(s), "metric": "success_rate", "mean": v, "std": None, "n": None}
                    for s, v in mean.items()]
            done = runs[(runs.scenario == scenario) & (runs.lam == lam)]
            row = {"experiment": scenario.replace("_", " "), "λ": lam}
            for metric, label in SUMMARIES.items():
                mean_, std = spread(done, metric)
                csv.append({**key, "epoch": None, "metric": metric, "mean": mean_, "std": std,
                            "n": int(done[metric].notna().sum()) if metric in done else 0})
                if label:
                    row[label] = fmt(mean_, std)
                if label and len(final_by_subtask) > 1 and metric == "final_policy_success_rate":
                    row["by subtask"] = by_subtask(done.reindex(columns=final_by_subtask))
            rows.append(row)
            mean_, std = spread(done, "final_policy_success_rate")
            results.append({"row": lam, "column": EXPERIMENTS.get(scenario, scenario), "mean": mean_, "std": std,
                            "n": int(done["final_policy_success_rate"].notna().sum())
                            if "final_policy_success_rate" in done else 0})
        ax.set_title(scenario.replace("_", " "), fontsize=9)
        ax.set_xlabel("epoch (subtasks in sequence)")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel("success rate (evaluation)")
        ax.set_ylim(-0.02, 1.02)
        ax.legend(fontsize=7)
    fig.tight_layout()
    text = [intro, "", markdown_table(pd.DataFrame(rows)) if rows else "(no runs)"]
    return Section(title, "\n".join(text), pd.DataFrame(csv), {png: fig}, results=results_frame(results))


def budget_text(runs: pd.DataFrame) -> str:
    """The training budget and the final evaluation, read from the runs' params."""
    return (f"{amount(runs, 'protocol.epochs', 'epochs')} per subtask (subtasks in sequence) of "
            f"{amount(runs, 'rl.cycles_per_epoch', 'cycles')} × {amount(runs, 'rl.episodes_per_cycle', 'episodes')} "
            f"of {amount(runs, 'rl.steps_per_subtask', 'steps')}; "
            f"{amount(runs, 'protocol.expert_demos', 'scripted demonstrations')} per subtask. Final policy SR: each "
            f"subtask's last agent on {amount(runs, 'protocol.final_eval_episodes', 'held-out scenes')}, mean over "
            f"subtasks; {over_seeds(runs)}.")


def guide_text(runs: pd.DataFrame) -> str:
    """Which sub-goal planner guides, and how long it trained."""
    return f"`{setting(runs, 'motion.name')}`, {amount(runs, 'motion.steps', 'training steps')}"


@register_section("fig_3_13")
def fig_3_13(runs: pd.DataFrame) -> Section:
    intro = (f"Algorithm 1: DDPG + HER whose actions the two-level planner ({guide_text(runs)}) corrects beyond "
             f"δg = {amount(runs, 'rl.delta_g', 'm')} in a fraction λ of the episodes; δr = "
             f"{amount(runs, 'rl.delta_r', 'm')}; " + budget_text(runs))
    section = curves_section(runs, "Fig. 3.13: hybrid guidance vs full guidance vs pure exploration", intro,
                             "fig_3_13.png")
    section.results = pd.concat([section.results, results_frame([hybrid_claim(section.results)])],
                                ignore_index=True)
    return section


def hybrid_claim(results: pd.DataFrame) -> dict:
    """Fig. 3.13's claim, from the final policies' SR per (λ, experiment): λ = 0.7 ends above λ = 0 and λ = 1 in
    every experiment the runs have."""
    table = results.pivot(index="row", columns="column", values="mean")
    lams = [lam for lam in ("0", "0.7", "1") if lam in table.index]
    text = "; ".join(f"{column.replace('_', ' ')} " + " / ".join(f"{table.loc[lam, column]:.2f}" for lam in lams)
                     for column in table.columns)
    met = None
    if set(lams) == {"0", "0.7", "1"}:
        met = bool((table.loc["0.7"] > table.loc["0"]).all() and (table.loc["0.7"] > table.loc["1"]).all())
    return {"row": "claim", "column": "", "text": f"λ {' / '.join(lams)}: {text}", "met": met}


@register_section("fig_3_12")
def fig_3_12(runs: pd.DataFrame) -> Section:
    intro = (f"Place and stack: DDPG + HER guided (λ = 1) by the NDP in mode {keyed(runs, 'motion.ndp.mode')} "
             f"towards the sub-goals of {guide_text(runs)} beyond δg = {amount(runs, 'rl.delta_g', 'm')}, vs "
             f"unguided (λ = 0); δr = {amount(runs, 'rl.delta_r', 'm')}; " + budget_text(runs))
    section = curves_section(runs, "Fig. 3.12: place and stack, NDP guidance vs unguided DRL", intro, "fig_3_12.png")
    section.results = pd.concat([section.results, results_frame([guided_claim(runs)])], ignore_index=True)
    return section


def guided_claim(runs: pd.DataFrame) -> dict:
    """Fig. 3.12's claim: the guided agent learns each task faster than the unguided one, read as the SR over
    every epoch (the area under the learning curve). Runs without an unguided arm (an ablation of the guide) are
    compared with the default runs' unguided arm of the same store."""
    runs = with_curve_summaries(runs)[0]
    unguided = runs[runs.lam == "0"]
    source = ""
    if unguided.empty:
        default = default_runs_of(runs)
        unguided = with_curve_summaries(default)[0] if not default.empty else default
        unguided = unguided[unguided.lam == "0"] if not unguided.empty else unguided
        source = " (unguided: the default study's runs)"
    parts, met = [], []
    for scenario in sorted(runs.scenario.unique()):
        guided = spread(runs[(runs.scenario == scenario) & (runs.lam != "0")], "mean_epochs_success_rate")[0]
        alone = spread(unguided[unguided.scenario == scenario], "mean_epochs_success_rate")[0] \
            if not unguided.empty else float("nan")
        parts.append(f"{scenario} {guided:.2f} / {alone:.2f}")
        met.append(guided > alone if alone == alone else None)
    known = [m for m in met if m is not None]
    return {"row": "claim", "column": "", "met": all(known) if known and len(known) == len(met) else None,
            "text": "SR over epochs, guided / unguided: " + ", ".join(parts) + source}


@register_section("fig_3_9")
def fig_3_9(runs: pd.DataFrame) -> Section:
    within = setting_number(runs, "protocol.within_m")
    fig, axes = plt.subplots(1, max(1, runs.scenario.nunique()), figsize=(5 * max(1, runs.scenario.nunique()), 3.2),
                             squeeze=False)
    rows, csv, results = [], [], []
    for ax, (scenario, part) in zip(axes[0], runs.groupby("scenario")):
        for k, arm in enumerate(("guided", "unguided")):
            history = histories(part, f"distance_{arm}")
            for _, one in history.groupby("run_id"):
                ax.plot(one.step, one.value, color=f"C{k}", alpha=0.25, linewidth=0.8)
            mean = history.groupby("step").value.mean()
            ax.plot(mean.index, mean.values, color=f"C{k}", linewidth=2, label=arm)
            key = {"scenario": scenario, "arm": arm}
            csv += [{**key, "step": int(s), "metric": "distance_m", "mean": v, "std": None} for s, v in mean.items()]
            row = {"task": scenario, "exploration": arm}
            for metric, label in ((f"mean_distance_{arm}", "mean ‖Δ‖ (m)"), (f"p95_distance_{arm}", "95th "
                                  "percentile (m)"), (f"within_{within:g}_{arm}", f"share of steps ≤ {within:g} m"),
                                  (f"mean_goal_distance_{arm}", "mean ‖eef − task goal‖ (m)")):
                mean_, std = spread(part, metric)
                row[label] = fmt(mean_, std, digits=2 if metric.startswith("within") else 3)
                csv.append({**key, "step": None, "metric": metric.removesuffix(f"_{arm}"), "mean": mean_, "std": std})
            rows.append(row)
            p95 = f"p95_distance_{arm}"
            results.append({"row": arm, "column": scenario, **dict(zip(("mean", "std"), spread(part, p95))),
                            "n": int(part[p95].notna().sum()) if p95 in part else 0})
        ax.axhline(within, color="black", linestyle="--", linewidth=1, label=f"{within:g} m")
        ax.set_title(scenario, fontsize=9)
        ax.set_xlabel("control step")
        ax.set_ylabel("|Δ| = |sub-goal − end effector| (m)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    text = [
        f"Random actions ({amount(runs, 'protocol.episodes', 'episodes')} per arm and seed, the same scenes), "
        f"corrected by Algorithm 1 with the NDP in mode {keyed(runs, 'motion.ndp.mode')} wherever they would leave "
        "the sub-goal by more than δg (guided), or never (unguided). ‖Δ‖: the end effector's distance to the "
        f"two-level planner's current sub-goal (3.2.2); {over_seeds(runs)}.",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no runs)",
    ]
    return Section("Fig. 3.9: the goal-state positional difference in guided vs unguided exploration", "\n".join(text),
                   pd.DataFrame(csv), {"fig_3_9.png": fig}, results=results_frame(results))


@register_section("fetch")
def fetch(runs: pd.DataFrame) -> Section:
    """The public anchor: the agent and loop of the robot cells on gymnasium-robotics' Fetch tasks, success per
    training episode beside the published result (:data:`hrc_lab.rl.benchmarks.PUBLISHED`)."""
    from hrc_lab.rl.benchmarks import PUBLISHED

    per_epoch = (runs[f"{PARAM_PREFIX}rl.cycles_per_epoch"].astype(int)
                 * runs[f"{PARAM_PREFIX}rl.episodes_per_cycle"].astype(int))
    runs = runs.assign(episodes_per_epoch=per_epoch.values)
    history = histories(runs, "success_rate").merge(runs[["run_id", "scenario", "episodes_per_epoch"]], on="run_id")
    history["episodes"] = history.step * history.episodes_per_epoch
    wall = histories(runs, "epoch_s").groupby("run_id").value.sum() / 60
    runs = runs.assign(last_epochs_success_rate=runs.run_id.map(epochs_sr(runs, history, LAST_EPOCHS)),
                       train_min=runs.run_id.map(wall))
    tasks = sorted(runs.scenario.unique())
    fig, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 3.6), squeeze=False)
    rows, csv = [], []
    for ax, task in zip(axes[0], tasks):
        part = history[history.scenario == task]
        for _, one in part.groupby("run_id"):
            ax.plot(one.episodes, one.value, color="C0", alpha=0.3, linewidth=0.8)
        mean = part.groupby("episodes").value.mean()
        ax.plot(mean.index, mean.values, "o-", color="C0", linewidth=2, label="hrc_lab DDPG + HER (mean over seeds)")
        csv += [{"task": task, "episodes": int(e), "sr_mean": v} for e, v in mean.items()]
        published = PUBLISHED.get(task)
        if published is not None:
            low, high = published["episodes"]
            middle = (low * high) ** 0.5
            ax.errorbar([middle], [published["success_rate"]], xerr=[[middle - low], [high - middle]], fmt="s",
                        color="C3", capsize=4, label=f"published: ~{published['success_rate']:g} by "
                                                     f"{low:,}-{high:,} episodes")
        ax.set_xscale("log")
        ax.set_ylim(-0.05, 1.05)
        ax.set_title(task, fontsize=9)
        ax.set_xlabel("training episodes")
        ax.set_ylabel("success rate (deterministic policy)")
        ax.legend(fontsize=7, loc="upper left")
        done = runs[runs.scenario == task]
        rows.append({"task": task, "seeds": len(done),
                     "training episodes": int(done.n_episodes.max()),
                     "final SR": fmt(*spread(done, "final_success_rate")),
                     f"SR, last {LAST_EPOCHS} epochs": fmt(*spread(done, "last_epochs_success_rate")),
                     "best SR": fmt(*spread(done, "best_success_rate")),
                     "training wall time per seed, min": fmt(*spread(done, "train_min"), 0),
                     "published": (f"~{published['success_rate']:g} after {published['episodes'][0]:,}-"
                                   f"{published['episodes'][1]:,} episodes ({published['source']})")
                     if published else "–"})
    fig.tight_layout()
    text = [
        "The agent and loop of Fig. 3.12 / 3.13 (`rl=ddpg_her`, the HER paper's settings) on gymnasium-robotics' "
        "Fetch tasks, where the HER reference implementation was published (19 workers there, one CPU core per "
        f"seed here). An epoch: {amount(runs, 'rl.cycles_per_epoch', 'cycles')} of "
        f"{amount(runs, 'rl.episodes_per_cycle', 'episodes')}, then "
        f"{amount(runs, 'protocol.eval_episodes', 'evaluation episodes')} on held-out goals; {over_seeds(runs)}.",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    return Section("A public anchor: the same agent and loop on gymnasium-robotics' Fetch tasks", "\n".join(text),
                   pd.DataFrame(csv), {"fetch.png": fig})


HYBRID = f"{thesis_results()['ch3']['text']['hybrid_guidance_lambda']:g}"  # the thesis' λ, a result row of ours
ONE_OBJECT_HYBRID = ("env=error_correction_one_object_case1", f"rl.lam={HYBRID}")

# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch3_rl",
    title="Ch.3 hybrid hierarchical guided RL (Algorithm 1): DDPG + HER guided by the two-level planner",
    note="Training runs in our robosuite UR5e error-correction cells as a gymnasium goal env, not the "
         "thesis' CoppeliaSim UR10; the agent is DDPG + HER with the HER paper's settings where the thesis gives "
         "none, and an epoch is the HER reference implementation's.",
    studies=(
        Study("ch3/fig_3_13"),
        Study("ch3/fig_3_12"),
        Study("ch3/fig_3_9"),
        Study("ch3/fig_3_13", (*ONE_OBJECT_HYBRID, "rl.steps_per_subtask=40"), key="fig_3_13_40_steps",
              title="Fig. 3.13 at the thesis' 40 control steps per subtask (one object, λ = 0.7)",
              question="Does the hybrid reach the thesis' success rate within the thesis' episode length?"),
        Study("ch3/fig_3_13", (*ONE_OBJECT_HYBRID, "rl.steps_per_subtask=40", "motion=tc_vi",
                               "motion.place_through_grasp=False", "protocol.stage_starts=[demonstrated]"),
              key="fig_3_13_tc_vi", title="Fig. 3.13 as written: the thesis' tc_vi guides, 40 steps (one object, "
                                         "λ = 0.7)",
              question="Does the thesis' own sub-goal planner, without hrc_lab's additions, guide Algorithm 1 to "
                       "the thesis' success rate?"),
        Study("ch3/fig_3_12", ("rl.lam=1", "motion.ndp.mode=direction", "rl.guidance=ndp_direction"),
              key="fig_3_12_direction", title="Fig. 3.12 with the thesis' direction-only NDP as guide",
              question="Does the thesis' direction-only NDP also make the guided agent learn place and stack "
                       "faster than the unguided one?"),
        Study("rl/fetch"),
    ),
    rows=(
        Row("Fig. 3.13", f"Hybrid guidance (λ = {HYBRID}): final SR", "ch3.fig_3_13.hybrid",
            Pick("fig_3_13_tc_vi", HYBRID, "the thesis' tc_vi guide and episode length"),
            star=Pick("fig_3_13", HYBRID, "hrc_lab's tc_vi_object guide, longer episodes"),
            why="fewer epochs than the thesis'; the episode length ([40 steps](#fig_3_13_40_steps)) and the guide "
                "([the thesis' tc_vi](#fig_3_13_tc_vi)) each measured"),
        Row("Fig. 3.13", f"λ = {HYBRID} above λ = 0 and λ = 1", "", None, star=Pick("fig_3_13", "claim"),
            claim="hybrid guidance ends above full guidance (which overfits) and pure exploration (sample-"
                  "inefficient)"),
        Row("Fig. 3.12", "Guided DRL learns place and stack faster than unguided", "",
            Pick("fig_3_12_direction", "claim", "direction-only NDP"), star=Pick("fig_3_12", "claim", "regression NDP"),
            claim="the NDP-guided agent learns both tasks faster than unguided DRL",
            why="the thesis' NDP outputs directions only; hrc_lab's regresses the joint deltas ([direction-only]"
                "(#fig_3_12_direction))"),
        Row("Fig. 3.9", "Guided exploration: 95th percentile of ‖Δ‖ (m)", "ch3.fig_3_9.guided_within_m",
            Pick("fig_3_9", "guided"), higher=False),
    ),
)
