"""Where does Algorithm 1's guide leave the part, and why? Trains the two-level planner of a Fig. 3.13 run's config
(the run's seed, its demonstrations; ``--stage-starts`` replaces ``protocol.stage_starts``) and rolls the guide
alone (every step corrected: lambda 1, delta_g 1e-6) through ``--episodes`` episodes of ``--subtask``, with
``--steps`` control steps per episode, ``--subgoal-steps`` (H_lo) and ``--subgoal-tolerance`` (the distance at which
a sub-goal counts as reached, in m). Per episode it prints the steps at which the cup gripped the part and the
episode first succeeded, the steps in which a joint moved at its limit, and, in cm: the planner's last sub-goal
minus the part's goal (the planner's error), the lip minus that sub-goal (the dynamic planner's), the lip minus
the part's centre when the cup gripped it (the grip's offset) and the part minus its goal; then the success rate.
A placing sub-goal is the lip's, so a right one is ~2.2 cm above the goal (the part's half height).
Scenes: the run's seed + 1000, not its training scenes. ``--residuals`` first prints the sub-goal planner's mean
and std residual (predicted minus demonstrated sub-goal, cm) on its own training pairs per stage label and
sub-goal index: a mean far from 0 is an underfit planner, not a hard scene.

    .venv/bin/python scripts/ch3_guide_rollouts.py <MLflow run id> --subtask 1 [--episodes 12]
        [--stage-starts demonstrated,executed] [--steps 40] [--subgoal-steps 4] [--subgoal-tolerance 0.008]
        [--set motion.place_through_grasp=true] [--residuals] [--tracking-uri URI]
"""

import argparse
import os
import tempfile

import numpy as np
import torch
import yaml
from mlflow.tracking import MlflowClient
from omegaconf import OmegaConf

from hrc_lab.config import ConfigError, validate_config
from hrc_lab.experiments.ch3_rl import guide_demos, train_guide_models
from hrc_lab.motion.two_level import correction_pairs
from hrc_lab.rl import RLS
from hrc_lab.rl.goal_env import make_goal_env
from hrc_lab.rl.guidance import CorrectionGuide, GuidedEnv
from hrc_lab.run_context import unlogged_trainer
from hrc_lab.tracking import saved_run

ROLLOUT_SCENES = 1000  # the rollouts' scene seed: the run's seed + this (not its training or evaluation scenes)


def print_residuals(planner, pairs) -> None:
    """Mean and std of the planner's sub-goal minus the demonstrated one (cm) per stage label and sub-goal index."""
    predicted, _ = planner.predict(pairs.x, pairs.labels, pairs.indices, pairs.references)
    residual = (predicted - pairs.subgoals) * 100
    print("planner residual on its training pairs, cm (x, y, z)")
    for label, index in sorted({*zip(pairs.labels.tolist(), pairs.indices.tolist())}):
        rows = residual[(pairs.labels == label) & (pairs.indices == index)]
        print(f"  label {label} sub-goal {index}: mean {np.round(rows.mean(0), 2)}, std {np.round(rows.std(0), 2)}, "
              f"{len(rows)} pairs", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_id")
    parser.add_argument("--subtask", type=int, required=True)
    parser.add_argument("--episodes", type=int, default=12)
    parser.add_argument("--stage-starts", help="comma-separated protocol.stage_starts (default: the run's)")
    parser.add_argument("--steps", type=int, help="control steps per episode (default: the run's)")
    parser.add_argument("--subgoal-steps", type=int, help="H_lo (default: the run's)")
    parser.add_argument("--subgoal-tolerance", type=float, help="a sub-goal's reach distance, m (default: the run's)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="replace a key of the run's config before the guide is trained, e.g. "
                             "motion.place_through_grasp=true (repeatable)")
    parser.add_argument("--residuals", action="store_true",
                        help="print the sub-goal planner's residuals on its training pairs first")
    parser.add_argument("--tracking-uri", default="sqlite:///runs/mlflow.db")
    args = parser.parse_args()
    torch.set_num_threads(1)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    with tempfile.TemporaryDirectory() as tmp:
        saved = saved_run(MlflowClient(args.tracking_uri), args.run_id, tmp, artifacts="config")
    cfg = saved.cfg
    if args.set:  # the run's composed config with the changes, validated again (an unknown key fails, named)
        for change in args.set:
            key, sep, value = change.partition("=")
            if not sep:
                parser.error(f"--set {change}: expected KEY=VALUE")
            OmegaConf.update(cfg.raw, key, yaml.safe_load(value), force_add=True)
        try:
            cfg = validate_config(cfg.raw)
        except ConfigError as error:
            parser.error(f"--set: {error}")
    starts = tuple(args.stage_starts.split(",")) if args.stage_starts else tuple(cfg.protocol.stage_starts)
    demonstrations = guide_demos(cfg, saved.seed)
    classifier, planner, ndp = train_guide_models(cfg, saved.seed, unlogged_trainer(cfg.trainer), starts,
                                                  demonstrations)
    if args.residuals:
        print_residuals(planner, correction_pairs(demonstrations[1], starts, cfg.motion.planner_input))
    changes = {k: v for k, v in (("steps_per_subtask", args.steps), ("subgoal_steps", args.subgoal_steps),
                                 ("subgoal_tolerance", args.subgoal_tolerance)) if v is not None}
    rl = RLS.derive(cfg.rl, lam=1.0, delta_g=1e-6, **changes)
    guide = CorrectionGuide.from_config(rl, classifier, planner, ndp, cfg.protocol.subgoals_per_stage)
    env = GuidedEnv(make_goal_env(cfg.env, rl, seed=saved.seed + ROLLOUT_SCENES, subtask=args.subtask), guide,
                    1.0, rl.delta_g, seed=saved.seed)
    cell, successes = env.unwrapped.cell, []
    print(f"stage starts {starts}, {rl.steps_per_subtask} steps, H_lo {rl.subgoal_steps}, sub-goals reached within "
          f"{rl.subgoal_tolerance} m; offsets in cm", flush=True)
    for episode in range(args.episodes):
        obs, _ = env.reset()
        grip = grip_step = success_step = None
        saturated = 0  # steps in which the guide drives a joint at >= 95 % of its per-step limit
        for step in range(1, env.unwrapped.horizon + 1):
            obs, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
            if grip is None and cell.suction.held >= 0:
                grip, grip_step = cell.grip_offset() * 100, step
            if success_step is None and info["is_success"]:
                success_step = step
            executed = info["executed_action"]
            saturated += executed is not None and np.abs(executed[:3]).max() >= 0.95
            if terminated or truncated:
                break
        goal = obs["desired_goal"][:3]
        successes.append(bool(info["is_success"]))
        grip_text = "none" if grip is None else np.round(grip, 1)
        print(f"episode {episode}: success {successes[-1]}, steps {env.unwrapped.elapsed_steps}, gripped at step "
              f"{grip_step}, first success at step {success_step}, a joint at its limit in {saturated} steps, "
              f"sub-goal - goal {np.round((guide.current - goal) * 100, 1)}, "
              f"lip - sub-goal {np.round((env.unwrapped.lip() - guide.current) * 100, 1)}, grip {grip_text}, "
              f"part - goal {np.round((obs['achieved_goal'][:3] - goal) * 100, 1)}", flush=True)
    print(f"success rate {np.mean(successes):.2f} over {args.episodes} episodes")
    env.close()


if __name__ == "__main__":
    main()
