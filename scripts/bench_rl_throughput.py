"""Throughput of RL in the robot loop, before and after, measured side by side in one run on one machine.

Fig. 3.13's one-object goal env and agent (2 x 64 networks, batch 256; rl=ddpg_her_guided's env settings, unguided):

- goal env control steps/s with random actions, robosuite's step vs the lean step (``env.sim.lean_step``);
- end-to-end training steps/s (collection and gradient steps, wall clock) for the same number of episodes:
  *before*: robosuite's step, one gradient step per collected step and a target update after each (what hrc_lab ran
  before the reference's cycle); *after*: the lean step and the HER reference implementation's cycle (2 episodes,
  40 gradient steps, one target update), with ``rl.n_envs`` 1 and 2.

The normaliser's statistics were also recomputed on every forward pass before (float64, ~7 ms of a 14 ms update);
that code is gone, so *before* here runs today's normaliser and understates the old cost.

    .venv/bin/python scripts/bench_rl_throughput.py --episodes 20 --out reports/ch3_rl/throughput.md
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from hrc_lab.env.robot.settings import ErrorCorrectionConfig, SimSettings
from hrc_lab.registry import named
from hrc_lab.rl import RLS
from hrc_lab.rl.agent import learn_episodes
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.goal_env import make_goal_env
from hrc_lab.rl.trainer import goal_env_factory, training_envs

AGENT = dict(suction="auto", delta_r=0.01, net_arch=[64, 64], buffer_size=100_000, learning_starts=80)


def cell_config(lean: bool) -> ErrorCorrectionConfig:
    return named(ErrorCorrectionConfig(sim=SimSettings(yaw_action=True, lean_step=lean)), "error_correction")


def env_steps_per_s(lean: bool, steps: int) -> float:
    env = make_goal_env(cell_config(lean), named(RLConfig(**AGENT), "ddpg_her"), seed=0, subtask=0)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(steps):
        *_, truncated, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        if truncated:
            env.reset()
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def training_steps_per_s(lean: bool, episodes: int, **loop) -> float:
    rl = named(RLConfig(**AGENT, **loop), "ddpg_her")
    envs = training_envs(goal_env_factory(cell_config(lean), rl, 0, subtask=0), rl.n_envs)
    agent = RLS.build(rl, env=envs, seed=0)
    learn_episodes(agent, 2 * rl.n_envs)  # warm-up (learning_starts): processes started, buffer seeded
    start, steps = time.perf_counter(), agent.num_timesteps
    learn_episodes(agent, 2 * rl.n_envs + episodes)
    rate = (agent.num_timesteps - steps) / (time.perf_counter() - start)
    envs.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=20, help="training episodes timed per row (40 steps each)")
    parser.add_argument("--env-steps", type=int, default=1000, help="random control steps timed per env row")
    parser.add_argument("--out", type=Path, help="also write the table (markdown) here")
    args = parser.parse_args()
    torch.set_num_threads(1)
    per_step = dict(episodes_per_cycle=1, gradient_steps=40, target_update="step")  # 1 update per collected step
    rows = [
        {"what": "goal env, random actions", "setting": "robosuite step", "steps/s": env_steps_per_s(False,
                                                                                                    args.env_steps)},
        {"what": "goal env, random actions", "setting": "lean step", "steps/s": env_steps_per_s(True, args.env_steps)},
        {"what": "training, end to end", "setting": "before: robosuite step, 1 update per step, targets per step",
         "steps/s": training_steps_per_s(False, args.episodes, **per_step)},
        {"what": "training, end to end", "setting": "after: lean step, reference cycle, 1 env",
         "steps/s": training_steps_per_s(True, args.episodes)},
        {"what": "training, end to end", "setting": "after: lean step, reference cycle, 2 envs (SubprocVecEnv)",
         "steps/s": training_steps_per_s(True, args.episodes, n_envs=2)},
    ]
    table = pd.DataFrame(rows)
    for _, part in table.groupby("what", sort=False):
        table.loc[part.index, "x first row"] = part["steps/s"] / part["steps/s"].iloc[0]
    text = table.round(2).to_markdown(index=False)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
