"""Throughput of RL in the robot loop, before and after, measured side by side in one run on one machine.

Fig. 3.13's one-object goal env and agent (2 x 64 networks, batch 256; rl=ddpg_her_guided's env settings, unguided):

- goal env control steps/s with random actions, robosuite's step vs the lean step (``env.sim.lean_step``);
- end-to-end training steps/s (collection and gradient steps, wall clock) for the same number of episodes:
  *before*: robosuite's step, one gradient step per collected step and a target update after each (what hrc_lab ran
  before the reference's cycle); *after*: the lean step and the HER reference implementation's cycle (2 episodes,
  40 gradient steps, one target update), with ``rl.n_envs`` 1 and 2.

*Before* also runs the rest of the update as hrc_lab had it then: the input normaliser updating its statistics from
every training batch and recomputing its float64 mean and std on every forward pass (:class:`PerPassNormalizer`,
the code before the reference's loop), stable-baselines3's own HER buffer (sampling over the whole allocated
buffer), policy (a training-mode switch before every action) and Adam (per-tensor loop).

    .venv/bin/python scripts/bench_rl_throughput.py --episodes 20 --out reports/ch3_rl/throughput.md
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from stable_baselines3 import HerReplayBuffer
from torch import nn

from hrc_lab.env.robot.settings import ErrorCorrectionConfig, SimSettings
from hrc_lab.registry import named
from hrc_lab.rl import RLS
from hrc_lab.rl.agent import ddpg_her_kwargs, learn_episodes, with_silent_logger
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.ddpg import HerDDPG
from hrc_lab.rl.goal_env import make_goal_env
from hrc_lab.rl.normalization import NormalizedCombinedExtractor, RunningNormalizer
from hrc_lab.rl.trainer import goal_env_factory, training_envs

AGENT = dict(suction="auto", delta_r=0.01, net_arch=[64, 64], buffer_size=100_000, learning_starts=80)


class PerPassNormalizer(RunningNormalizer):
    """The input normaliser as hrc_lab ran it before the reference's loop: every batch a training-mode pass sees
    is added to the statistics, and the float64 mean and std are recomputed on every forward pass."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.training:
            self.update(x.detach())
        self._stats = None
        return super().forward(x)


class PerPassExtractor(NormalizedCombinedExtractor):
    """:class:`~hrc_lab.rl.normalization.NormalizedCombinedExtractor` with a :class:`PerPassNormalizer` per key."""

    def __init__(self, observation_space, **kwargs) -> None:
        super().__init__(observation_space, **kwargs)
        self.normalizers = nn.ModuleDict({key: PerPassNormalizer(normalizer.running_sum.numel(), normalizer.clip,
                                                                 normalizer.min_std)
                                          for key, normalizer in self.normalizers.items()})


def before_agent(rl: RLConfig, envs) -> HerDDPG:
    """The agent as hrc_lab built it before: stable-baselines3's policy, HER buffer and Adam, the per-pass
    normaliser."""
    kwargs = ddpg_her_kwargs(rl, envs, seed=0)
    kwargs.update(policy="MultiInputPolicy", replay_buffer_class=HerReplayBuffer,
                  policy_kwargs={"net_arch": list(rl.net_arch), "features_extractor_class": PerPassExtractor})
    return with_silent_logger(HerDDPG(**kwargs))


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


def training_steps_per_s(lean: bool, episodes: int, before: bool = False, **loop) -> float:
    rl = named(RLConfig(**AGENT, **loop), "ddpg_her")
    envs = training_envs(goal_env_factory(cell_config(lean), rl, 0, subtask=0), rl.n_envs)
    agent = before_agent(rl, envs) if before else RLS.build(rl, env=envs, seed=0)
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
        {"what": "training, end to end", "setting": "before: robosuite step, 1 update per step, targets per step, "
                                                    "per-pass normaliser, SB3's HER buffer, policy and Adam",
         "steps/s": training_steps_per_s(False, args.episodes, before=True, **per_step)},
        {"what": "training, end to end", "setting": "before, with today's normaliser, buffer, policy and Adam",
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
