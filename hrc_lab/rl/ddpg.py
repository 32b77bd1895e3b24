"""stable-baselines3's DDPG with the three details of the HER paper's DDPG that it lacks.

The HER paper's agent (Andrychowicz et al. 2017, ref. [19]; its code: OpenAI baselines' ``her``, Plappert et al.
2018) differs from a textbook DDPG in three places the thesis inherits by adopting "the standard DDPG with HER
architecture" (3.3):

- **action penalty**: the actor minimises ``-Q(s, pi(s)) + action_l2 * mean(pi(s)^2)`` over the [-1, 1] actions
  (``action_l2`` 1.0), so the policy does not saturate at the action bounds where the critic is flat;
- **random actions**: an exploration step is, with probability ``random_eps`` (0.3), an action drawn uniformly
  from the action space instead of the noisy policy's;
- **clipped targets**: with rewards in {-1, 0}, every return lies in [-1 / (1 - gamma), 0], so the critic's
  target ``r + gamma * Q'(s', pi'(s'))`` is clipped to it (``clip_return``).

:class:`HerDDPG` adds them to stable-baselines3's ``DDPG`` (``_sample_action`` for the random actions, ``train``
for the other two; ``train`` is SB3 2.x's ``TD3.train`` with the two changes marked). With ``action_l2 = 0``,
``random_eps = 0`` and ``clip_return = False`` (the constructor's defaults, so checkpoints saved by a plain DDPG
load unchanged) it is SB3's DDPG.
"""

from __future__ import annotations

import numpy as np
import torch as th
import torch.nn.functional as F
from stable_baselines3 import DDPG
from stable_baselines3.common.utils import polyak_update


class HerDDPG(DDPG):
    """DDPG with the HER paper's action penalty, random exploration actions and clipped critic targets (module
    docstring)."""

    def __init__(self, *args, action_l2: float = 0.0, random_eps: float = 0.0, clip_return: bool = False,
                 **kwargs) -> None:
        # validated with the rl config (hrc_lab.rl.configs.RLConfig), which is what builds every agent
        self.action_l2, self.random_eps, self.clip_return = action_l2, random_eps, clip_return
        super().__init__(*args, **kwargs)

    def _sample_action(self, learning_starts: int, action_noise=None, n_envs: int = 1) -> tuple[np.ndarray, np.ndarray]:
        action, buffer_action = super()._sample_action(learning_starts, action_noise, n_envs)
        if self.random_eps > 0 and self.num_timesteps >= learning_starts:
            for i in range(n_envs):  # the action space's generator, which SB3 seeds with the agent's seed
                if self.action_space.np_random.random() < self.random_eps:
                    buffer_action[i] = self.policy.scale_action(self.action_space.sample())
            action = self.policy.unscale_action(buffer_action)
        return action, buffer_action

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        return_bounds = (-1.0 / (1.0 - self.gamma), 0.0) if self.clip_return and self.gamma < 1 else None
        actor_losses, critic_losses = [], []
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay_data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            discounts = replay_data.discounts if replay_data.discounts is not None else self.gamma

            with th.no_grad():
                noise = replay_data.actions.clone().data.normal_(0, self.target_policy_noise)
                noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
                next_actions = (self.actor_target(replay_data.next_observations) + noise).clamp(-1, 1)
                next_q_values = th.cat(self.critic_target(replay_data.next_observations, next_actions), dim=1)
                next_q_values, _ = th.min(next_q_values, dim=1, keepdim=True)
                target_q_values = replay_data.rewards + (1 - replay_data.dones) * discounts * next_q_values
                if return_bounds is not None:  # HER paper: returns of {-1, 0} rewards lie in [-1 / (1 - gamma), 0]
                    target_q_values = target_q_values.clamp(*return_bounds)

            current_q_values = self.critic(replay_data.observations, replay_data.actions)
            critic_loss = sum(F.mse_loss(current_q, target_q_values) for current_q in current_q_values)
            critic_losses.append(critic_loss.item())
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            if self._n_updates % self.policy_delay == 0:
                actions = self.actor(replay_data.observations)
                actor_loss = -self.critic.q1_forward(replay_data.observations, actions).mean()
                if self.action_l2 > 0:  # HER paper: the action penalty on the [-1, 1] actions
                    actor_loss = actor_loss + self.action_l2 * actions.pow(2).mean()
                actor_losses.append(actor_loss.item())
                self.actor.optimizer.zero_grad()
                actor_loss.backward()
                self.actor.optimizer.step()

                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
                polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
                polyak_update(self.critic_batch_norm_stats, self.critic_batch_norm_stats_target, 1.0)
                polyak_update(self.actor_batch_norm_stats, self.actor_batch_norm_stats_target, 1.0)

        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if actor_losses:
            self.logger.record("train/actor_loss", np.mean(actor_losses))
        self.logger.record("train/critic_loss", np.mean(critic_losses))
