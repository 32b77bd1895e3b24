"""DDPG + HER agents built from an ``rl`` config (stable-baselines3), training by episodes, evaluation and
checkpoints.

``RLS.build(cfg, env=..., seed=...)`` gives :func:`build_ddpg_her` (``rl=ddpg_her``: the DRL baseline of 3.3 and
Table 4.3) or, with ``guide=...``, :func:`build_guided_ddpg_her` (``rl=ddpg_her_guided``: Algorithm 1,
:mod:`hrc_lab.rl.guidance`). Both are stable-baselines3's DDPG (one critic, no target smoothing) with the HER
paper's action penalty, random exploration actions and clipped targets (:class:`~hrc_lab.rl.ddpg.HerDDPG`) and
SB3's ``HerReplayBuffer`` on the goal env of :mod:`hrc_lab.rl.goal_env`; exploration adds Gaussian noise to the
[-1, 1] actions; with ``rl.normalize_inputs`` the networks see the HER paper's normalised inputs
(:mod:`hrc_lab.rl.normalization`). A checkpoint (:func:`save_agent`) is a folder with SB3's ``agent.zip`` and,
when it is small enough, the gzipped replay buffer (``replay_buffer.pkl.gz``), which :func:`load_agent` restores
to resume.
"""

from __future__ import annotations

import gzip
import pathlib
import pickle
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from stable_baselines3 import HerReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.noise import NormalActionNoise
from tqdm import tqdm

from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.ddpg import HerDDPG
from hrc_lab.rl.goal_env import HRCGoalEnv
from hrc_lab.rl.guidance import GuidedDDPG
from hrc_lab.rl.normalization import NormalizedCombinedExtractor

AGENT_FILE = "agent.zip"
BUFFER_FILE = "replay_buffer.pkl.gz"
MAX_BUFFER_BYTES = 256 * 2**20  # by default the replay buffer is saved while its transitions take at most this
MOVED_M = 0.02  # a goal object farther than this from where the episode started it counts as moved, m


def policy_kwargs(cfg: RLConfig) -> dict[str, Any]:
    """The networks' hidden layers and, with ``rl.normalize_inputs``, the HER paper's input normalisation."""
    kwargs: dict[str, Any] = {"net_arch": list(cfg.net_arch)}
    if cfg.normalize_inputs:
        kwargs["features_extractor_class"] = NormalizedCombinedExtractor
    return kwargs


def ddpg_her_kwargs(cfg: RLConfig, env: HRCGoalEnv, seed: int) -> dict[str, Any]:
    """The arguments of :class:`~hrc_lab.rl.ddpg.HerDDPG` (stable-baselines3's ``DDPG`` and the HER paper's
    additions) for an ``rl`` config."""
    n_actions = env.action_space.shape[0]
    return {
        "policy": "MultiInputPolicy",
        "env": env,
        "learning_rate": cfg.learning_rate,
        "buffer_size": cfg.buffer_size,
        "learning_starts": cfg.learning_starts,
        "batch_size": cfg.batch_size,
        "tau": cfg.tau,
        "gamma": cfg.gamma,
        "train_freq": (cfg.train_freq, "episode"),
        "gradient_steps": cfg.gradient_steps,
        "action_noise": NormalActionNoise(np.zeros(n_actions), np.full(n_actions, cfg.action_noise_std)),
        "replay_buffer_class": HerReplayBuffer,
        "replay_buffer_kwargs": {"n_sampled_goal": cfg.n_sampled_goal,
                                 "goal_selection_strategy": cfg.goal_selection_strategy},
        "policy_kwargs": policy_kwargs(cfg),
        "action_l2": cfg.action_l2,
        "random_eps": cfg.random_eps,
        "clip_return": cfg.clip_return,
        "seed": seed,
        "device": "cpu",
        "verbose": 0,
    }


def with_silent_logger(agent: HerDDPG) -> HerDDPG:
    """Give ``agent`` a logger that writes nothing: metrics go to the run's tracker through
    :class:`EpisodeMetrics`, and without a logger of its own every ``learn`` call makes an empty
    ``SB3-<time>`` folder in the temp directory."""
    agent.set_logger(Logger(folder=None, output_formats=[]))
    return agent


