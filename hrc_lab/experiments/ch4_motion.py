"""Table 4.2 (thesis 4.4.2.1): sub-goal regressors on package-to-order demonstrations (R^2, 3-fold CV) and the
two-level motion module's success rate in the robot cell with ground-truth reasoning outputs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
from sklearn.metrics import r2_score
from sklearn.model_selection import GroupKFold
from tqdm import tqdm

from hrc_lab.env import ENVS
from hrc_lab.env.robot.spec import combinations, goal_configurations, position_ranges, sample_episode
from hrc_lab.experiments.context import RunContext
from hrc_lab.motion import MOTIONS


def fixed_goal_configurations(spec) -> list:
    """Training orders in which every selection is packed one way: the k-th lowest product into slot k (each
    product "only allowed to be manipulated to one goal position" per selection, 4.4.2.1)."""
    return [tuple((product, k) for k, product in enumerate(selection)) for selection in combinations(spec)]


def collect_demos(env, n: int, desc: str) -> list:
    from hrc_lab.env.robot.expert import ScriptedExpert
    from hrc_lab.experiments.collect import record_episode

    expert = ScriptedExpert(env)
    demos = [record_episode(env, expert) for _ in tqdm(range(n), desc=desc, unit="demo")]
    return [d for d in demos if d.success]


def cross_validated_r2(ctx: RunContext, pairs, folds: int) -> float:
    """R^2 of the sub-goal regressor on held-out demonstrations (GroupKFold over demos, uniform over x, y, z)."""
    from hrc_lab.motion.two_level import DESIGNED_SUBGOALS

    scores = []
    for k, (train, test) in enumerate(GroupKFold(folds).split(pairs.x, groups=pairs.groups)):
        planner = MOTIONS.build(ctx.cfg.motion, n_labels=1 + ctx.cfg.env.slots, n_subgoals=DESIGNED_SUBGOALS,
                                seed=ctx.seed)
        planner.fit(pairs.x[train], pairs.labels[train], pairs.subgoals[train], lambda k=k: ctx.trainer(f"cv{k}"),
                    pairs.indices[train])
        mean, _ = planner.predict(pairs.x[test], pairs.labels[test], pairs.indices[test])
        scores.append(r2_score(pairs.subgoals[test], mean))
    return float(np.mean(scores))


def train_motion_module(ctx: RunContext, env, demos, max_steps: int, tolerance: float):
    """Ours (4.2.2): the run's sub-goal planner (``motion``) on the demonstrations' sub-goal pairs and the neural
    dynamic planner on their steps (joint limit and base frame of the cell ``env``), as a
    :class:`~hrc_lab.motion.two_level.TwoLevelMotion`."""
    from hrc_lab.motion.subgoal import DynamicPlanner
    from hrc_lab.motion.two_level import DESIGNED_SUBGOALS, TwoLevelMotion, dynamics_pairs, package_pairs

    spec, motion = ctx.cfg.env, ctx.cfg.motion
    pairs = package_pairs(demos)
    planner = MOTIONS.build(motion, n_labels=1 + spec.slots, n_subgoals=DESIGNED_SUBGOALS, seed=ctx.seed)
    planner.fit(pairs.x, pairs.labels, pairs.subgoals, lambda: ctx.trainer("subgoal"), pairs.indices)
    ndp = DynamicPlanner(motion.ndp, env.max_joint_step, env.base_position(), seed=ctx.seed)
    ndp.fit(*dynamics_pairs(demos), lambda: ctx.trainer("ndp"))
    for name, model in (("subgoal", getattr(planner, "network", None)), ("ndp", ndp.network)):
        if model is not None:
            ctx.tracker.log_torch_model(model, f"model/{name}.pt")
    return TwoLevelMotion(planner, ndp, DESIGNED_SUBGOALS, max_steps, tolerance)


def sampled_ranges(spec, rng, repeats: int = 5) -> dict[str, float]:
    """Sec. 4.4.3's ranges as the cell's scene sampler draws them (the test envs sample scenes from the same spec):
    ``repeats`` scenes of every goal configuration."""
    return position_ranges([sample_episode(spec, c, rng) for c in goal_configurations(spec) for _ in range(repeats)])


def table_4_2(ctx: RunContext) -> dict[str, float]:
    from hrc_lab.motion.two_level import capped_share, package_pairs, run_package

    spec, protocol, motion = ctx.cfg.env, ctx.cfg.protocol, ctx.cfg.motion
    train_env = ENVS.build(spec, seed=ctx.seed)
    train_env.configurations = fixed_goal_configurations(spec)
    demos = collect_demos(train_env, protocol.demos, f"demos {spec.cell}")
    pairs = package_pairs(demos)
    r2 = cross_validated_r2(ctx, pairs, protocol.cv_folds)
    module = train_motion_module(ctx, train_env, demos, protocol.max_steps_per_subgoal, protocol.tolerance)

    # tests: every goal configuration (permutations unseen in training), CASE 1 and CASE 2 alternating
    test_envs = [ENVS.build(ENVS.derive(spec, sim=dataclasses.replace(spec.sim, case=c)), seed=1000 + ctx.seed)
                 for c in (1, 2)]
    rows = []
    for trial in tqdm(range(protocol.trials), desc=f"table 4.2 {spec.cell} {motion.name}", unit="trial"):
        env = test_envs[trial % 2]
        out = run_package(env, module)
        rows.append({"trial": trial, "case": 1 + trial % 2, "success": out.success, "failure": out.failure,
                     "steps": out.steps, "objects": len(out.object_steps),
                     "subgoals": out.subgoals, "capped": out.capped,
                     "planning_ms": float(np.mean(out.planning_ms)) if out.planning_ms else np.nan})
    trials = pd.DataFrame(rows)
    ctx.tracker.log_table(trials, "trials")
    done = trials[trials.objects > 0]
    metrics = {
        "r2": r2,
        "sr": float(trials.success.mean()),
        "sr_case1": float(trials[trials.case == 1].success.mean()),
        "sr_case2": float(trials[trials.case == 2].success.mean()),
        "planning_ms": float(trials.planning_ms.mean()),
        "steps_per_object": float(done.steps.sum() / max(done.objects.sum(), 1)),
        "subgoals_capped": capped_share(trials),
        "n_demos": float(len(demos)),
        "n_pairs": float(len(pairs.x)),
        **sampled_ranges(spec, ctx.rng(42)),
    }
    for failure in ("pick", "placement", "collision", "horizon"):
        metrics[f"fail_{failure}"] = float((trials.failure == failure).mean())
    table = pd.DataFrame([{"method": motion.name, "seed": ctx.seed, "cell": spec.cell, **metrics}])
    ctx.tracker.log_table(table, "table_4_2")
    return metrics
