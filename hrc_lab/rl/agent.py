"""DDPG + HER agents built from an ``rl`` config (stable-baselines3), training by episodes, evaluation and
checkpoints.

``RLS.build(cfg, env=..., seed=...)`` gives :func:`build_ddpg_her` (``rl=ddpg_her``: the DRL baseline of 3.3 and
Table 4.3) or :func:`build_guided_ddpg_her` (``rl=ddpg_her_guided``: Algorithm 1, whose guidance wraps the envs,
:mod:`hrc_lab.rl.guidance`). Both are stable-baselines3's DDPG (one critic, no target smoothing) trained as the HER
reference implementation trains it, with demonstrations when given (:class:`~hrc_lab.rl.ddpg.HerDDPG`) and
SB3's ``HerReplayBuffer`` on the goal env of :mod:`hrc_lab.rl.goal_env`; exploration adds Gaussian noise to the
[-1, 1] actions; with ``rl.normalize_inputs`` the networks see the HER paper's normalised inputs
(:mod:`hrc_lab.rl.normalization`). A checkpoint (:func:`save_agent`) is a folder with SB3's ``agent.zip``, the
demonstrations and, when it is small enough, the gzipped replay buffer (``replay_buffer.pkl.gz``), which
:func:`load_agent` restores to resume. The epoch loop around them is :mod:`hrc_lab.rl.trainer`.
"""

from __future__ import annotations

import gzip
import pathlib
import pickle
import time
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3 import HerReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.vec_env import VecEnv
from tqdm import tqdm

from hrc_lab.rl.buffers import FilledHerReplayBuffer
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.ddpg import HerDDPG, HerPolicy
from hrc_lab.rl.goal_env import HRCGoalEnv
from hrc_lab.rl.normalization import NormalizedCombinedExtractor

AGENT_FILE = "agent.zip"
BUFFER_FILE = "replay_buffer.pkl.gz"
DEMO_BUFFER_FILE = "demo_buffer.pkl.gz"
MAX_BUFFER_BYTES = 256 * 2**20  # by default the replay buffer is saved while its transitions take at most this
MOVED_M = 0.02  # a goal object farther than this from where the episode started it counts as moved, m


def policy_kwargs(cfg: RLConfig) -> dict[str, Any]:
    """The networks' hidden layers, Adam's fused kernel (the same update as the per-tensor loop SB3 otherwise runs,
    in ~40 % of its time on this CPU) and, with ``rl.normalize_inputs``, the HER paper's input normalisation."""
    kwargs: dict[str, Any] = {"net_arch": list(cfg.net_arch), "optimizer_kwargs": {"fused": True}}
    if cfg.normalize_inputs:
        kwargs["features_extractor_class"] = NormalizedCombinedExtractor
    return kwargs


def cycle_steps(cfg: RLConfig, env: gym.Env | VecEnv) -> int:
    """Steps of each env in one cycle: ``rl.episodes_per_cycle`` episodes over all envs, every episode of a goal env
    ``horizon`` steps long (stable-baselines3 counts cycles in episodes with one env only)."""
    return cfg.episodes_per_cycle // getattr(env, "num_envs", 1) * env_horizon(env)


