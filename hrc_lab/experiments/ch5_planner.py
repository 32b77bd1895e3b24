"""Ch.5 semantic-planner protocols (Sec. 5.4.2, Table 5.2 planner columns). One job = (goal count, seed)."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.env.assembly.spec import (
    SCREW,
    AssembleToOrderSpec,
    HumanWorker,
    Scenario,
    ambiguous_scenarios,
    assembled_pairs,
    next_object,
    plan_text,
    plan_tokens,
    scenarios,
)
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop
from hrc_lab.reasoning.semantic_planner import SemanticPlanner, score_plans
from hrc_lab.reasoning.training import train_planner
from hrc_lab.run_context import RunContext


def evaluate_all(planner: SemanticPlanner, spec: AssembleToOrderSpec, tests: list[Scenario]) -> dict[str, float]:
    return score_plans(spec, tests, planner.plan([assembled_pairs(spec, s) for s in tests]))


def ambiguity_table(spec: AssembleToOrderSpec) -> pd.DataFrame:
    rows = [
        {"goal": f"g{s.goal}", "assembled": plan_text([f"{o}->p{p}" for o, p in assembled_pairs(spec, s)])}
        for s in ambiguous_scenarios(spec)
    ]
    return pd.DataFrame(rows, columns=["goal", "assembled"])


def success_ceiling(spec: AssembleToOrderSpec) -> float:
    """The best success rate any planner can reach: one scenario per group of indistinguishable ones."""
    groups = {tuple(assembled_pairs(spec, s)) for s in ambiguous_scenarios(spec)}
    return 1 - (len(ambiguous_scenarios(spec)) - len(groups)) / len(scenarios(spec))


def fig_5_7(ctx: RunContext) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    everything = scenarios(spec)
    sizes = {f"lam{r}": max(1, round(r * len(everything))) for r in protocol.ratios}
    sizes |= {f"n{n}": n for n in protocol.train_counts if n <= len(everything)}
    metrics = {"sr_ceiling": success_ceiling(spec), "n_scenarios": float(len(everything))}
    rows = []
    for i, (key, size) in enumerate(tqdm(sizes.items(), desc=f"fig 5.7 {spec.cell}", unit="ratio")):
        chosen = ctx.rng(40 + i).permutation(len(everything))[:size]
        planner = train_planner(ctx.cfg.reasoning, spec, [everything[j] for j in chosen], ctx.trainer, ctx.seed,
                                prefix=key)
        result = evaluate_all(planner, spec, everything)
        metrics[f"sr_{key}"] = result["sr"]
        rows.append(
            {
                "method": "semantic_planner",
                "seed": ctx.seed,
                "goals": spec.n_goals,
                "train": key,
                "n_train": size,
                **result,
            }
        )
    ctx.tracker.log_table(pd.DataFrame(rows), "fig_5_7")
    ctx.tracker.log_table(ambiguity_table(spec), "ambiguous_scenarios")
    return metrics


def run_session(planner: SemanticPlanner, human: HumanWorker, goal: int) -> dict[str, list[bool]]:
    """Stream one session through Algorithm 3 and score every planner answer against the truth: the Semantic
    Guidance after each assembly action (SG) and the Semantic Control at each screw event (SC). The robot places the
    expert's choice: when its command is wrong, the human puts the right part in, so the session stays on the goal."""
    spec = planner.spec

    def robot(part: str, position: int) -> tuple[str, int]:
        scenario = Scenario(goal, frozenset(loop.assembled))
        return next_object(spec, scenario), min(set(range(1, spec.n_positions + 1)) - scenario.assembled)

    loop = SemanticPlannerLoop(planner, robot, echo=None)
    truth: dict[str, list[bool]] = {"sg": [], "sc": []}
    while not loop.finished:
        for label in human.next_actions(loop.assembled):
            before = Scenario(goal, frozenset(loop.assembled))
            event = loop.step(label)
            if event is None:
                continue
            if label == SCREW:
                expected = next_object(spec, before)
                control = event.plan.control == plan_tokens(spec, before, expected)
                truth["sc"].append(event.plan.next_object == expected and control)
            else:
                now = Scenario(goal, frozenset(loop.assembled))
                truth["sg"].append(all(event.plan.guidance[t] == plan_tokens(spec, now, t) for t in spec.types))
    return truth


def table_5_2_planner(ctx: RunContext) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    everything = scenarios(spec)
    rng = ctx.rng(50)
    chosen = rng.permutation(len(everything))[: max(1, round(protocol.train_ratio * len(everything)))]
    planner = train_planner(ctx.cfg.reasoning, spec, [everything[j] for j in chosen], ctx.trainer, ctx.seed)

    sg, sc, rows = [], [], []
    for i in tqdm(range(protocol.sessions), desc=f"sessions {spec.cell}", unit="session"):
        goal = int(rng.integers(spec.n_goals))
        result = run_session(planner, HumanWorker(spec, goal, rng, protocol.p_screw), goal)
        sg += result["sg"]
        sc += result["sc"]
        rows.append(
            {
                "session": i,
                "goal": goal,
                "sg_acc": np.mean(result["sg"]) if result["sg"] else np.nan,
                "sc_acc": np.mean(result["sc"]) if result["sc"] else np.nan,
                "assembly_events": len(result["sg"]),
                "screw_events": len(result["sc"]),
            }
        )
    latencies = []
    for scenario in everything[: protocol.latency_samples]:
        start = time.perf_counter()
        planner.plan([assembled_pairs(spec, scenario)])
        latencies.append(time.perf_counter() - start)
    ctx.tracker.log_table(pd.DataFrame(rows), "table_5_2_planner_sessions")
    ctx.tracker.log_torch_model(planner.network, "model/semantic_planner.pt")
    return {
        "sg_acc": float(np.mean(sg)),
        "sc_acc": float(np.mean(sc)) if sc else float("nan"),
        "n_assembly_events": float(len(sg)),
        "n_screw_events": float(len(sc)),
        "scenario_sr": evaluate_all(planner, spec, everything)["sr"],
        "latency_ms": 1e3 * float(np.median(latencies)),
    }
