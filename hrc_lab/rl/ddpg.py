"""stable-baselines3's DDPG as the HER reference implementation trains it, with demonstrations.

The HER paper's agent (Andrychowicz et al. 2017, ref. [19]; its code: OpenAI baselines' ``her``, Plappert et al.
2018) differs from a textbook DDPG in places the thesis inherits by adopting "the standard DDPG with HER
architecture" (3.3):

- **action penalty**: the actor minimises ``-Q(s, pi(s)) + action_l2 * mean(pi(s)^2)`` over the [-1, 1] actions
  (``action_l2`` 1.0), so the policy does not saturate at the action bounds where the critic is flat;
- **random actions**: an exploration step is, with probability ``random_eps`` (0.3), an action drawn uniformly
  from the action space instead of the noisy policy's;
- **clipped targets**: with rewards in {-1, 0}, every return lies in [-1 / (1 - gamma), 0], so the critic's
  target ``r + gamma * Q'(s', pi'(s'))`` is clipped to it (``clip_return``);
- **one target update per cycle** (``target_update="cycle"``): the soft update with ``tau`` runs once after a
  cycle's gradient steps, not after each;
- **normaliser statistics from the stored episodes** (:meth:`HerDDPG.update_input_statistics`, before each cycle's
  gradient steps), not from the batches.

Demonstrations (Nair et al. 2018, the reference's ``bc_loss`` / ``q_filter``): :meth:`HerDDPG.add_demonstration`
stores whole episodes in a second HER buffer (``demo_buffer``); each batch then takes ``demo_batch_size`` samples
from it, and the actor's loss gains ``bc_weight * sum((pi(s) - a)^2)`` over the demonstration samples whose
demonstrated action the critic rates above the policy's (``q_filter``). Before the first update with
demonstrations the actor clones them alone for ``bc_pretrain_steps`` batches, and the critic then learns for
``critic_warmup_steps`` gradient steps before the actor follows it (an untrained critic's Q-filter rejects most
demonstrations and undoes the cloning).

Executed actions: when an env wrapper replaced the policy's action (Algorithm 1's guidance,
:class:`~hrc_lab.rl.guidance.GuidedEnv`), ``info["executed_action"]`` is what the replay buffer stores. With
``guided_episodes="demos"`` the guided episodes also enter the demonstration buffer, and with
``guided_exploration=False`` the policy acts in them without exploration noise (the ``guided`` flag of each
env's reset info).

With the constructor's defaults (no penalty, no random actions, no clipping, targets per step, no demonstrations)
it is SB3's DDPG.
"""

from __future__ import annotations

import numpy as np
import torch as th
import torch.nn.functional as F
from gymnasium.spaces import Box
from stable_baselines3 import DDPG
from stable_baselines3.common.type_aliases import DictReplayBufferSamples
from stable_baselines3.common.utils import ConstantSchedule, polyak_update
from stable_baselines3.td3.policies import MultiInputPolicy
from torch import nn

from hrc_lab.rl.buffers import FilledHerReplayBuffer
from hrc_lab.rl.normalization import update_normalizers


def concatenate(a: DictReplayBufferSamples, b: DictReplayBufferSamples) -> DictReplayBufferSamples:
    """Two batches of HER samples as one (``a``'s rows first)."""
    return DictReplayBufferSamples(
        observations={key: th.cat((a.observations[key], b.observations[key])) for key in a.observations},
        actions=th.cat((a.actions, b.actions)),
        next_observations={key: th.cat((a.next_observations[key], b.next_observations[key]))
                           for key in a.next_observations},
        dones=th.cat((a.dones, b.dones)),
        rewards=th.cat((a.rewards, b.rewards)),
    )


