"""A public anchor for hrc_lab's DDPG + HER: the gymnasium-robotics Fetch tasks the HER reference implementation was
published on (Andrychowicz et al. 2017; Plappert et al. 2018, arXiv:1802.09464), trained by the same agent
(:func:`~hrc_lab.rl.agent.build_ddpg_her`) and the same epoch loop (:func:`~hrc_lab.rl.trainer.train_epochs`) as
the thesis' robot cells, so a result there can be read against a curve nobody here produced.

- :func:`make_fetch_env`: ``FetchReach-v4``, ``FetchPush-v4`` or ``FetchPickAndPlace-v4`` (50-step episodes) inside
  :class:`FetchEnv`, which gives the loop what it reads from hrc_lab's goal envs: ``horizon`` and
  ``compute_reward`` on the outermost wrapper, and the info keys of :class:`~hrc_lab.rl.agent.EpisodeMetrics`
  (nothing is held or collided in hrc_lab's sense; ``moved_m`` is how far the object is from where the episode
  started it, 0 in FetchReach, which has none; ``goal_distances`` is |achieved - desired goal|);
- :func:`train_fetch`: ``epochs`` epochs of the reference loop on ``rl.n_envs`` envs, each followed by
  ``eval_episodes`` episodes of the deterministic policy on a separate env (success: ``info["is_success"]`` at
  the episode's last step, as the reference's test rollouts); returns the per-epoch success rates.

``rl.steps_per_subtask`` and the other keys of the robot cells (delta_r, suction, start, yaw, wrist 3, release,
guidance) do not apply to these envs and are ignored. ``conf/experiment/rl/fetch.yaml`` runs this as an
experiment; the ch3_rl report plots its curves beside :data:`PUBLISHED` (``hrc_lab.report.ch3_rl``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from hrc_lab.env.fetch import FETCH_ENV_IDS
from hrc_lab.rl.configs import RLConfig

__all__ = ["FETCH_ENV_IDS", "PUBLISHED", "FetchEnv", "evaluate_fetch", "make_fetch_env", "train_fetch"]

# The published anchor (read, not measured here). Plappert et al. 2018's text, as quoted in a public Q&A thread
# (datascience.stackexchange.com/questions/68190): "We train for 50 epochs (one epoch consists of 19 x 2 x 50 = 1 900
# full episodes), which amounts to a total of 4.75 x 10^6 timesteps." The success level and the epochs are read off
# its Fig. 2 (median test success rate, DDPG + HER, sparse reward) as commonly cited: ~1.0 after ~10-20 epochs;
# approximate, and for FetchPush-v1 (mujoco-py), of which gymnasium-robotics' FetchPush-v4 is the port to the mujoco
# bindings. rl-baselines3-zoo's FetchPush entry trains TQC (hyperparams/her.yml), another algorithm: no anchor for DDPG.
PUBLISHED = {
    "FetchPush-v4": {
        "source": "Plappert et al. 2018, Multi-Goal Reinforcement Learning: Challenging Robotics Environments and "
                  "Request for Research, arXiv:1802.09464, Fig. 2 (FetchPush-v1, DDPG + HER, 19 MPI workers)",
        "success_rate": 1.0,  # approximately, median over seeds
        "episodes": (10 * 1900, 20 * 1900),  # epochs 10-20 of 19 workers x 2 rollouts x 50 cycles
    },
}
EVAL_SEED = 10_000  # the evaluation env of a run with seed s draws its goals from EVAL_SEED + s (apart from training)


class FetchEnv(gym.Wrapper):
    """A Fetch env as :mod:`hrc_lab.rl.trainer` and :mod:`hrc_lab.rl.agent` take a goal env: ``horizon`` (the time
    limit, 50 steps) and ``compute_reward`` on this wrapper (gymnasium 1.x wrappers forward no attributes, and
    stable-baselines3's HER buffer and the loop read them from the outermost env), and each step's info with
    ``held=False``, ``collided=False``, ``goal_distances=[|achieved - desired goal|]`` and ``moved_m``: in the
    tasks with an object (whose position is the achieved goal) its distance from its position at the reset, so
    the loop's ``train_moved_rate`` says how often exploration pushed it (HER's relabelled goals teach pushing only
    from such episodes); 0.0 in FetchReach."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.horizon = int(env.spec.max_episode_steps)
        self.has_object = bool(env.unwrapped.has_object)
        self.start: np.ndarray | None = None

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        return self.env.unwrapped.compute_reward(achieved_goal, desired_goal, info)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.start = np.array(obs["achieved_goal"], copy=True)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        distance = float(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]))
        moved = float(np.linalg.norm(obs["achieved_goal"] - self.start)) if self.has_object else 0.0
        info = {**info, "held": False, "moved_m": moved, "collided": False, "goal_distances": [distance]}
        return obs, reward, terminated, truncated, info


