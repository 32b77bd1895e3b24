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
from hrc_lab.env.robot.spec import goal_configurations, position_ranges, sample_episode
from hrc_lab.motion import MOTIONS
from hrc_lab.motion.demonstrations import collect_demos, fixed_goal_configurations
from hrc_lab.motion.training import train_motion_module
from hrc_lab.run_context import RunContext
from hrc_lab.seeds import TEST_SCENES, scene_seed


def cross_validated_r2(ctx: RunContext, pairs, folds: int) -> float:
    """R^2 of the sub-goal regressor on held-out demonstrations (GroupKFold over demos, uniform over x, y, z)."""
    from hrc_lab.motion.two_level import DESIGNED_SUBGOALS

    scores = []
    for k, (train, test) in enumerate(GroupKFold(folds).split(pairs.x, groups=pairs.groups)):
        planner = MOTIONS.build(ctx.cfg.motion, n_labels=1 + ctx.cfg.env.slots, n_subgoals=DESIGNED_SUBGOALS,
                                seed=ctx.seed)
        planner.fit(pairs.x[train], pairs.labels[train], pairs.subgoals[train], lambda k=k: ctx.trainer(f"cv{k}"),
                    pairs.indices[train], pairs.references[train])
        mean, _ = planner.predict(pairs.x[test], pairs.labels[test], pairs.indices[test], pairs.references[test])
        scores.append(r2_score(pairs.subgoals[test], mean))
    return float(np.mean(scores))


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
    module = train_motion_module(motion, spec.slots, train_env, demos, protocol.max_steps_per_subgoal,
                                 protocol.tolerance, ctx.trainer, ctx.seed, ctx.tracker.log_torch_model)

    # tests: every goal configuration (permutations unseen in training), CASE 1 and CASE 2 alternating
    test_envs = [ENVS.build(ENVS.derive(spec, sim=dataclasses.replace(spec.sim, case=c)),
                            seed=scene_seed(ctx.seed, TEST_SCENES)) for c in (1, 2)]
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