class HerPolicy(MultiInputPolicy):
    """stable-baselines3's DDPG policy for dict observations whose training mode switches only when it changes: SB3
    sets it before every ``predict``, a walk over every module that took ~0.2 ms of a ~1.5 ms control step (the
    networks have no dropout or batch norm, so the mode changes no output)."""

    def set_training_mode(self, mode: bool) -> None:
        if mode != self.training:
            super().set_training_mode(mode)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = False):
        """SB3's ``predict`` for the goal env's dict of float32 arrays (one observation or a batch) with the usual
        actor (:meth:`_lean_actor`): the same operations on the same numbers in fewer calls (~0.1 ms of a control
        step). The keys are concatenated first and normalised in one pass with the normalisers' concatenated mean and
        std (element-wise operations, so each element is computed as the per-key passes compute it), and the
        layers are called as functions. Anything else goes through SB3's."""
        layers = self._lean_actor()
        flat = self._flat_observation(observation) if layers is not None else None
        if flat is None:
            return super().predict(observation, state, episode_start, deterministic)
        self.set_training_mode(False)
        x, vectorized = flat
        mean, std, clip = self._input_statistics()
        with th.no_grad():
            x = ((th.from_numpy(x) - mean) / std).clamp(-clip, clip)
            for kind, weight, bias in layers:
                x = F.linear(x, weight, bias) if kind == "linear" else kind(x)
        actions = self.unscale_action(x.numpy().reshape((-1, *self.action_space.shape)))  # squash_output
        return (actions if vectorized else actions.squeeze(axis=0)), state

    def _flat_observation(self, observation) -> tuple[np.ndarray, bool] | None:
        """The observation's keys in the normalisers' order, flattened and concatenated (float32, one row per
        observation), and whether it was a batch; None when it is not a dict of float32 arrays of the space's
        shapes."""
        spaces = self.observation_space.spaces
        if not isinstance(observation, dict) or observation.keys() != spaces.keys():
            return None
        rows, vectorized = [], False
        for key in self.actor.features_extractor.normalizers:
            obs, space = observation[key], spaces[key]
            if type(obs) is not np.ndarray or obs.dtype != np.float32 or space.dtype != np.float32:
                return None
            if obs.shape[1:] == space.shape:
                vectorized = True
            elif obs.shape != space.shape:
                return None  # SB3 names the wrong shape
            rows.append(obs.reshape(-1, int(np.prod(space.shape))))
        return np.concatenate(rows, axis=1), vectorized

    def _input_statistics(self) -> tuple[th.Tensor, th.Tensor, float]:
        """The actor's normalisers' mean and std (:meth:`RunningNormalizer.stats`) concatenated in key order, kept
        while they stay the same, and their clip."""
        normalizers = list(self.actor.features_extractor.normalizers.values())
        stats = [normalizer.stats() for normalizer in normalizers]
        cached = self.__dict__.get("_input_stats")
        if cached is None or any(a is not b for a, b in zip(cached[0], [m for m, _ in stats])):
            cached = ([m for m, _ in stats], th.cat([m for m, _ in stats]), th.cat([sd for _, sd in stats]))
            self.__dict__["_input_stats"] = cached
        return cached[1], cached[2], normalizers[0].clip

    def _lean_actor(self) -> list | None:
        """The actor's layers as (``"linear"``, weight, bias) or (function, None, None), or None when they are not
        all Linear, ReLU and Tanh, or its extractor is not the normalising one with one clip for every key (read
        once per actor). The weights are the parameters' ``.data``: the same storage, which Adam and
        ``load_state_dict`` update in place, without autograd's bookkeeping."""
        from hrc_lab.rl.normalization import NormalizedCombinedExtractor, RunningNormalizer

        cached = self.__dict__.get("_lean_layers")
        if cached is not None and cached[0] is self.actor:
            return cached[1]
        kinds = {nn.ReLU: th.relu, nn.Tanh: th.tanh}
        extractor = self.actor.features_extractor
        normalizers = list(getattr(extractor, "normalizers", {}).values())
        usual = (type(extractor) is NormalizedCombinedExtractor and self.squash_output
                 and all(type(n) is RunningNormalizer for n in normalizers)
                 and len({n.clip for n in normalizers}) == 1
                 and all(type(layer) in (nn.Linear, *kinds) and not getattr(layer, "inplace", False)
                         for layer in self.actor.mu))
        layers = [("linear", layer.weight.data, None if layer.bias is None else layer.bias.data)
                  if type(layer) is nn.Linear else (kinds[type(layer)], None, None)
                  for layer in self.actor.mu] if usual else None
        self.__dict__["_lean_layers"] = (self.actor, layers)
        return layers

    def obs_to_tensor(self, observation):
        """SB3's ``obs_to_tensor`` for the goal env's dict of float arrays (one observation or a batch), without its
        deep copy and per-key checks: the same tensors, copies of the arrays. Anything else goes through SB3's."""
        spaces = self.observation_space.spaces
        if not isinstance(observation, dict) or observation.keys() != spaces.keys():
            return super().obs_to_tensor(observation)
        tensors, vectorized = {}, False
        for key, space in spaces.items():
            obs = observation[key]
            if type(obs) is not np.ndarray or obs.dtype != space.dtype or not isinstance(space, Box):
                return super().obs_to_tensor(observation)
            if obs.shape[1:] == space.shape:
                vectorized = True
            elif obs.shape != space.shape:
                return super().obs_to_tensor(observation)  # SB3 names the wrong shape
            tensors[key] = th.from_numpy(obs.reshape((-1, *space.shape)).copy())
        return tensors, vectorized