def build_ddpg_her(cfg: RLConfig, env: HRCGoalEnv, seed: int = 0) -> HerDDPG:
    """``rl=ddpg_her``: unguided DDPG + HER."""
    if cfg.guidance != "none":
        raise ValueError(f"rl.guidance: ddpg_her is the unguided agent, got guidance '{cfg.guidance}'; "
                         "use rl=ddpg_her_guided")
    return with_silent_logger(HerDDPG(**ddpg_her_kwargs(cfg, env, seed)))


def build_guided_ddpg_her(cfg: RLConfig, env: HRCGoalEnv, guide: Any, seed: int = 0) -> GuidedDDPG:
    """``rl=ddpg_her_guided``: Algorithm 1 with the trained two-level planner ``guide`` (e.g. a
    :class:`~hrc_lab.rl.guidance.CorrectionGuide`); lambda, delta_g from the config, the per-episode draws from a
    generator seeded with ``seed``."""
    if cfg.guidance == "none":
        raise ValueError("rl.guidance: ddpg_her_guided needs 'ndp' or 'ndp_direction' (for no guidance use "
                         "rl=ddpg_her, or rl.lam=0 for the pure-exploration arm of Fig. 3.13)")
    expected = "direction" if cfg.guidance == "ndp_direction" else "regression"
    mode = getattr(guide, "ndp_mode", None)
    if mode is not None and mode != expected:
        raise ValueError(f"rl.guidance={cfg.guidance} needs a dynamic planner with motion.ndp.mode={expected}, "
                         f"got {mode}")
    return with_silent_logger(GuidedDDPG(guide=guide, lam=cfg.lam, delta_g=cfg.delta_g, guidance_seed=seed,
                                         **ddpg_her_kwargs(cfg, env, seed)))


