"""Ch.3 motion experiments: Table 3.1 (two-level planner correcting human errors) and Fig. 3.10 (neural dynamic
planner vs. a full-observation actor)."""

from __future__ import annotations

from functools import partial

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.env import ENVS
from hrc_lab.motion.dagger import dagger, takeover_demos
from hrc_lab.motion.demonstrations import correction_demos
from hrc_lab.motion.training import train_two_level
from hrc_lab.run_context import RunContext
from hrc_lab.seeds import DAGGER_SCENES, TEST_SCENES, scene_seed

COLOURS = {1: "blue", 2: "red"}


def table_3_1(ctx: RunContext) -> dict[str, float]:
    from hrc_lab.motion.two_level import capped_share

    config, protocol = ctx.cfg.env, ctx.cfg.protocol
    env = ENVS.build(config, seed=ctx.seed)
    demos = correction_demos(env, protocol.demos, protocol.subgoals_per_stage, protocol.segmentation_penalty,
                             f"demos {config.cell}", protocol.placement_noise, ctx.rng(5), protocol.action_noise,
                             ctx.rng(6), protocol.subgoal_path)

    def train(data: list) -> tuple:
        return train_two_level(ctx.cfg.motion, env, data, protocol.stage_starts, protocol.subgoals_per_stage,
                               ctx.trainer, ctx.seed)

    collect = dagger_collector(ctx) if protocol.dagger_rounds else None
    models, aggregated = dagger(train, collect, demos, protocol.dagger_rounds)
    _, planner, ndp = models
    loop = correction_loop(protocol, models)
    test = ENVS.build(config, seed=scene_seed(ctx.seed, TEST_SCENES))
    rows, stage_rows = [], []
    for trial in tqdm(range(protocol.trials), desc=f"table 3.1 {config.cell}", unit="trial"):
        out, final = loop(test)
        missing = [np.full(3, np.nan)] * (len(out.picks) - len(out.pick_offsets))
        stage_rows += [{"trial": trial, "stage": k, "picked": COLOURS[obj], "expert": COLOURS[expert],
                        "moved_error_m": moved, "pick_xy_m": float(np.linalg.norm(offset[:2])),
                        "pick_z_m": float(offset[2]), "subgoal_xy_m": float(np.linalg.norm(planned[:2])),
                        "subgoal_z_m": float(planned[2])}
                       for k, (obj, expert, offset, planned, moved) in enumerate(zip(
                           out.picks, test.expert_plan(), out.pick_offsets + missing, out.subgoal_offsets + missing,
                           out.moved_errors))]
        for obj in test.expert_plan():
            distance = float(np.linalg.norm(final[obj] - test.goals[obj]))
            row = {"trial": trial, "object": COLOURS[obj], "distance": distance, "collision": bool(test.collisions),
                   "failure": out.failure, "subgoals": out.subgoals, "capped": out.capped,
                   "steps": out.object_steps.get(obj, np.nan), "planning_ms": float(np.mean(out.planning_ms))}
            for threshold in protocol.thresholds:
                row[f"success_{threshold:g}"] = distance <= threshold and not test.collisions
            rows.append(row)
    trials = pd.DataFrame(rows)
    ctx.tracker.log_table(trials, "trials")
    ctx.tracker.log_torch_model(planner.network, "model/subgoal.pt")
    ctx.tracker.log_torch_model(ndp.network, "model/ndp.pt")
    metrics = {"planning_ms": float(trials.planning_ms.mean()), "n_demos": float(len(demos))}
    if protocol.dagger_rounds:
        metrics["n_dagger_demos"] = float(len(aggregated) - len(demos))
    for colour, part in trials.groupby("object"):
        for threshold in protocol.thresholds:
            metrics[f"sr_{colour}_{threshold:g}"] = float(part[f"success_{threshold:g}"].mean())
        metrics[f"steps_{colour}"] = float(part.steps.mean())
    per_trial = trials.drop_duplicates("trial")
    for failure in ("pick", "collision", "horizon"):
        metrics[f"fail_{failure}"] = float((per_trial.failure == failure).mean())
    metrics["subgoals_capped"] = capped_share(per_trial)
    return metrics | stage_metrics(pd.DataFrame(stage_rows), ctx)


def correction_loop(protocol, models, **overrides):
    """The closed loop of Table 3.1 with the trained ``models`` (c(x), sub-goal planner, neural dynamic planner)
    and the protocol's execution settings: ``loop(env, **more)`` runs
    :func:`~hrc_lab.motion.two_level.run_correction`; ``overrides`` and ``more`` replace its keywords."""
    from hrc_lab.motion.two_level import run_correction

    classifier, planner, ndp = models
    settings = dict(n_subgoals=protocol.subgoals_per_stage, max_steps=protocol.max_steps_per_subgoal,
                    tolerance=protocol.tolerance, stage_labels=protocol.stage_labels,
                    planner_input=planner.config.planner_input,
                    place_through_grasp=planner.config.place_through_grasp, placement_oracle=protocol.placement_oracle)
    return partial(run_correction, planner=planner, ndp=ndp, classifier=classifier, **settings | overrides)


def dagger_collector(ctx: RunContext):
    """DAgger's expert labels for Table 3.1 (:mod:`hrc_lab.motion.dagger`): ``collect(models)`` rolls the loop of
    ``models`` in for ``protocol.dagger_episodes`` scenes of the job's DAgger scenes (their own stream,
    :data:`~hrc_lab.seeds.DAGGER_SCENES`; every round draws new ones) and returns the scripted expert's
    demonstrations of the later stages from there. The roll-in never uses the placement oracle: DAgger labels the
    states the learner reaches."""
    config, protocol = ctx.cfg.env, ctx.cfg.protocol
    env = ENVS.build(config, seed=scene_seed(ctx.seed, DAGGER_SCENES))
    rng = ctx.rng(7)
    return lambda models: takeover_demos(env, correction_loop(protocol, models, placement_oracle=False),
                                         protocol.dagger_episodes, protocol.subgoals_per_stage,
                                         protocol.segmentation_penalty, f"dagger {config.cell}",
                                         protocol.placement_noise, rng, protocol.subgoal_path)