def make_fetch_env(env_id: str, seed: int | None = None, reward: str = "sparse") -> FetchEnv:
    """The gymnasium-robotics env ``env_id`` (one of :data:`FETCH_ENV_IDS`) inside :class:`FetchEnv`, its goals and
    action space seeded with ``seed`` (None: unseeded); ``reward`` (``rl.reward``) is its ``reward_type``, sparse
    (the published curves') or dense (-|achieved - desired goal|)."""
    if env_id not in FETCH_ENV_IDS:
        raise ValueError(f"unknown Fetch env id '{env_id}'; choose one of {list(FETCH_ENV_IDS)}")
    import gymnasium_robotics

    gym.register_envs(gymnasium_robotics)
    env = FetchEnv(gym.make(env_id, reward_type=reward))
    env.reset(seed=seed)
    env.action_space.seed(seed)
    return env


@dataclass
class FetchFactory:
    """A picklable ``make_env(index)`` for :func:`~hrc_lab.rl.trainer.training_envs` (one process per env when
    there are several): env ``index`` seeded ``seed + index * ENV_SEED_STRIDE``, as the robot cells' envs
    (stable-baselines3 then reseeds env i of the agent's VecEnv with the agent's seed + i at its first reset)."""

    env_id: str
    seed: int
    reward: str = "sparse"

    def __call__(self, index: int) -> FetchEnv:
        from hrc_lab.rl.trainer import ENV_SEED_STRIDE

        return make_fetch_env(self.env_id, self.seed + index * ENV_SEED_STRIDE, self.reward)


def evaluate_fetch(agent: Any, env: FetchEnv, episodes: int) -> dict[str, float]:
    """``success_rate`` (``info["is_success"]`` at the last step) and ``final_distance`` (|achieved - desired goal|
    then, m) of the deterministic policy over ``episodes`` episodes of ``env``, each from its next goal."""
    successes, distances = [], []
    for _ in range(episodes):
        obs, _ = env.reset()
        terminated = truncated = False
        while not (terminated or truncated):
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
        successes.append(float(info["is_success"]))
        distances.append(info["goal_distances"][0])
    return {"success_rate": float(np.mean(successes)), "final_distance": float(np.mean(distances))}


def train_fetch(env_id: str, rl_cfg: RLConfig, epochs: int, seed: int = 0, eval_episodes: int = 10,
                log: Callable[[dict[str, float], int], None] | None = None,
                save: Callable[[Any], None] | None = None, checkpoint_every: int | None = None,
                resume: Callable[[Any], Any] | None = None, on_resume: Callable[[int], None] | None = None
                ) -> list[float]:
    """Train DDPG + HER (:func:`~hrc_lab.rl.agent.build_ddpg_her` with ``rl_cfg``) on ``env_id`` for ``epochs``
    epochs of :func:`~hrc_lab.rl.trainer.train_epochs` on ``rl_cfg.n_envs`` envs; after each, ``eval_episodes``
    episodes of the deterministic policy on a separate env (:func:`evaluate_fetch`). ``log(metrics, epoch)`` gets
    each epoch's metrics (the evaluation's and the loop's: training rates, speeds, ``epoch_s``); ``save(agent)``
    the agent every ``checkpoint_every`` epochs and at the end (None: only at the end). ``resume(envs)``: a saved
    agent on the training envs, or None (e.g. :meth:`~hrc_lab.run_context.RunContext.resume_agent`), trained on
    from the epochs it has (``on_resume(epochs)`` is told how many, before the first). Returns the success rate
    after each epoch this call trained."""
    from hrc_lab.rl.agent import build_ddpg_her
    from hrc_lab.rl.trainer import completed_epochs, train_epochs, training_envs

    if epochs < 1 or eval_episodes < 1:
        raise ValueError(f"epochs and eval_episodes must be >= 1, got {epochs}, {eval_episodes}")
    # also rejects an unknown id before any process starts
    test = make_fetch_env(env_id, EVAL_SEED + seed, rl_cfg.reward)
    envs = training_envs(FetchFactory(env_id, seed, rl_cfg.reward), rl_cfg.n_envs)
    curve: list[float] = []

    def record(metrics: dict[str, float], epoch: int) -> None:
        curve.append(metrics["success_rate"])
        if log is not None:
            log(metrics, epoch)

    try:
        agent = resume(envs) if resume is not None else None
        if agent is None:
            agent = build_ddpg_her(rl_cfg, envs, seed=seed)
        elif on_resume is not None:
            on_resume(completed_epochs(agent, rl_cfg))
        train_epochs(agent, rl_cfg, epochs, evaluate=lambda agent, epoch: evaluate_fetch(agent, test, eval_episodes),
                     log=record, save=save or (lambda agent: None), checkpoint_every=checkpoint_every or epochs,
                     desc=env_id)
    finally:
        envs.close()
        test.close()
    return curve
