"""Report sections of the Ch.3 guided-RL experiments (Algorithm 1): Fig. 3.13 (hybrid vs full guidance vs pure
exploration on error correction), Fig. 3.12 (place and stack, NDP guidance vs none) and Fig. 3.9
(the goal-state positional difference in guided vs unguided exploration). Curves come from the runs' per-epoch
metric histories (MLflow metrics logged with step = epoch; an epoch is defined in
:mod:`hrc_lab.experiments.ch3_rl`)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from hrc_lab.report.plan import Plan, Study  # noqa: E402
from hrc_lab.report.runs import (  # noqa: E402
    PARAM_PREFIX,
    amount,
    histories,
    keyed,
    over_seeds,
    setting_number,
    setting_values,
    spread,
)
from hrc_lab.report.sections import Section, register_section  # noqa: E402
from hrc_lab.report.thesis import fmt, markdown_table, thesis_results  # noqa: E402

ARMS = {"0": "pure exploration (λ = 0)", "0.7": "hybrid (λ = 0.7)", "1": "full guidance (λ = 1)"}


def lam_of(runs: pd.DataFrame) -> pd.Series:
    """The guidance ratio of each run as text ("0", "0.7", "1"), from its logged ``rl.lam``."""
    return runs[f"{PARAM_PREFIX}rl.lam"].astype(float).map(lambda v: f"{v:g}")


LAST_EPOCHS = 3  # "SR, last epochs": the evaluations of a subtask's last 3 epochs pooled (60 episodes at 20 each)
# a row's budget: protocol.epochs, rl.learning_rate -> rl.final_learning_rate, protocol.expert_demos
BUDGET = "epochs (Adam step size), demonstrations"


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


def curves_section(runs: pd.DataFrame, title: str, intro: str, thesis_line: str, png: str) -> Section:
    """SR per epoch for every (scenario, lambda, budget): each run light, the mean over seeds bold; the final-epoch
    table. Runs of another budget (epochs, Adam step size, demonstrations) get their own row and curve, never a
    shared mean."""
    runs = runs.assign(lam=lam_of(runs), budget=runs.apply(run_budget, axis=1))
    history = histories(runs, "success_rate").merge(runs[["run_id", "scenario", "lam", "budget", "seed"]],
                                                    on="run_id")
    runs = runs.assign(last_epochs_success_rate=runs.run_id.map(epochs_sr(runs, history, LAST_EPOCHS)),
                       mean_epochs_success_rate=runs.run_id.map(epochs_sr(runs, history)))
    # per subtask, where a plan has several: the final policies' SR and the last epoch's training episodes' SR
    train_by_subtask = subtask_sr(runs, histories(runs, "train_success_rate"), last=1)
    train_by_subtask = train_by_subtask.unstack() if len(train_by_subtask) else pd.DataFrame()
    # the subtasks these runs logged (a column only other runs of the store logged is empty here)
    final_by_subtask = sorted((c for c in runs if c.startswith("final_policy_success_rate_subtask")
                               and runs[c].notna().any()),
                              key=lambda c: int(c.removeprefix("final_policy_success_rate_subtask")))
    several_subtasks = train_by_subtask.shape[1] > 1 or len(final_by_subtask) > 1
    scenarios = sorted(runs.scenario.unique())
    fig, axes = plt.subplots(1, len(scenarios), figsize=(5 * len(scenarios), 3.4), squeeze=False)
    rows, csv = [], []
    for ax, scenario in zip(axes[0], scenarios):
        arms = runs[runs.scenario == scenario][["lam", "budget"]].drop_duplicates()
        several = arms.budget.nunique() > 1
        for k, (lam, budget) in enumerate(sorted(arms.itertuples(index=False), key=lambda a: (float(a[0]), a[1]))):
            colour = f"C{k}"
            part = history[(history.scenario == scenario) & (history.lam == lam) & (history.budget == budget)]
            for _, one in part.groupby("run_id"):
                ax.plot(one.step, one.value, color=colour, alpha=0.25, linewidth=0.8)
            mean = part.groupby("step").value.mean()
            label = ARMS.get(lam, f"λ = {lam}") + (f", {budget}" if several else "")
            ax.plot(mean.index, mean.values, color=colour, linewidth=2, label=label)
            csv += [{"scenario": scenario, "lam": lam, "budget": budget, "epoch": int(s), "sr_mean": v}
                    for s, v in mean.items()]
            done = runs[(runs.scenario == scenario) & (runs.lam == lam) & (runs.budget == budget)]
            row = {"experiment": scenario.replace("_", " "), "λ": lam, "seeds": len(done),
                   BUDGET: budget}
            for metric, label in (("final_success_rate", "final SR"),
                                  ("final_policy_success_rate", "final policy SR"),
                                  ("last_epochs_success_rate", f"SR, last {LAST_EPOCHS} epochs"),
                                  ("best_success_rate", "best SR"),
                                  ("mean_epochs_success_rate", "SR, mean over epochs"),
                                  ("final_distance", "final ‖P_obj − P_goal‖ (evaluation)"),
                                  ("final_grip_rate", "evaluation episodes that held the part"),
                                  ("final_moved_rate", "evaluation episodes that moved it > 2 cm"),
                                  ("final_train_success_rate", "final training-episode SR"),
                                  ("final_train_grip_rate", "training episodes that held the part"),
                                  ("final_train_moved_rate", "training episodes that moved it > 2 cm"),
                                  ("final_train_distance", "training episodes' final ‖P_obj − P_goal‖"),
                                  ("final_collision_rate", "collisions"), ("mean_guidance_rate", "guidance rate"),
                                  ("mean_env_steps_per_s", "env steps/s"), ("mean_updates_per_s", "updates/s")):
                digits = 0 if metric.startswith("mean_env") or metric.startswith("mean_up") else 2
                row[label] = fmt(*spread(done, metric), digits=digits)
            if several_subtasks:
                row["final policy SR by subtask"] = by_subtask(done.reindex(columns=final_by_subtask))
                row["training-episode SR by subtask (last epoch)"] = by_subtask(
                    train_by_subtask.reindex(done.run_id))
            rows.append(row)
        ax.set_title(scenario.replace("_", " "), fontsize=9)
        ax.set_xlabel("epoch (subtasks in sequence)")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel("success rate (evaluation)")
        ax.set_ylim(-0.02, 1.02)
        ax.legend(fontsize=7)
    fig.tight_layout()
    text = [intro, "", thesis_line, "", markdown_table(pd.DataFrame(rows)) if rows else "(no runs)"]
    if any("–" in row.values() for row in rows):
        text += ["", "–: a metric these runs did not log (they ran before it was added)."]
    return Section(title, "\n".join(text), pd.DataFrame(csv), {png: fig})


def run_budget(run: pd.Series) -> str:
    """A run's epochs per subtask, Adam step size and scripted-expert demonstrations per subtask, e.g.
    "10 (0.001 → 0.0001), 300" for ``rl.final_learning_rate``'s linear fall, "4 (0.001), 50" when constant (runs
    from before the key logged none); "?" for a key the run did not log."""
    start, final = run.get(f"{PARAM_PREFIX}rl.learning_rate"), run.get(f"{PARAM_PREFIX}rl.final_learning_rate")
    rate = f"{float(start):g}" if pd.notna(start) else "?"
    if pd.notna(final) and str(final) != "None":  # MLflow logs a null as the text "None"
        rate += f" → {float(final):g}"
    demos = run.get(f"{PARAM_PREFIX}protocol.expert_demos")
    return f"{run.get(f'{PARAM_PREFIX}protocol.epochs', '?')} ({rate}), {demos if pd.notna(demos) else '?'}"


def net_arch(runs: pd.DataFrame) -> str:
    """The logged hidden layers (params ``rl.net_arch.<i>``) as "64 x 64", or "not logged"."""
    prefix = f"{PARAM_PREFIX}rl.net_arch."
    columns = sorted((c for c in runs if c.startswith(prefix)), key=lambda c: int(c.removeprefix(prefix)))
    if not columns:
        return "(`rl.net_arch` not logged)"
    archs = {" x ".join(str(v) for v in row if v == v) for row in runs[columns].itertuples(index=False)}
    return " or ".join(sorted(archs)) + " units"


def inputs_text(runs: pd.DataFrame) -> str:
    """Whether the runs' networks saw the HER paper's normalised inputs (``rl.normalize_inputs``)."""
    column = f"{PARAM_PREFIX}rl.normalize_inputs"
    # runs from before the key existed had raw inputs
    values = set(runs[column].fillna("False").astype(str)) if column in runs else {"False"}
    names = {"True": "inputs normalised as in the HER paper", "False": "raw inputs"}
    return " or ".join(names.get(v, f"rl.normalize_inputs={v}") for v in sorted(values))


def reward_text(runs: pd.DataFrame) -> str:
    """Which reward the runs trained on (``rl.reward``; runs from before the key had Eq. 3.6's)."""
    column = f"{PARAM_PREFIX}rl.reward"
    values = set(runs[column].fillna("sparse").astype(str)) if column in runs else {"sparse"}
    names = {"sparse": "Eq. 3.6's sparse reward (0 within δr, else -1)",
             "dense": "a dense reward, -Σ ‖P_obj − P_goal‖ (success still Eq. 3.6's within δr)"}
    return " or ".join(names.get(v, f"rl.reward={v}") for v in sorted(values))


GUIDE_PLANNERS = {"tc_vi": "the thesis' sub-goal planner (`tc_vi`)",
                  "tc_vi_object": "hrc_lab's sub-goal planner (`tc_vi_object`, Table 3.1's best)"}
GUIDE_OBJECTS = {"classifier": "the object of c(x_1)'s label",
                 "picking_classifier": "c(x_1)'s most likely picking label",
                 "ground_truth": "the episode's goal object, not c(x_1) (`rl.stage_labels=ground_truth`, a diagnosis)"}
GUIDE_ALONE_M = 1e-3  # a delta_g below this with lambda 1 corrects every step: the runs measure the guide alone


def guide_text(runs: pd.DataFrame) -> str:
    """The guide of the runs: its sub-goal planner (``motion.name``), what named the object a guided episode goes
    for (``rl.stage_labels``; runs from before the key: c(x_1)'s label), whether its training pairs also start
    where the closed loop starts a stage (``protocol.stage_starts``), whether it places through the cup's grip
    (``motion.place_through_grasp``), and, with ``rl.delta_g`` below 1 mm and λ = 1, that every step was the
    guide's."""
    planners = setting_values(runs, "motion.name")
    rules = setting_values(runs, "rl.stage_labels") or ["classifier"]
    text = ("Guide: " + " or ".join(GUIDE_PLANNERS.get(p, f"`{p}`") for p in planners or ["?"])
            + ", going for " + " or ".join(GUIDE_OBJECTS.get(r, f"`rl.stage_labels={r}`") for r in rules) + ".")
    starts = {v for c in runs if c.startswith(f"{PARAM_PREFIX}protocol.stage_starts.") for v in runs[c].dropna()}
    if "executed" in starts:
        text += (" Its training pairs start each stage both where the demonstrator's lip was at the change point and "
                 "where the closed loop starts it (`protocol.stage_starts`, docs/chapters/ch3_motion.md).")
    if "True" in setting_values(runs, "motion.place_through_grasp"):
        text += (" Its placing sub-goals move by the lip's offset from the held part's centre, so that the part, "
                 "not the lip, reaches them (`motion.place_through_grasp`, docs/chapters/ch3_motion.md).")
    delta_g = setting_number(runs, "rl.delta_g")
    if delta_g is not None and delta_g < GUIDE_ALONE_M and set(lam_of(runs)) == {"1"}:
        text += (f" δg = {delta_g:g} m and λ = 1: the guide corrects every step, so these runs measure the guide "
                 "alone (its episodes are the training-episode columns).")
    return text


def ddpg_text(runs: pd.DataFrame) -> str:
    """Whether the runs' DDPG had the HER paper's action penalty, random actions and clipped targets
    (``rl.action_l2``, ``rl.random_eps``, ``rl.clip_return``; :class:`hrc_lab.rl.ddpg.HerDDPG`)."""
    columns = [f"{PARAM_PREFIX}rl.{key}" for key in ("action_l2", "random_eps", "clip_return")]
    if not all(c in runs for c in columns):
        return "stable-baselines3's DDPG without the HER paper's additions"  # runs from before the keys existed
    texts = set()
    for l2, eps, clip in runs[columns].itertuples(index=False):
        if l2 != l2:  # NaN: a run from before the keys existed
            texts.add("stable-baselines3's DDPG without the HER paper's additions")
        else:
            texts.add(f"the HER paper's DDPG (action penalty {float(l2):g}, random actions {float(eps):.0%}, "
                      f"targets {'clipped' if str(clip) == 'True' else 'not clipped'})")
    return " or ".join(sorted(texts))


def epoch_text(runs: pd.DataFrame) -> str:
    return (f"An epoch (the HER reference implementation's): {amount(runs, 'rl.cycles_per_epoch', 'cycles')} of "
            f"{amount(runs, 'rl.episodes_per_cycle', 'training episodes')} of "
            f"{amount(runs, 'rl.steps_per_subtask', 'control steps')} and "
            f"{amount(runs, 'rl.gradient_steps', 'gradient steps')}, then "
            f"{amount(runs, 'protocol.eval_episodes', 'evaluation episodes')} of the deterministic policy on held-out "
            f"scenes; {amount(runs, 'protocol.epochs', 'epochs')} per subtask (each row's, with its Adam step size and "
            "the scripted-expert demonstrations per subtask in the agent's demonstration buffer, in its own "
            "column), subtasks in sequence (thesis: within 550 epochs, read as the reference implementation's). "
            "Agent: DDPG + HER, hidden layers "
            f"{net_arch(runs)}, {inputs_text(runs)}, {ddpg_text(runs)}, {reward_text(runs)}; planner trained on "
            f"{amount(runs, 'protocol.demos', 'expert demonstrations')}. Final SR: the last epoch's evaluation, "
            "mean over the plan's subtasks; final policy SR: each subtask's last agent on "
            f"{amount(runs, 'protocol.final_eval_episodes', 'held-out scenes')} that no epoch's evaluation saw, "
            f"mean over the plan's subtasks; SR, last {LAST_EPOCHS} epochs: the evaluations of each subtask's last "
            f"{LAST_EPOCHS} epochs pooled; by subtask (plans of several): each subtask's value in the plan's "
            f"order, mean over seeds; {over_seeds(runs)}.")


@register_section("fig_3_13")
def fig_3_13(runs: pd.DataFrame) -> Section:
    ref = thesis_results()["ch3"]["text"]
    sr = ref["hybrid_guidance_final_sr"]
    thesis = (f"Thesis (Fig. 3.13): with the hybrid λ = {ref['hybrid_guidance_lambda']} the overall success rates "
              f"reach {sr[0]} and {sr[1]} within {ref['hybrid_guidance_epochs']} epochs without any collision; full "
              "guidance (λ = 1) overfits to one behaviour, pure exploration (λ = 0) is sample-inefficient, so hybrid "
              "beats both.")
    intro = ("Algorithm 1: DDPG + HER whose actions the two-level planner corrects (δg = "
             f"{amount(runs, 'rl.delta_g', 'm')}) in a fraction λ of the episodes, the next sub-goal planned after "
             f"H_lo = {amount(runs, 'rl.subgoal_steps', 'steps')} (or once reached), on the error-correction "
             f"experiments, δr = {amount(runs, 'rl.delta_r', 'm')}. " + guide_text(runs) + " " + epoch_text(runs))
    return curves_section(runs, "Fig. 3.13: hybrid guidance vs full guidance vs pure exploration", intro, thesis,
                          "fig_3_13.png")


@register_section("fig_3_12")
def fig_3_12(runs: pd.DataFrame) -> Section:
    intro = ("Place and stack: DDPG + HER guided (λ > 0) by the neural dynamic planner in mode "
             f"{keyed(runs, 'motion.ndp.mode')} (the thesis' outputs directions only), which corrects an action "
             f"that would leave the lip more than δg = {amount(runs, 'rl.delta_g', 'm')} from its sub-goal, "
             f"vs unguided (λ = 0); δr = {amount(runs, 'rl.delta_r', 'm')}. " + guide_text(runs) + " "
             + epoch_text(runs))
    thesis = ("Thesis (Fig. 3.12): the DRL agent guided by the direction-only NDP learns both tasks faster than "
              "unguided DRL (curves only; no final numbers are stated).")
    return curves_section(runs, "Fig. 3.12: place and stack, NDP guidance vs unguided DRL", intro,
                          thesis, "fig_3_12.png")


@register_section("fig_3_9")
def fig_3_9(runs: pd.DataFrame) -> Section:
    within = thesis_results()["ch3"]["text"]["guided_exploration_within_m"]
    fig, axes = plt.subplots(1, max(1, runs.scenario.nunique()), figsize=(5 * max(1, runs.scenario.nunique()), 3.2),
                             squeeze=False)
    rows, csv = [], []
    for ax, (scenario, part) in zip(axes[0], runs.groupby("scenario")):
        for k, arm in enumerate(("guided", "unguided")):
            history = histories(part, f"distance_{arm}")
            for _, one in history.groupby("run_id"):
                ax.plot(one.step, one.value, color=f"C{k}", alpha=0.25, linewidth=0.8)
            mean = history.groupby("step").value.mean()
            ax.plot(mean.index, mean.values, color=f"C{k}", linewidth=2, label=arm)
            csv += [{"scenario": scenario, "arm": arm, "step": int(s), "distance_m": v} for s, v in mean.items()]
            rows.append({"task": scenario, "exploration": arm, "seeds": len(part),
                         "mean ‖Δ‖ (m)": fmt(*spread(part, f"mean_distance_{arm}"), digits=3),
                         "95th percentile (m)": fmt(*spread(part, f"p95_distance_{arm}"), digits=3),
                         f"share of steps ≤ {within} m": fmt(*spread(part, f"within_{within:g}_{arm}")),
                         "mean ‖eef − task goal‖ (m)": fmt(*spread(part, f"mean_goal_distance_{arm}"), digits=3)})
        ax.axhline(within, color="black", linestyle="--", linewidth=1, label=f"thesis: within {within} m")
        ax.set_title(scenario, fontsize=9)
        ax.set_xlabel("control step")
        ax.set_ylabel("|Δ| = |sub-goal − end effector| (m)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    text = [
        f"Exploration with random actions ({amount(runs, 'protocol.episodes', 'episodes')} per arm and seed, the "
        "same scenes), corrected by Algorithm 1 with the direction-only NDP in every step where the action would "
        "leave the sub-goal by more than δg (guided), or never (unguided). ‖Δ‖: the goal-state positional "
        "difference of 3.2.2, the end effector's distance to the two-level planner's current sub-goal (in the "
        "unguided arm the planner only tracks its sub-goals); the thesis' demonstrations keep it under 0.12 m "
        "(Fig. 3.8). The last column is the distance to the task's goal instead. Curves: mean over episodes per "
        "run (light) and over seeds (bold).",
        "",
        f"Thesis (Fig. 3.9): the guided exploration keeps the goal-state positional difference within {within} m.",
        "",
        markdown_table(pd.DataFrame(rows)) if rows else "(no runs)",
    ]
    return Section("Fig. 3.9: the goal-state positional difference in guided vs unguided exploration", "\n".join(text),
                   pd.DataFrame(csv), {"fig_3_9.png": fig})



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
        ax.set_xlabel("training episodes (50 steps each)")
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
        "The DDPG + HER agent of Table 4.3's DRL and Fig. 3.12 / 3.13 (`rl=ddpg_her`, the HER paper's settings, "
        f"hidden layers {net_arch(runs)}), trained by the same loop (`hrc_lab/rl/trainer.py`) on gymnasium-robotics' "
        "Fetch tasks, the tasks the HER reference implementation was published on. An epoch: "
        f"{amount(runs, 'rl.cycles_per_epoch', 'cycles')} of {amount(runs, 'rl.episodes_per_cycle', 'episodes')} "
        f"and {amount(runs, 'rl.gradient_steps', 'gradient steps')}, then "
        f"{amount(runs, 'protocol.eval_episodes', 'evaluation episodes')} of the deterministic policy on held-out "
        f"goals (success: within 5 cm at the last step); SR, last {LAST_EPOCHS} epochs: their evaluations pooled. "
        "The published runs used 19 workers and 1,900 episodes per epoch; each seed here ran on one CPU core "
        "(wall time: the epochs' training and evaluation).",
        "",
        markdown_table(pd.DataFrame(rows)),
    ]
    return Section("A public anchor: the same agent and loop on gymnasium-robotics' Fetch tasks", "\n".join(text),
                   pd.DataFrame(csv), {"fetch.png": fig})


# The report's plan: its studies (hrc-lab-reproduce runs them) and the thesis rows it opens with.
PLAN = Plan(
    topic="ch3_rl",
    title="Ch.3 hybrid hierarchical guided RL (Algorithm 1): DDPG + HER guided by the two-level planner",
    note="Training runs in our robosuite UR5e error-correction cells as a gymnasium goal env, not the "
         "thesis' CoppeliaSim UR10; the agent is stable-baselines3's DDPG with its HER replay buffer.",
    studies=(Study("ch3/fig_3_13"), Study("ch3/fig_3_12"), Study("ch3/fig_3_9"), Study("rl/fetch")),
)