def stage_metrics(stages: pd.DataFrame, ctx: RunContext) -> dict[str, float]:
    """Which object each picking stage went for (c(x)'s choice, or the expert's with ground-truth stage labels):
    ``stage<k>_right`` the share of stage-k starts that chose the expert's object, ``stage<k>_repeat`` the share that
    went back for the object an earlier stage had already moved; ``stage<k>_pick_xy_m`` / ``_pick_z_m`` the median
    horizontal distance and height of the lip from the picked object's top-face centre where the picking stage
    ended (the cup grips within the face, 2.5 cm of its centre), ``stage<k>_subgoal_xy_m`` / ``_subgoal_z_m`` the
    same of the stage's last planned sub-goal (the planner's share of the offset), ``stage<k>_moved_error_m`` the
    median distance of the objects moved before stage k from their goals at its start; the rows go to the run's
    ``stages`` table."""
    ctx.tracker.log_table(stages, "stages")
    metrics = {}
    for k, part in stages.groupby("stage"):
        metrics[f"stage{k + 1}_right"] = float((part.picked == part.expert).mean())
        metrics[f"stage{k + 1}_pick_xy_m"] = float(part.pick_xy_m.median())
        metrics[f"stage{k + 1}_pick_z_m"] = float(part.pick_z_m.median())
        metrics[f"stage{k + 1}_subgoal_xy_m"] = float(part.subgoal_xy_m.median())
        metrics[f"stage{k + 1}_subgoal_z_m"] = float(part.subgoal_z_m.median())
        if k > 0:
            metrics[f"stage{k + 1}_moved_error_m"] = float(part.moved_error_m.median())
            earlier = stages[stages.stage < k].groupby("trial").picked.agg(set)
            metrics[f"stage{k + 1}_repeat"] = float(np.mean([p in earlier.get(t, set())
                                                              for t, p in zip(part.trial, part.picked)]))
    return metrics


def fig_3_10(ctx: RunContext) -> dict[str, float]:
    """Mean |Delta| over 30 steps towards random sub-goals from the initial pose, for the neural dynamic planner
    (Delta only), its direction-only variant and the full-observation actor pi(r, s), all trained on the same
    error-correction demonstrations."""
    import dataclasses

    from hrc_lab.motion.subgoal import DynamicPlanner
    from hrc_lab.motion.two_level import dynamics_pairs

    protocol, ndp_config = ctx.cfg.protocol, ctx.cfg.motion.ndp
    demos = []
    for task in ("one_object", "two_object"):
        for case in (1, 2):
            config = ENVS.derive(ctx.cfg.env, task=task, sim=dataclasses.replace(ctx.cfg.env.sim, case=case))
            demos += correction_demos(ENVS.build(config, seed=ctx.seed), protocol.demos_per_case,
                                      protocol.subgoals_per_stage, protocol.segmentation_penalty,
                                      f"demos {config.cell}")
    env = ENVS.build(ENVS.derive(ctx.cfg.env, task="place"), seed=ctx.seed)
    r, s, a = dynamics_pairs(demos, ndp_config)
    controllers = {
        "ndp": DynamicPlanner(ndp_config, env.max_joint_step, env.base_position(), seed=ctx.seed),
        "ndp_direction": DynamicPlanner(dataclasses.replace(ndp_config, mode="direction"), env.max_joint_step,
                                        env.base_position(), seed=ctx.seed),
        "actor": DynamicPlanner(ndp_config, env.max_joint_step, env.base_position(), full_observation=True,
                                seed=ctx.seed),
    }
    for name, controller in controllers.items():
        controller.fit(r, s, a, lambda name=name: ctx.trainer(name))
    rng = ctx.rng(3)
    low, high = np.array(protocol.subgoal_low), np.array(protocol.subgoal_high)
    rows = []
    for trial in tqdm(range(protocol.trials), desc="fig 3.10", unit="trial"):
        subgoal = rng.uniform(low, high)
        for name, controller in controllers.items():
            env.reset()
            for step in range(protocol.steps + 1):
                r_t = env.eef_position()
                rows.append({"trial": trial, "controller": name, "step": step,
                             "distance": float(np.linalg.norm(subgoal - r_t))})
                if step < protocol.steps:
                    env.step(np.array([*controller.act(env.lip_target_position(), subgoal), -1.0]))
    curves = pd.DataFrame(rows)
    ctx.tracker.log_table(curves, "fig_3_10")
    mean_curve = curves.groupby(["controller", "step"]).distance.mean()
    metrics = {f"curve_{name}_{step:02d}": float(value) for (name, step), value in mean_curve.items()}
    final = curves[curves.step == protocol.steps].groupby("controller").distance
    metrics |= {f"final_m_{k}": float(v) for k, v in final.mean().items()}
    metrics |= {f"final_std_{k}": float(v) for k, v in final.std(ddof=0).items()}
    for name, part in curves.groupby("controller"):
        reached = part[part.distance < protocol.converged_m].groupby("trial").step.min()
        metrics[f"reached_{name}"] = float(len(reached) / protocol.trials)
        metrics[f"steps_to_converge_{name}"] = float(reached.mean()) if len(reached) else float("nan")
    return metrics
