"""The HER paper's input normalisation for stable-baselines3's policies (Andrychowicz et al. 2017, ref. [19],
appendix "Normalizing inputs": every observation and goal coordinate is shifted and scaled by a running estimate
of its mean and standard deviation over the data seen so far, and clipped to [-5, 5]).

stable-baselines3's DDPG feeds raw inputs to its networks. In our cells that is 3.3's joint angles, positions in
metres and yaws in radians, where the last centimetres of Eq. 3.6 are differences of 0.01 in an input of
magnitude ~1. :class:`NormalizedCombinedExtractor` replaces SB3's ``CombinedExtractor`` (flatten and
concatenate the keys of the goal env's dict observation) by the same with a :class:`RunningNormalizer` per key.

The statistics are buffers named ``running_*``: they are saved with the policy, and SB3's TD3/DDPG copies them to
the target networks after every gradient step as it does batch-norm statistics. They are updated from every batch
the networks see in training mode, i.e. the replay buffer's samples, HER's relabelled goals included (as the HER
paper updates its goal statistics with relabelled goals); in evaluation mode (rollouts, ``predict``) they are only
read.
"""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

CLIP = 5.0  # the HER paper's clip range of normalised inputs
MIN_STD = 1e-2  # the HER baselines' normaliser floor: a constant coordinate is divided by this, not by 0


class RunningNormalizer(nn.Module):
    """``clip((x - mean) / max(std, min_std), -clip, clip)`` per coordinate, with the mean and std of every row
    passed through it in training mode (sums kept in float64, so long runs do not lose precision)."""

    def __init__(self, size: int, clip: float = CLIP, min_std: float = MIN_STD) -> None:
        super().__init__()
        self.clip, self.min_std = clip, min_std
        self.register_buffer("running_sum", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("running_sumsq", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("running_count", torch.zeros((), dtype=torch.float64))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.training:
            with torch.no_grad():
                rows = x.detach().reshape(-1, self.running_sum.numel()).double()
                self.running_sum += rows.sum(0)
                self.running_sumsq += rows.pow(2).sum(0)
                self.running_count += rows.shape[0]
        count = self.running_count.clamp(min=1.0)
        mean = self.running_sum / count
        var = (self.running_sumsq / count - mean.pow(2)).clamp(min=0.0)
        std = var.sqrt().clamp(min=self.min_std)
        if self.running_count == 0:  # nothing seen yet: pass through (SB3 trains only after rl.learning_starts)
            mean, std = torch.zeros_like(mean), torch.ones_like(std)
        return ((x - mean.to(x.dtype)) / std.to(x.dtype)).clamp(-self.clip, self.clip)


class NormalizedCombinedExtractor(BaseFeaturesExtractor):
    """SB3's ``CombinedExtractor`` for flat dict observations (observation, achieved goal, desired goal), each key
    flattened and normalised by its own :class:`RunningNormalizer`, then concatenated."""

    def __init__(self, observation_space: gym.spaces.Dict, clip: float = CLIP, min_std: float = MIN_STD) -> None:
        sizes = {key: get_flattened_obs_dim(space) for key, space in observation_space.spaces.items()}
        super().__init__(observation_space, features_dim=sum(sizes.values()))
        self.normalizers = nn.ModuleDict({key: RunningNormalizer(size, clip, min_std) for key, size in sizes.items()})

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        return torch.cat([normalizer(observations[key].flatten(1)) for key, normalizer in self.normalizers.items()],
                         dim=1)