class EpisodeMetrics(BaseCallback):
    """Every ``every`` episodes, ``log(metrics, step)`` (e.g. ``RunTracker.log_metrics``) with the success rate
    and collision rate of those episodes (their last step's ``is_success`` and ``collided``), how exploration
    reached the objects (``grip_rate``: share of episodes in which a part was held at some step; ``moved_rate``:
    share in which a goal object moved more than ``moved_m`` from its start: without that, HER's relabelled
    goals are all about where the parts already were), the mean final |P_obj - P_goal| (``final_distance``, the
    farthest goal object; Eq. 3.6's distance) and, for a :class:`GuidedDDPG`, the guidance rate so far
    (corrected steps / steps); ``step`` is the episode count."""

    def __init__(self, log: Callable[..., None], every: int = 10, prefix: str = "train_",
                 moved_m: float = MOVED_M) -> None:
        super().__init__()
        self.log, self.every, self.prefix, self.moved_m = log, every, prefix, moved_m
        self.episodes: list[dict[str, bool]] = []
        self.held = self.moved = False

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            self.held |= bool(info["held"])
            self.moved |= info["moved_m"] > self.moved_m
            if done:
                self.episodes.append({"success_rate": bool(info["is_success"]),
                                      "collision_rate": bool(info["collided"]),
                                      "grip_rate": self.held, "moved_rate": self.moved,
                                      "final_distance": float(np.max(info["goal_distances"]))})
                self.held = self.moved = False
        if len(self.episodes) >= self.every:
            metrics = {f"{self.prefix}{key}": float(np.mean([episode[key] for episode in self.episodes]))
                       for key in self.episodes[0]}
            if isinstance(self.model, GuidedDDPG):
                metrics[f"{self.prefix}guidance_rate"] = self.model.guidance_rate
            horizon = self.model.get_env().envs[0].unwrapped.horizon
            self.log(metrics, step=self.model.num_timesteps // horizon)
            self.episodes = []
        return True


class EpisodeProgress(BaseCallback):
    """A progress bar over the training episodes of one ``learn`` call (``total``: the episode count it ends at)."""

    def __init__(self, total: int, desc: str) -> None:
        super().__init__()
        self.total, self.desc = total, desc
        self.bar: tqdm | None = None

    def _on_training_start(self) -> None:
        horizon = self.model.get_env().envs[0].unwrapped.horizon
        self.bar = tqdm(total=self.total, initial=self.num_timesteps // horizon, desc=self.desc, unit="episode")

    def _on_step(self) -> bool:
        self.bar.update(int(sum(self.locals["dones"])))
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


class PhaseTimes(BaseCallback):
    """Wall time, summed over ``learn`` calls, in rollout collection (between SB3's rollout-start and rollout-end
    hooks; guidance included) and in training (from a rollout's end to the next rollout or to the end of
    ``learn``: the gradient steps). A callback rather than wrapped methods, so nothing is left on the agent for
    ``save`` to pickle."""

    def __init__(self) -> None:
        super().__init__()
        self.collect_s = self.train_s = 0.0
        self._since = 0.0
        self._trained = False  # whether the time since ``_since`` was spent training

    def _on_training_start(self) -> None:
        self._since, self._trained = time.perf_counter(), False

    def _on_rollout_start(self) -> None:
        now = time.perf_counter()
        if self._trained:
            self.train_s += now - self._since
        self._since = now

    def _on_rollout_end(self) -> None:
        now = time.perf_counter()
        self.collect_s += now - self._since
        self._since, self._trained = now, True

    def _on_training_end(self) -> None:
        if self._trained:
            self.train_s += time.perf_counter() - self._since

    def _on_step(self) -> bool:
        return True


def learn_episodes(agent: HerDDPG, episodes: int, callback: BaseCallback | None = None) -> HerDDPG:
    """Train until the agent has run ``episodes`` episodes in all (a resumed agent continues its count). Every
    episode of the goal env has ``horizon`` steps, so this is ``episodes x horizon`` control steps, and the last
    episode is stored and trained on like the others."""
    horizon = agent.get_env().envs[0].unwrapped.horizon
    remaining = episodes - agent.num_timesteps // horizon
    if remaining > 0:
        agent.learn(total_timesteps=remaining * horizon, callback=callback,
                    reset_num_timesteps=agent.num_timesteps == 0)
    return agent


def add_demonstrations(agent: HerDDPG, env: HRCGoalEnv, episodes: int, seed: int = 0) -> float:
    """Put ``episodes`` episodes of the scripted expert (:class:`~hrc_lab.env.robot.expert.ScriptedExpert`) acting in
    ``env`` into the agent's replay buffer, as the thesis' DRL baseline is "trained using demonstrations" (Table 4.3);
    HER relabels them like the agent's own. Each episode runs the env's full horizon (the arm holds still with
    suction off once the expert is done), so its transitions look like the agent's. The first scene is drawn with
    ``seed``. Returns the share of demonstrations that ended in success."""
    from hrc_lab.env.robot.expert import ScriptedExpert

    if not env.suction_action:
        raise ValueError("demonstrations switch the cup on and off: they need rl.suction=action, got auto")
    still = np.zeros(env.action_space.shape[0], dtype=np.float32)
    still[-1] = -1.0
    successes = []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed if k == 0 else None)
        expert = ScriptedExpert(env.cell)
        truncated, info = False, {}
        while not truncated:
            step = expert.act()
            action = still if step is None else np.clip(step.action / env.action_scale, -1.0, 1.0).astype(np.float32)
            next_obs, reward, _, truncated, info = env.step(action)
            agent.replay_buffer.add({k: v[None] for k, v in obs.items()}, {k: v[None] for k, v in next_obs.items()},
                                    action[None], np.array([reward]), np.array([truncated]),
                                    [{**info, "TimeLimit.truncated": truncated}])
            obs = next_obs
        successes.append(bool(info["is_success"]))
    return float(np.mean(successes)) if successes else float("nan")


def run_episode(agent: HerDDPG, env: HRCGoalEnv, seed: int | None = None) -> tuple[dict, int | None]:
    """One episode of the deterministic policy from the env's next scene (reseeded with ``seed`` when given):
    the last step's info, with ``ever_held`` (a part was held at some step), ``ever_moved`` (a goal object was
    more than :data:`MOVED_M` from its start at some step) and the last observation's ``achieved_goal`` and
    ``desired_goal`` added, and the step at which the goal was first reached (None if never)."""
    obs, _ = env.reset(seed=seed)
    first = None
    truncated = terminated = False
    held = moved = False
    while not (truncated or terminated):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        held |= bool(info["held"])
        moved |= info["moved_m"] > MOVED_M
        if info["is_success"] and first is None:
            first = env.elapsed_steps
    goals = {key: obs[key] for key in ("achieved_goal", "desired_goal")}
    return {**info, "ever_held": held, "ever_moved": moved, **goals}, first


def evaluate(agent: HerDDPG, env: HRCGoalEnv, episodes: int, seed: int = 0) -> dict[str, float]:
    """Success rate (Eq. 3.7 / 4.7 at the episode's last step), collision rate, mean final goal distance, and how
    far the policy got with the part (``grip_rate``: share of episodes in which it held a part at some step;
    ``moved_rate``: in which it moved a goal object more than :data:`MOVED_M`; as the training episodes'
    :class:`EpisodeMetrics`) of the deterministic policy over ``episodes`` scenes (episode k seeded ``seed + k``)."""
    infos = [run_episode(agent, env, seed=seed + k)[0] for k in range(episodes)]
    return {"success_rate": float(np.mean([i["is_success"] for i in infos])),
            "collision_rate": float(np.mean([i["collided"] for i in infos])),
            "final_distance": float(np.mean([np.max(i["goal_distances"]) for i in infos])),
            "grip_rate": float(np.mean([i["ever_held"] for i in infos])),
            "moved_rate": float(np.mean([i["ever_moved"] for i in infos]))}


# --- checkpoints ------------------------------------------------------------------------------------------------


def _filled_bytes(buffer: Any) -> int:
    """Bytes of the transitions stored so far (the arrays are allocated at ``rl.buffer_size``; gzip shrinks the
    empty rest to almost nothing)."""
    total = 0
    for value in vars(buffer).values():
        arrays = value.values() if isinstance(value, dict) else [value]
        total += sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
    return total * buffer.size() // buffer.buffer_size


def save_agent(agent: HerDDPG, directory: str | pathlib.Path, replay_buffer: bool | None = None,
               max_buffer_bytes: int = MAX_BUFFER_BYTES) -> list[pathlib.Path]:
    """Save ``agent`` into ``directory``: SB3's ``agent.zip`` (networks, optimisers, counters, and a
    :class:`GuidedDDPG`'s guidance state), plus the replay buffer, pickled and gzipped (``replay_buffer.pkl.gz``;
    HER's buffer leaves its env out), when ``replay_buffer`` is True, or when None and the stored transitions take
    at most ``max_buffer_bytes``. Returns the files written, for ``mlflow.log_artifact``."""
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    agent.save(directory / AGENT_FILE)
    written = [directory / AGENT_FILE]
    if replay_buffer is None:
        replay_buffer = _filled_bytes(agent.replay_buffer) <= max_buffer_bytes
    if replay_buffer:
        with gzip.open(directory / BUFFER_FILE, "wb", compresslevel=1) as file:
            pickle.dump(agent.replay_buffer, file, protocol=pickle.HIGHEST_PROTOCOL)
        written.append(directory / BUFFER_FILE)
    return written


def load_agent(directory: str | pathlib.Path, env: HRCGoalEnv, guide: Any = None) -> HerDDPG:
    """The agent saved by :func:`save_agent`, on ``env``; a :class:`GuidedDDPG` when ``guide`` is given (the
    guide is not saved). A saved replay buffer is restored as ``OffPolicyAlgorithm.load_replay_buffer`` does
    (HER's buffer gets the env back, an unfinished last episode is closed), so :func:`learn_episodes` continues
    where the saved run stopped."""
    directory = pathlib.Path(directory)
    cls = GuidedDDPG if guide is not None else HerDDPG
    agent = cls.load(directory / AGENT_FILE, env=env, device="cpu")
    if guide is not None:
        agent.guide = guide
    if (directory / BUFFER_FILE).exists():
        with gzip.open(directory / BUFFER_FILE, "rb") as file:
            agent.replay_buffer = pickle.load(file)
        if isinstance(agent.replay_buffer, HerReplayBuffer):
            agent.replay_buffer.set_env(agent.get_env())
            agent.replay_buffer.truncate_last_trajectory()
    return with_silent_logger(agent)