class HerDDPG(DDPG):
    """DDPG as the HER reference implementation trains it, with an optional demonstration buffer (module
    docstring)."""

    def __init__(self, *args, action_l2: float = 0.0, random_eps: float = 0.0, clip_return: bool = False,
                 target_update: str = "step", demo_batch_size: int = 0, bc_weight: float = 0.0,
                 q_filter: bool = False, bc_pretrain_steps: int = 0, critic_warmup_steps: int = 0,
                 guided_episodes: str = "replay", guided_exploration: bool = True, **kwargs) -> None:
        # validated with the rl config (hrc_lab.rl.configs.RLConfig), which is what builds every agent
        self.action_l2, self.random_eps, self.clip_return = action_l2, random_eps, clip_return
        self.target_update = target_update
        self.demo_batch_size, self.bc_weight, self.q_filter = demo_batch_size, bc_weight, q_filter
        self.bc_pretrain_steps, self.critic_warmup_steps = bc_pretrain_steps, critic_warmup_steps
        self.critic_warmup_until: int | None = None  # the update count until which only the critic learns
        self.guided_episodes, self.guided_exploration = guided_episodes, guided_exploration
        self.demo_buffer: FilledHerReplayBuffer | None = None
        self._open_demos: dict[int, list[tuple]] = {}  # env index -> the guided episode being collected
        self._guided_now: np.ndarray | None = None  # per env: is its running episode guided (from the reset infos)
        self._statistics_steps = 0  # num_timesteps when the normaliser last took the replay buffer's new rows
        self._update_values: dict[str, list[float]] = {}  # per-update diagnostics since update_diagnostics()
        super().__init__(*args, **kwargs)

    # --- exploration and storage --------------------------------------------------------------------------------

    def _sample_action(self, learning_starts: int, action_noise=None, n_envs: int = 1) -> tuple[np.ndarray, np.ndarray]:
        action, buffer_action = super()._sample_action(learning_starts, action_noise, n_envs)
        if self.num_timesteps < learning_starts:
            return action, buffer_action
        quiet = self._noiseless_envs(n_envs)
        if quiet.any():  # guided episodes without exploration: the current policy's own action
            policy_action, _ = self.predict(self._last_obs, deterministic=True)
            buffer_action[quiet] = self.policy.scale_action(policy_action)[quiet]
        if self.random_eps > 0:
            for i in range(n_envs):  # the action space's generator, which SB3 seeds with the agent's seed
                if not quiet[i] and self.action_space.np_random.random() < self.random_eps:
                    buffer_action[i] = self.policy.scale_action(self.action_space.sample())
        return self.policy.unscale_action(buffer_action), buffer_action

    def _noiseless_envs(self, n_envs: int) -> np.ndarray:
        """Which envs run a guided episode whose actions carry no exploration noise (``guided_exploration``)."""
        if self.guided_exploration or self._guided_now is None:
            return np.zeros(n_envs, dtype=bool)
        return self._guided_now.copy()

    def _setup_learn(self, total_timesteps, callback=None, reset_num_timesteps=True, *args, **kwargs):
        resets = reset_num_timesteps or self._last_obs is None  # when SB3's setup resets the envs
        setup = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, *args, **kwargs)
        if resets:  # each env's reset info says whether its episode is guided (no call into the env processes)
            self._guided_now = np.array([info.get("guided", False) for info in self.env.reset_infos], dtype=bool)
        return setup

    def _store_transition(self, replay_buffer, buffer_action, new_obs, reward, dones, infos) -> None:
        if self._guided_now is not None:  # an env that ended its episode has reset into its next one
            for i in np.flatnonzero(dones):
                self._guided_now[i] = self.env.reset_infos[i].get("guided", False)
        executed = [info.get("executed_action") for info in infos]
        if any(a is not None for a in executed):  # a wrapper acted instead of the policy: store what it executed
            buffer_action = np.array([buffer_action[i] if a is None else a for i, a in enumerate(executed)],
                                     dtype=buffer_action.dtype)
        if self.guided_episodes == "demos":
            self._collect_guided(buffer_action, new_obs, reward, dones, infos)
        if self._vec_normalize_env is not None or not isinstance(new_obs, dict):
            return super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)
        # SB3's _store_transition, with copies of the observation arrays for its deep copy of their dict
        self._last_original_obs = self._last_obs
        next_obs = {key: np.copy(value) for key, value in new_obs.items()}
        for i, done in enumerate(dones):  # the VecEnv has reset a finished env: its last observation is in infos
            if done and infos[i].get("terminal_observation") is not None:
                for key in next_obs:
                    next_obs[key][i] = infos[i]["terminal_observation"][key]
        replay_buffer.add(self._last_original_obs, next_obs, buffer_action, reward, dones, infos)
        self._last_obs = new_obs

    def _collect_guided(self, buffer_action, new_obs, reward, dones, infos) -> None:
        """Keep each env's guided episode, transition by transition, and move it into the demonstration buffer
        when it ends."""
        for i, info in enumerate(infos):
            if not info.get("guided"):
                continue
            terminal = info.get("terminal_observation") if dones[i] else None  # the VecEnv has already reset
            next_obs = {key: new_obs[key][i] if terminal is None else terminal[key] for key in new_obs}
            obs = {key: self._last_obs[key][i] for key in self._last_obs}
            self._open_demos.setdefault(i, []).append((obs, next_obs, buffer_action[i], float(reward[i]), info))
            if dones[i]:
                self.add_demonstration(self._open_demos.pop(i))

    def add_demonstration(self, episode: list[tuple]) -> None:
        """Store one episode of ``(obs, next_obs, action in [-1, 1], reward, info)`` transitions in the
        demonstration buffer (made on first use, as large as the replay buffer) and its inputs in the normaliser's
        statistics."""
        if self.demo_buffer is None:
            self.demo_buffer = FilledHerReplayBuffer(
                self.buffer_size, self.observation_space, self.action_space, env=self.env, device="cpu", n_envs=1,
                **self.replay_buffer_kwargs)
        for k, (obs, next_obs, action, reward, info) in enumerate(episode):
            last = k == len(episode) - 1
            self.demo_buffer.add({key: v[None] for key, v in obs.items()},
                                 {key: v[None] for key, v in next_obs.items()}, np.asarray(action)[None],
                                 np.array([reward]), np.array([last]), [{**info, "TimeLimit.truncated": last}])
        rows = {key: np.stack([t[0][key] for t in episode]) for key in episode[0][0]}
        self._add_statistics(rows)

    # --- input statistics ---------------------------------------------------------------------------------------

    def _add_statistics(self, rows: dict[str, np.ndarray]) -> None:
        """Observation and goal rows into the normaliser's statistics; the desired goals as HER samples them:
        ``n_sampled_goal`` achieved goals of the same episodes ("future" relabelling) per original desired goal."""
        desired = np.concatenate([rows["desired_goal"], *[rows["achieved_goal"]] * self.replay_buffer.n_sampled_goal])
        update_normalizers(self.policy, {**rows, "desired_goal": desired})

    def update_input_statistics(self) -> None:
        """Add the transitions stored since the last call (every env's) to the normaliser's statistics: the rows
        written since then end at the buffer's position (also when a resumed agent starts a fresh buffer)."""
        buffer = self.replay_buffer
        new = min((self.num_timesteps - self._statistics_steps) // buffer.n_envs, buffer.buffer_size)
        if new <= 0:
            return
        rows = (buffer.pos - new + np.arange(new)) % buffer.buffer_size
        self._add_statistics({key: value[rows].reshape(-1, value.shape[-1])
                              for key, value in buffer.observations.items()})
        self._statistics_steps = self.num_timesteps

    # --- training -----------------------------------------------------------------------------------------------

    def _sample(self, batch_size: int) -> tuple[DictReplayBufferSamples, int]:
        """A batch: ``demo_batch_size`` demonstration samples first when there are demonstrations, the rest from
        the replay buffer; and how many of its rows are demonstrations."""
        n_demo = self.demo_batch_size if self.demo_buffer is not None and self.demo_buffer.size() > 0 else 0
        replay = self.replay_buffer.sample(batch_size - n_demo, env=self._vec_normalize_env)
        if not n_demo:
            return replay, 0
        return concatenate(self.demo_buffer.sample(n_demo, env=self._vec_normalize_env), replay), n_demo

    def _actor_loss(self, data: DictReplayBufferSamples, n_demo: int) -> th.Tensor:
        actions = self.actor(data.observations)
        q_pi = self.critic.q1_forward(data.observations, actions)
        loss = -q_pi.mean()
        self._accumulate("q_policy", q_pi.mean().item())
        if self.action_l2 > 0:  # HER paper: the action penalty on the [-1, 1] actions
            loss = loss + self.action_l2 * actions.pow(2).mean()
        if n_demo and self.bc_weight > 0:  # Nair et al.: behaviour cloning on the demonstrations, Q-filtered
            error = (actions[:n_demo] - data.actions[:n_demo]).pow(2).sum(dim=1, keepdim=True)
            if self.q_filter:
                with th.no_grad():
                    better = self.critic.q1_forward(
                        {key: v[:n_demo] for key, v in data.observations.items()}, data.actions[:n_demo])
                    error = error * (better > q_pi[:n_demo].detach()).float()
            bc_loss = self.bc_weight * error.sum()
            self._accumulate("bc_loss", bc_loss.item())
            self._accumulate("bc_share", bc_loss.item() / max(1e-9, abs(loss.item()) + bc_loss.item()))
            loss = loss + bc_loss
        return loss

    def _accumulate(self, key: str, value: float) -> None:
        self._update_values.setdefault(key, []).append(value)

    def update_diagnostics(self) -> dict[str, float]:
        """Means over the gradient steps since the last call (then reset), for the trainer's per-epoch metrics:
        ``critic_loss``, ``target_q`` (the critic's targets), ``q_policy`` (Q(s, pi(s)) the actor climbs),
        ``actor_loss``; with demonstrations ``bc_loss`` (the weighted cloning term) and ``bc_share`` (its share of
        the actor's loss magnitude). A falling ``q_policy`` with a rising ``critic_loss`` is the critic diverging."""
        values, self._update_values = self._update_values, {}
        return {key: float(np.mean(v)) for key, v in values.items()}

    def pretrain_on_demonstrations(self, batch_size: int) -> None:
        """Behaviour cloning alone: ``bc_pretrain_steps`` batches of demonstrations (HER-relabelled goals, as in
        training), the actor's squared error to their actions; then the target actor copies the actor, and the
        critic alone learns for the next ``critic_warmup_steps`` gradient steps."""
        for _ in range(self.bc_pretrain_steps):
            data = self.demo_buffer.sample(batch_size, env=self._vec_normalize_env)
            loss = (self.actor(data.observations) - data.actions).pow(2).sum(dim=1).mean()
            self.actor.optimizer.zero_grad()
            loss.backward()
            self.actor.optimizer.step()
        polyak_update(self.actor.parameters(), self.actor_target.parameters(), 1.0)
        self.critic_warmup_until = self._n_updates + self.critic_warmup_steps

    def set_learning_rate(self, value: float) -> None:
        """Adam's step size of the actor and the critic from the next cycle on (the trainer's per-epoch schedule,
        :func:`hrc_lab.rl.trainer.learning_rate_at`)."""
        self.learning_rate = value
        self.lr_schedule = ConstantSchedule(value)

    def _update_targets(self) -> None:
        polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
        polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
        polyak_update(self.critic_batch_norm_stats, self.critic_batch_norm_stats_target, 1.0)
        polyak_update(self.actor_batch_norm_stats, self.actor_batch_norm_stats_target, 1.0)

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        """One cycle's gradient steps (SB3 2.x's ``TD3.train`` with the changes of the module docstring)."""
        self.policy.set_training_mode(True)
        self.update_input_statistics()
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        return_bounds = (-1.0 / (1.0 - self.gamma), 0.0) if self.clip_return and self.gamma < 1 else None
        if self.critic_warmup_until is None and self.demo_buffer is not None and self.demo_buffer.size():
            self.pretrain_on_demonstrations(batch_size)
        actor_losses, critic_losses = [], []
        for _ in range(gradient_steps):
            self._n_updates += 1
            data, n_demo = self._sample(batch_size)
            with th.no_grad():
                next_q = th.cat(self.critic_target(data.next_observations,
                                                   self.actor_target(data.next_observations)), dim=1)
                next_q, _ = th.min(next_q, dim=1, keepdim=True)
                target_q = data.rewards + (1 - data.dones) * self.gamma * next_q
                if return_bounds is not None:  # HER paper: returns of {-1, 0} rewards lie in [-1 / (1 - gamma), 0]
                    target_q = target_q.clamp(*return_bounds)
            critic_loss = sum(F.mse_loss(q, target_q) for q in self.critic(data.observations, data.actions))
            critic_losses.append(critic_loss.item())
            self._accumulate("critic_loss", critic_loss.item())
            self._accumulate("target_q", target_q.mean().item())
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            if self.critic_warmup_until is None or self._n_updates > self.critic_warmup_until:
                # the critic's weights take no gradient from the actor's loss (SB3 computed it, and the next
                # step's zero_grad dropped it): the actor's gradients are the same, bit for bit
                critic_weights = [p for p in self.critic.parameters() if p.requires_grad]
                for weight in critic_weights:
                    weight.requires_grad_(False)
                try:
                    actor_loss = self._actor_loss(data, n_demo)
                    actor_losses.append(actor_loss.item())
                    self._accumulate("actor_loss", actor_loss.item())
                    self.actor.optimizer.zero_grad()
                    actor_loss.backward()
                finally:
                    for weight in critic_weights:
                        weight.requires_grad_(True)
                self.actor.optimizer.step()
            if self.target_update == "step":
                self._update_targets()
        if self.target_update == "cycle" and gradient_steps:
            self._update_targets()
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if actor_losses:
            self.logger.record("train/actor_loss", np.mean(actor_losses))
        if critic_losses:
            self.logger.record("train/critic_loss", np.mean(critic_losses))

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "demo_buffer", "_open_demos", "_update_values"]
