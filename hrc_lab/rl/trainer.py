"""The one reinforcement-learning training loop of hrc_lab: Fig. 3.12 / 3.13 (Algorithm 1) and Table 4.3's DRL
baseline train through :func:`train_epochs`.

Its structure is the HER reference implementation's (OpenAI baselines' ``her``, which the thesis' "epochs" are read
as): an **epoch** is ``rl.cycles_per_epoch`` cycles; a **cycle** collects ``rl.episodes_per_cycle`` episodes over
the ``rl.n_envs`` environments, adds them to the normaliser's statistics, runs ``rl.gradient_steps`` gradient steps
and one soft target update (:class:`~hrc_lab.rl.ddpg.HerDDPG`); after each epoch the deterministic policy is
evaluated on held-out scenes. stable-baselines3's ``learn`` runs the cycles (``train_freq`` = the cycle's
episodes, ``gradient_steps`` per cycle); this module runs the epochs, logs each one and saves checkpoints, from
which a killed run resumes.

:func:`training_envs` makes the environments: ``rl.n_envs`` goal envs, each in its own process when more than one
(stable-baselines3's ``SubprocVecEnv``), wrapped in Algorithm 1's guidance when a guide is given.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv
from tqdm import tqdm

from hrc_lab.rl.agent import EpisodeMetrics, PhaseTimes, episode_horizon, learn_episodes
from hrc_lab.rl.configs import RLConfig

ENV_SEED_STRIDE = 100_003  # env i of a job draws its scenes from seed + i * this (env 0: the job's seed)
TRAIN_METRICS = ("train_success_rate", "train_collision_rate", "train_grip_rate", "train_moved_rate",
                 "train_final_distance", "train_guidance_rate")


def episodes_per_epoch(cfg: RLConfig) -> int:
    """Training episodes in one epoch: cycles x episodes per cycle (100 in the reference)."""
    return cfg.cycles_per_epoch * cfg.episodes_per_cycle


class _Worker:
    """``make_env(index)`` in a worker process, with torch on one thread there (a guide's networks run in it)."""

    def __init__(self, make_env: Callable[[int], gym.Env], index: int) -> None:
        self.make_env, self.index = make_env, index

    def __call__(self) -> gym.Env:
        import torch

        torch.set_num_threads(1)
        return self.make_env(self.index)


class LeanDummyVecEnv(DummyVecEnv):
    """stable-baselines3's ``DummyVecEnv`` whose step returns copies of its observation arrays and a new list of
    its envs' info dicts instead of deep copies of both (SB3 copies so that its reused buffers are not changed under
    the caller; the goal env returns new info dicts, lists and arrays every step): the same values, ~0.1 ms less a
    step."""

    def step_wait(self):
        for env_idx in range(self.num_envs):
            obs, self.buf_rews[env_idx], terminated, truncated, self.buf_infos[env_idx] = self.envs[env_idx].step(
                self.actions[env_idx])
            self.buf_dones[env_idx] = terminated or truncated
            self.buf_infos[env_idx]["TimeLimit.truncated"] = truncated and not terminated
            if self.buf_dones[env_idx]:
                self.buf_infos[env_idx]["terminal_observation"] = obs
                obs, self.reset_infos[env_idx] = self.envs[env_idx].reset()
            self._save_obs(env_idx, obs)
        return self._obs_from_buf(), np.copy(self.buf_rews), np.copy(self.buf_dones), list(self.buf_infos)

    def _obs_from_buf(self):
        if not isinstance(self.observation_space, gym.spaces.Dict):
            return super()._obs_from_buf()
        return {key: np.copy(value) for key, value in self.buf_obs.items()}


def training_envs(make_env: Callable[[int], gym.Env], n_envs: int) -> VecEnv:
    """``n_envs`` environments ``make_env(0..n_envs-1)``: in this process when one (:class:`LeanDummyVecEnv`), one
    process each otherwise (``SubprocVecEnv``)."""
    if n_envs < 1:
        raise ValueError(f"rl.n_envs must be >= 1, got {n_envs}")
    if n_envs == 1:
        return LeanDummyVecEnv([lambda: make_env(0)])
    return SubprocVecEnv([_Worker(make_env, i) for i in range(n_envs)], start_method="forkserver")


def goal_env_factory(env_cfg: Any, rl_cfg: RLConfig, seed: int, guide: Any = None,
                     **goal_env_kwargs: Any) -> Callable[[int], gym.Env]:
    """A picklable ``make_env(index)`` for :func:`training_envs`: the goal env of ``env_cfg`` and ``rl_cfg``
    (:func:`~hrc_lab.rl.goal_env.make_goal_env`, e.g. ``subtask=k`` or ``cases=(1, 2)``), seeded ``seed + index *
    ENV_SEED_STRIDE``, inside Algorithm 1's :class:`~hrc_lab.rl.guidance.GuidedEnv` when ``guide`` is given."""
    return _GoalEnvFactory(env_cfg, rl_cfg, seed, guide, goal_env_kwargs)


@dataclass
class _GoalEnvFactory:
    env_cfg: Any
    rl_cfg: RLConfig
    seed: int
    guide: Any
    goal_env_kwargs: dict

    def __call__(self, index: int) -> gym.Env:
        from hrc_lab.rl.goal_env import make_goal_env
        from hrc_lab.rl.guidance import GuidedEnv

        seed = self.seed + index * ENV_SEED_STRIDE
        env = make_goal_env(self.env_cfg, self.rl_cfg, seed=seed, **self.goal_env_kwargs)
        if self.guide is None:
            return env
        return GuidedEnv(env, self.guide, self.rl_cfg.lam, self.rl_cfg.delta_g, seed=seed)


def learning_rate_at(cfg: RLConfig, epoch: int, epochs: int) -> float:
    """Adam's step size in ``epoch`` (1-based) of ``epochs``: ``rl.learning_rate`` falling linearly to
    ``rl.final_learning_rate`` at the last epoch, or constant when that is null."""
    if cfg.final_learning_rate is None or epochs == 1:
        return cfg.learning_rate
    return cfg.learning_rate + (cfg.final_learning_rate - cfg.learning_rate) * (epoch - 1) / (epochs - 1)


def completed_epochs(agent: Any, cfg: RLConfig) -> int:
    """Epochs an agent (e.g. a resumed one) has trained."""
    return agent.num_timesteps // episode_horizon(agent) // episodes_per_epoch(cfg)


def train_epochs(agent: Any, cfg: RLConfig, epochs: int, evaluate: Callable[[Any, int], dict[str, float]] | None,
                 log: Callable[[dict[str, float], int], None], save: Callable[[Any], None],
                 checkpoint_every: int = 10, step_offset: int = 0, desc: str = "rl") -> None:
    """Train ``agent`` to ``epochs`` epochs (a resumed agent continues after the epochs it has). After each epoch:
    ``evaluate(agent, epoch)`` (the deterministic policy's scores; None: no evaluation), the epoch's training
    episodes' rates (:class:`~hrc_lab.rl.agent.EpisodeMetrics`), the epoch's update diagnostics
    (:meth:`~hrc_lab.rl.ddpg.HerDDPG.update_diagnostics`: losses and Q-values), ``env_steps_per_s`` (collected
    steps / time in collection, guidance included), ``updates_per_s`` (gradient steps / time in training),
    ``epoch_s`` and the epoch's ``learning_rate`` (:func:`learning_rate_at`), logged with ``log(metrics,
    step_offset + epoch)``; ``save(agent)`` every ``checkpoint_every`` epochs and at the end."""
    per_epoch = episodes_per_epoch(cfg)
    timer = PhaseTimes()
    training: dict[str, float] = {}  # the epoch's training episodes (guided ones included), as they ended
    callback = CallbackList([EpisodeMetrics(lambda values, step, into=training: into.update(values),
                                            every=per_epoch), timer])
    done = completed_epochs(agent, cfg)
    for epoch in tqdm(range(done + 1, epochs + 1), desc=desc, unit="epoch", initial=done, total=epochs):
        start, steps, updates = time.perf_counter(), agent.num_timesteps, agent._n_updates
        collect_s, train_s = timer.collect_s, timer.train_s
        learning_rate = learning_rate_at(cfg, epoch, epochs)
        agent.set_learning_rate(learning_rate)
        learn_episodes(agent, epoch * per_epoch, callback)
        metrics = dict(evaluate(agent, epoch)) if evaluate is not None else {}
        metrics.update({key: training.get(key, float("nan")) for key in TRAIN_METRICS})
        metrics.update(agent.update_diagnostics())  # the epoch's critic and actor losses and Q-values
        metrics.update({
            "env_steps_per_s": (agent.num_timesteps - steps) / max(1e-9, timer.collect_s - collect_s),
            "updates_per_s": (agent._n_updates - updates) / max(1e-9, timer.train_s - train_s),
            "epoch_s": time.perf_counter() - start,
            "learning_rate": learning_rate,
        })
        log(metrics, step_offset + epoch)
        if epoch % checkpoint_every == 0 or epoch == epochs:
            save(agent)
