"""Ch.4 reasoning-module protocols (Sec. 4.4.1 and 4.4.5): Table 4.1, Fig. 4.7, the practical scenarios and the
GNNExplainer masks of Fig. 4.9. One Hydra job = one (experiment cell, method, seed); sweeps cover the rest.

A trial is an episode of the package-to-order task; it succeeds only if every prediction of P_o and P_g at the
start of each of its 2n picking and placing stages is right (Sec. 4.4.1).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.env.robot.spec import (
    PICK,
    PLACE,
    Episode,
    PackageToOrderSpec,
    combinations,
    configurations_of,
    goal_configurations,
    position_ranges,
    stage_observations,
)
from hrc_lab.reasoning import REASONERS
from hrc_lab.reasoning.base import Reasoner
from hrc_lab.reasoning.episodes import demo_repeats, episodes_for, observations_of, random_episodes
from hrc_lab.reasoning.training import train
from hrc_lab.run_context import RunContext

# Data and scoring ------------------------------------------------------------------------------------------------

PICK_ERRORS = ("area", "packed", "unselected", "other")
# per-head, per-stage accuracies and the kinds of picking errors, logged per case and ratio (Fig. 4.7) or scenario
DIAGNOSTICS = ("acc_o_pick", "acc_o_place", "acc_g_pick", "acc_g_place", *(f"pick_error_{k}" for k in PICK_ERRORS))


def evaluate(reasoner: Reasoner, episodes: list[Episode]) -> dict[str, float]:
    """Trial success rate (all 2n stage predictions right) and the accuracies of P_o and P_g over all stage
    predictions (``acc_o``, ``acc_g``) and per stage (``acc_o_pick``, ``acc_o_place``, ``acc_g_pick``, ...)."""
    per_episode = [stage_observations(e) for e in episodes]
    flat = [obs for stages in per_episode for obs in stages]
    predicted = reasoner.predict(flat)
    correct = predicted == reasoner.labels(flat)
    bounds = np.cumsum([0] + [len(stages) for stages in per_episode])
    trials = [correct[a:b].all() for a, b in zip(bounds[:-1], bounds[1:])]
    stage = np.array([obs.stage for obs in flat])
    metrics = {
        "sr": float(np.mean(trials)),
        "acc_o": float(correct[:, 0].mean()),
        "acc_g": float(correct[:, 1].mean()),
        "n_trials": float(len(trials)),
    }
    for name, value in (("pick", PICK), ("place", PLACE)):
        for head, column in (("o", 0), ("g", 1)):
            metrics[f"acc_{head}_{name}"] = float(correct[stage == value, column].mean())
    return metrics | pick_errors(flat, predicted[:, 0])


def pick_errors(observations: list, predicted_o: np.ndarray) -> dict[str, float]:
    """Where wrong P_o predictions at picking stages point, as shares of all picking stages: the packaging area (a
    placing stage assumed), an already packed product, an unselected product, or another selected, unpacked one."""
    counts = dict.fromkeys(PICK_ERRORS, 0)
    picks = [(obs, p) for obs, p in zip(observations, predicted_o) if obs.stage == PICK]
    for obs, p in picks:
        if p == obs.o_label:
            continue
        if p == 0:
            counts["area"] += 1
        elif obs.packed[p - 1]:
            counts["packed"] += 1
        else:
            counts["other" if obs.selected[p - 1] else "unselected"] += 1
    return {f"pick_error_{kind}": n / max(1, len(picks)) for kind, n in counts.items()}


def measure_latency(reasoner: Reasoner, observations: list, n_single: int = 100) -> dict[str, float]:
    """Milliseconds per decision on the CPU, graph construction included: one observation at a time (median)
    and in one batch (total time / batch size)."""
    singles = []
    for obs in observations[:n_single]:
        start = time.perf_counter()
        reasoner.predict([obs])
        singles.append(time.perf_counter() - start)
    start = time.perf_counter()
    reasoner.predict(observations)
    batched = (time.perf_counter() - start) / len(observations)
    return {"latency_ms_batch1": 1e3 * float(np.median(singles)), "latency_ms_batched": 1e3 * batched}


def result_row(ctx: RunContext, **values) -> dict:
    return {"method": ctx.cfg.reasoning.name, "seed": ctx.seed, **values}


# Table 4.1 -------------------------------------------------------------------------------------------------------


def table_4_1(ctx: RunContext) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    episodes = episodes_for(spec, goal_configurations(spec), ctx.rng(0), demo_repeats(spec, protocol.min_demos))
    order = ctx.rng(1).permutation(len(episodes))
    test_index = set(np.array_split(order, protocol.n_folds)[ctx.seed % protocol.n_folds].tolist())
    train_eps = [e for i, e in enumerate(episodes) if i not in test_index]
    test_eps = [e for i, e in enumerate(episodes) if i in test_index]

    reasoner, train_s = train(ctx.cfg.reasoning, spec, train_eps, ctx.trainer, ctx.seed)
    metrics = evaluate(reasoner, test_eps)
    metrics |= measure_latency(reasoner, observations_of(test_eps)) | position_ranges(test_eps)
    metrics |= {"train_s": train_s, "n_train_demos": float(len(train_eps))}
    ctx.tracker.log_table(pd.DataFrame([result_row(ctx, cell=spec.cell, **metrics)]), "table_4_1")
    if hasattr(reasoner, "network"):
        ctx.tracker.log_torch_model(reasoner.network, "model/reasoner.pt")
    return metrics


# Fig. 4.7 --------------------------------------------------------------------------------------------------------


def case1_split(spec: PackageToOrderSpec, ratio: float, rng) -> tuple[list, list]:
    """Fig. 4.7 CASE 1 (4.4.1): the goal configurations of round(λ x mCn) random selections, all their
    permutations, to train on, and those of every other selection to test on; at λ = 1 nothing is unseen and the
    test set is the training configurations again (with new positions)."""
    selections = combinations(spec)
    k = max(1, round(ratio * len(selections)))
    order = rng.permutation(len(selections))
    seen = [c for j in order[:k] for c in configurations_of(spec, selections[j])]
    unseen = [c for j in order[k:] for c in configurations_of(spec, selections[j])]
    return seen, unseen or seen


def fig_4_7(ctx: RunContext) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    configurations = goal_configurations(spec)
    metrics: dict[str, float] = {}
    rows = []
    for i, ratio in enumerate(tqdm(protocol.ratios, desc=f"fig 4.7 {spec.cell}", unit="ratio")):
        rng = ctx.rng(10 + i)
        # CASE 1: unseen goal configurations (selections never trained on)
        seen, unseen = case1_split(spec, ratio, rng)
        reasoner, _ = train(ctx.cfg.reasoning, spec, episodes_for(spec, seen, rng), ctx.trainer, ctx.seed,
                            prefix=f"case1_lam{ratio}")
        case1 = evaluate(reasoner, episodes_for(spec, unseen, rng)) | {"n_train_demos": float(len(seen))}
        # CASE 2: unseen task structures from human intervention
        k = max(1, round(ratio * len(configurations)))
        trained = [configurations[j] for j in rng.permutation(len(configurations))[:k]]
        reasoner, _ = train(ctx.cfg.reasoning, spec, episodes_for(spec, trained, rng), ctx.trainer, ctx.seed,
                            prefix=f"case2_lam{ratio}")
        case2 = evaluate(reasoner, random_episodes(spec, protocol.case2_tests, rng, case=2))
        case2 |= {"n_train_demos": float(k)}
        for case, result in (("case1", case1), ("case2", case2)):
            metrics[f"{case}_sr_lam{ratio}"] = result["sr"]
            metrics |= {f"{case}_{key}_lam{ratio}": result[key] for key in (*DIAGNOSTICS, "n_train_demos")}
            rows.append(result_row(ctx, cell=spec.cell, case=case, ratio=ratio, **result))
    ctx.tracker.log_table(pd.DataFrame(rows), "fig_4_7")
    return metrics


# Practical scenarios (4.4.5) -------------------------------------------------------------------------------------


def practical(ctx: RunContext) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    metrics: dict[str, float] = {}
    rows = []
    rng = ctx.rng(20)
    draw_missing = lambda: int(rng.integers(1, protocol.max_missing + 1))  # noqa: E731

    if REASONERS.load(ctx.cfg.reasoning.name).handles_missing_products:
        full = episodes_for(spec, goal_configurations(spec), rng, demo_repeats(spec, protocol.min_demos))
        partial = random_episodes(spec, protocol.partial_demos, rng, n_missing=draw_missing)
        tests = random_episodes(spec, protocol.missing_tests, rng, n_missing=draw_missing)
        for label, demos in (("missing_without_partial", full), ("missing", full + partial)):
            reasoner, _ = train(ctx.cfg.reasoning, spec, demos, ctx.trainer, ctx.seed, prefix=label)
            result = evaluate(reasoner, tests)
            metrics[f"{label}_sr"] = result["sr"]
            metrics |= {f"{label}_{key}": result[key] for key in DIAGNOSTICS}
            rows.append(result_row(ctx, scenario=label, cell=spec.cell, case="case1", **result))

    train_spec = dataclasses.replace(spec, n_selected=protocol.train_selected, n_slots=protocol.slots)
    demos = episodes_for(train_spec, goal_configurations(train_spec), rng, demo_repeats(train_spec, protocol.min_demos))
    reasoner, _ = train(ctx.cfg.reasoning, train_spec, demos, ctx.trainer, ctx.seed,
                        prefix=f"order_size_{train_spec.cell}")
    for n in tqdm(protocol.test_selected, desc="order sizes", unit="size"):
        test_spec = dataclasses.replace(train_spec, n_selected=n)
        for case in (1, 2):
            result = evaluate(reasoner, random_episodes(test_spec, protocol.test_tests, rng, case=case))
            metrics[f"order_size_{test_spec.cell}_case{case}_sr"] = result["sr"]
            metrics |= {f"order_size_{test_spec.cell}_case{case}_{key}": result[key] for key in DIAGNOSTICS}
            rows.append(
                result_row(
                    ctx,
                    scenario=f"order_size_from_{train_spec.cell}",
                    cell=test_spec.cell,
                    case=f"case{case}",
                    **result,
                )
            )
    ctx.tracker.log_table(pd.DataFrame(rows), "practical")
    return metrics


# Fig. 4.9 --------------------------------------------------------------------------------------------------------


def fig_4_9(ctx: RunContext) -> dict[str, float]:
    from hrc_lab.reasoning.explain import explain_stage, plot_explanations

    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    rng = ctx.rng(30)
    demos = episodes_for(spec, goal_configurations(spec), rng, demo_repeats(spec, protocol.min_demos))
    reasoner, _ = train(ctx.cfg.reasoning, spec, demos, ctx.trainer, ctx.seed)
    metrics: dict[str, float] = {}
    for case in (1, 2):
        observations = stage_observations(random_episodes(spec, 1, rng, case=case)[0])
        chosen = {"picking": observations[0], "placing": observations[1]}
        explanations = {stage: explain_stage(reasoner, obs, protocol.explainer_epochs) for stage, obs in chosen.items()}
        figure = plot_explanations(explanations, title=f"Fig. 4.9 analogue, CASE {case}, {spec.cell}")
        ctx.tracker.log_figure(figure, f"plots/fig_4_9_case{case}.png")
        for stage, explanation in explanations.items():
            for feature, value in explanation.feature_importance.items():
                metrics[f"case{case}_{stage}_importance_{feature}"] = value
    return metrics