def ddpg_her_kwargs(cfg: RLConfig, env: gym.Env | VecEnv, seed: int) -> dict[str, Any]:
    """The arguments of :class:`~hrc_lab.rl.ddpg.HerDDPG` (stable-baselines3's ``DDPG`` and the HER paper's
    additions) for an ``rl`` config."""
    n_actions = env.action_space.shape[0]
    return {
        "policy": HerPolicy,
        "env": env,
        "learning_rate": cfg.learning_rate,
        "buffer_size": cfg.buffer_size,
        "learning_starts": cfg.learning_starts,
        "batch_size": cfg.batch_size,
        "tau": cfg.tau,
        "gamma": cfg.gamma,
        "train_freq": (cycle_steps(cfg, env), "step"),
        "gradient_steps": cfg.gradient_steps,
        "action_noise": NormalActionNoise(np.zeros(n_actions), np.full(n_actions, cfg.action_noise_std)),
        "replay_buffer_class": FilledHerReplayBuffer,
        "replay_buffer_kwargs": {"n_sampled_goal": cfg.n_sampled_goal,
                                 "goal_selection_strategy": cfg.goal_selection_strategy,
                                 # HER's relabelled rewards read the transitions' infos (rl.collision_fails)
                                 "copy_info_dict": cfg.collision_fails},
        "policy_kwargs": policy_kwargs(cfg),
        "action_l2": cfg.action_l2,
        "random_eps": cfg.random_eps,
        "clip_return": cfg.clip_return,
        "target_update": cfg.target_update,
        "demo_batch_size": cfg.demo_batch_size,
        "bc_weight": cfg.bc_weight,
        "q_filter": cfg.q_filter,
        "bc_pretrain_steps": cfg.bc_pretrain_steps,
        "critic_warmup_steps": cfg.critic_warmup_steps,
        "guided_episodes": cfg.guided_episodes,
        "guided_exploration": cfg.guided_exploration,
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


def build_ddpg_her(cfg: RLConfig, env: gym.Env | VecEnv, seed: int = 0) -> HerDDPG:
    """``rl=ddpg_her``: unguided DDPG + HER on ``env`` (a goal env, or the vectorised envs of
    :func:`hrc_lab.rl.trainer.training_envs`)."""
    if cfg.guidance != "none":
        raise ValueError(f"rl.guidance: ddpg_her is the unguided agent, got guidance '{cfg.guidance}'; "
                         "use rl=ddpg_her_guided")
    return with_silent_logger(HerDDPG(**ddpg_her_kwargs(cfg, env, seed)))


def build_guided_ddpg_her(cfg: RLConfig, env: gym.Env | VecEnv, seed: int = 0) -> HerDDPG:
    """``rl=ddpg_her_guided``: Algorithm 1's agent. The agent is DDPG + HER as ``ddpg_her``; the guidance is in its
    envs (:class:`~hrc_lab.rl.guidance.GuidedEnv`, which :func:`hrc_lab.rl.trainer.training_envs` wraps around
    each env with the trained planner, lambda and delta_g of the config)."""
    if cfg.guidance == "none":
        raise ValueError("rl.guidance: ddpg_her_guided needs 'ndp' or 'ndp_direction' (for no guidance use "
                         "rl=ddpg_her, or rl.lam=0 for the pure-exploration arm of Fig. 3.13)")
    return with_silent_logger(HerDDPG(**ddpg_her_kwargs(cfg, env, seed)))


def env_horizon(env: gym.Env | VecEnv) -> int:
    """Control steps per episode of a goal env, or of a VecEnv's envs (every episode of a goal env has this
    length)."""
    return int(env.get_attr("horizon", [0])[0] if isinstance(env, VecEnv) else env.get_wrapper_attr("horizon"))


def episode_horizon(agent: HerDDPG) -> int:
    """Control steps per episode of the agent's envs."""
    return env_horizon(agent.get_env())


class EpisodeMetrics(BaseCallback):
    """Every ``every`` episodes, ``log(metrics, step)`` (e.g. ``RunTracker.log_metrics``) with the success rate
    and collision rate of those episodes (their last step's ``is_success`` and ``collided``), how exploration
    reached the objects (``grip_rate``: share of episodes in which a part was held at some step; ``moved_rate``:
    share in which a goal object moved more than ``moved_m`` from its start: without that, HER's relabelled
    goals are all about where the parts already were), the mean final |P_obj - P_goal| (``final_distance``, the
    farthest goal object; Eq. 3.6's distance) and, in guided envs (:class:`~hrc_lab.rl.guidance.GuidedEnv`), the
    guidance rate of those episodes (corrected steps / steps); ``step`` is the episode count."""

    def __init__(self, log: Callable[..., None], every: int = 10, prefix: str = "train_",
                 moved_m: float = MOVED_M) -> None:
        super().__init__()
        self.log, self.every, self.prefix, self.moved_m = log, every, prefix, moved_m
        self.episodes: list[dict[str, bool]] = []
        self.held = self.moved = np.zeros(0, bool)  # per env of the agent's VecEnv
        self.corrected = self.steps = 0  # Algorithm 1's corrected steps / collected steps since the last log

    def _on_training_start(self) -> None:
        if len(self.held) != self.training_env.num_envs:
            n_envs = self.training_env.num_envs
            self.held, self.moved = np.zeros(n_envs, bool), np.zeros(n_envs, bool)

    def _on_step(self) -> bool:
        dones, infos = self.locals["dones"], self.locals["infos"]
        for i, (done, info) in enumerate(zip(dones, infos)):
            self.held[i] |= bool(info["held"])
            self.moved[i] |= info["moved_m"] > self.moved_m
            self.corrected += bool(info.get("corrected", False))
            self.steps += 1
            if done:
                self.episodes.append({"success_rate": bool(info["is_success"]),
                                      "collision_rate": bool(info["collided"]),
                                      "grip_rate": bool(self.held[i]), "moved_rate": bool(self.moved[i]),
                                      "final_distance": float(np.max(info["goal_distances"]))})
                self.held[i] = self.moved[i] = False
        if len(self.episodes) >= self.every:
            metrics = {f"{self.prefix}{key}": float(np.mean([episode[key] for episode in self.episodes]))
                       for key in self.episodes[0]}
            metrics[f"{self.prefix}guidance_rate"] = self.corrected / max(1, self.steps)
            self.log(metrics, step=self.model.num_timesteps // episode_horizon(self.model))
            self.episodes, self.corrected, self.steps = [], 0, 0
        return True


class EpisodeProgress(BaseCallback):
    """A progress bar over the training episodes of one ``learn`` call (``total``: the episode count it ends at)."""

    def __init__(self, total: int, desc: str) -> None:
        super().__init__()
        self.total, self.desc = total, desc
        self.bar: tqdm | None = None

    def _on_training_start(self) -> None:
        self.bar = tqdm(total=self.total, initial=self.num_timesteps // episode_horizon(self.model), desc=self.desc,
                        unit="episode")

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
    horizon = episode_horizon(agent)
    remaining = episodes - agent.num_timesteps // horizon
    if remaining > 0:
        agent.learn(total_timesteps=remaining * horizon, callback=callback,
                    reset_num_timesteps=agent.num_timesteps == 0)
    return agent


def add_demonstrations(agent: HerDDPG, env: HRCGoalEnv, episodes: int, seed: int = 0) -> float:
    """Put ``episodes`` episodes of the scripted expert (:class:`~hrc_lab.env.robot.expert.ScriptedExpert`) acting in
    ``env`` into the agent's demonstration buffer, as the thesis' DRL baseline is "trained using demonstrations"
    (Table 4.3; Nair et al. 2018, :mod:`hrc_lab.rl.ddpg`); HER relabels them like the agent's own. Each episode runs
    the env's full horizon (the arm holds still, suction off, once the expert is done), so its transitions look
    like the agent's; with ``rl.suction=auto`` the expert's suction commands are dropped and the env's release on
    a support lets the part go. In error correction the expert moves the subtask's objects only (``goal_objects``).
    The first scene is drawn with ``seed``. Returns the share of demonstrations that ended in success."""
    from hrc_lab.env.robot.expert import ScriptedExpert

    if not (env.suction_action or env.release_on_support):
        raise ValueError("demonstrations release the part at its goal: they need rl.suction=action, or "
                         "rl.suction=auto with rl.release=support")
    still = np.zeros(env.action_space.shape[0], dtype=np.float32)
    if env.suction_action:
        still[-1] = -1.0
    successes = []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed if k == 0 else None)
        # error correction: the subtask's objects only (those of earlier subtasks start at their goals)
        expert = ScriptedExpert(env.cell, objects=env.goal_objects if env.correction else None)
        truncated, info, episode = False, {}, []
        while not truncated:
            step = expert.act()
            action = still if step is None else env.from_cell_action(step.action)
            next_obs, reward, _, truncated, info = env.step(action)
            episode.append((obs, next_obs, action, reward, info))
            obs = next_obs
        agent.add_demonstration(episode)
        successes.append(bool(info["is_success"]))
    return float(np.mean(successes)) if successes else float("nan")


def run_episode(agent: HerDDPG, env: HRCGoalEnv, seed: int | None = None,
                on_step: Callable[[HRCGoalEnv, dict], None] | None = None) -> tuple[dict, int | None]:
    """One episode of the deterministic policy from the env's next scene (reseeded with ``seed`` when given):
    the last step's info, with ``ever_held`` (a part was held at some step), ``ever_moved`` (a goal object was
    more than :data:`MOVED_M` from its start at some step) and the last observation's ``achieved_goal`` and
    ``desired_goal`` added, and the step at which the goal was first reached (None if never). ``on_step(env,
    info)`` sees every step (e.g. a diagnosis of where the cup holds the part)."""
    obs, _ = env.reset(seed=seed)
    first = None
    truncated = terminated = False
    held = moved = False
    while not (truncated or terminated):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        if on_step is not None:
            on_step(env, info)
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


def _dump(buffer: Any, path: pathlib.Path) -> None:
    with gzip.open(path, "wb", compresslevel=1) as file:
        pickle.dump(buffer, file, protocol=pickle.HIGHEST_PROTOCOL)


def _load_buffer(path: pathlib.Path, agent: HerDDPG) -> HerReplayBuffer:
    """A buffer saved by :func:`save_agent`, restored as ``OffPolicyAlgorithm.load_replay_buffer`` does (HER's
    buffer gets the env back, an unfinished last episode is closed)."""
    with gzip.open(path, "rb") as file:
        buffer = pickle.load(file)
    buffer.set_env(agent.get_env())
    buffer.truncate_last_trajectory()
    return buffer


def save_agent(agent: HerDDPG, directory: str | pathlib.Path, replay_buffer: bool | None = None,
               max_buffer_bytes: int = MAX_BUFFER_BYTES) -> list[pathlib.Path]:
    """Save ``agent`` into ``directory``: SB3's ``agent.zip`` (networks, optimisers, counters, the normaliser's
    statistics), the demonstration buffer when the agent has one (``demo_buffer.pkl.gz``), plus the replay buffer,
    pickled and gzipped (``replay_buffer.pkl.gz``; HER's buffer leaves its env out), when ``replay_buffer`` is
    True, or when None and the stored transitions take at most ``max_buffer_bytes``. Returns the files written,
    for ``mlflow.log_artifact``."""
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    agent.save(directory / AGENT_FILE)
    written = [directory / AGENT_FILE]
    if agent.demo_buffer is not None:
        _dump(agent.demo_buffer, directory / DEMO_BUFFER_FILE)
        written.append(directory / DEMO_BUFFER_FILE)
    if replay_buffer is None:
        replay_buffer = _filled_bytes(agent.replay_buffer) <= max_buffer_bytes
    if replay_buffer:
        _dump(agent.replay_buffer, directory / BUFFER_FILE)
        written.append(directory / BUFFER_FILE)
    return written


def load_agent(directory: str | pathlib.Path, env: gym.Env | VecEnv) -> HerDDPG:
    """The agent saved by :func:`save_agent`, on ``env``, with its saved buffers, so :func:`learn_episodes`
    continues where the saved run stopped."""
    directory = pathlib.Path(directory)
    agent = HerDDPG.load(directory / AGENT_FILE, env=env, device="cpu")
    if (directory / DEMO_BUFFER_FILE).exists():
        agent.demo_buffer = _load_buffer(directory / DEMO_BUFFER_FILE, agent)
    if (directory / BUFFER_FILE).exists():
        agent.replay_buffer = _load_buffer(directory / BUFFER_FILE, agent)
    return with_silent_logger(agent)
