"""The HER paper's input normalisation for stable-baselines3's policies (Andrychowicz et al. 2017, ref. [19],
appendix "Normalizing inputs": every observation and goal coordinate is shifted and scaled by a running estimate
of its mean and standard deviation over the data seen so far, and clipped to [-5, 5]).

stable-baselines3's DDPG feeds raw inputs to its networks. In our cells that is 3.3's joint angles, positions in
metres and yaws in radians, where the last centimetres of Eq. 3.6 are differences of 0.01 in an input of
magnitude ~1. :class:`NormalizedCombinedExtractor` replaces SB3's ``CombinedExtractor`` (flatten and
concatenate the keys of the goal env's dict observation) by the same with a :class:`RunningNormalizer` per key.

The statistics are buffers named ``running_*``, saved with the policy. As in the reference implementation they
follow the stored episodes, not the batches the networks see: :func:`update_normalizers` adds a cycle's new
transitions to every extractor of a policy (actor, critic and their targets), with the desired goals of HER's
relabelling mixed in (:meth:`~hrc_lab.rl.ddpg.HerDDPG.update_input_statistics`). A forward pass only reads them;
the mean and std are recomputed once per update, not per pass.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

CLIP = 5.0  # the HER paper's clip range of normalised inputs
MIN_STD = 1e-2  # the HER baselines' normaliser floor: a constant coordinate is divided by this, not by 0


class RunningNormalizer(nn.Module):
    """``clip((x - mean) / max(std, min_std), -clip, clip)`` per coordinate, with the mean and std of every row
    passed to :meth:`update` (sums kept in float64, so long runs do not lose precision). Before any update it
    passes inputs through."""

    def __init__(self, size: int, clip: float = CLIP, min_std: float = MIN_STD) -> None:
        super().__init__()
        self.clip, self.min_std = clip, min_std
        self.register_buffer("running_sum", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("running_sumsq", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("running_count", torch.zeros((), dtype=torch.float64))
        # (mean, std, count): float32 mean and std of the sums at that count (SB3's target copies write the sums
        # in place, so the count, not a flag, says when to recompute)
        self._stats: tuple[torch.Tensor, torch.Tensor, float] | None = None

    def update(self, rows: np.ndarray | torch.Tensor) -> None:
        """Add ``rows`` (any leading shape, the last axis this normaliser's size) to the statistics."""
        rows = torch.as_tensor(np.asarray(rows), dtype=torch.float64).reshape(-1, self.running_sum.numel())
        self.running_sum += rows.sum(0)
        self.running_sumsq += rows.pow(2).sum(0)
        self.running_count += rows.shape[0]
        self._stats = None

    def _load_from_state_dict(self, *args, **kwargs) -> None:
        super()._load_from_state_dict(*args, **kwargs)
        self._stats = None  # loaded or copied sums (SB3 copies ``running_*`` buffers into the target networks)

    def stats(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The current mean and std (float32)."""
        if self._stats is None or self._stats[2] != float(self.running_count):
            count = float(self.running_count)
            if count == 0:
                mean, std = torch.zeros_like(self.running_sum), torch.ones_like(self.running_sum)
            else:
                mean = self.running_sum / count
                std = (self.running_sumsq / count - mean.pow(2)).clamp(min=0.0).sqrt().clamp(min=self.min_std)
            self._stats = (mean.float(), std.float(), count)
        return self._stats[0], self._stats[1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        mean, std = self.stats()
        return ((x - mean) / std).clamp(-self.clip, self.clip)


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


def update_normalizers(module: nn.Module, rows: dict[str, np.ndarray]) -> None:
    """Add ``rows`` (key -> array of rows) to every :class:`NormalizedCombinedExtractor` inside ``module`` (a policy:
    the actor's, the critic's and their targets' extractors keep the same statistics)."""
    for extractor in module.modules():
        if isinstance(extractor, NormalizedCombinedExtractor):
            for key, normalizer in extractor.normalizers.items():
                normalizer.update(rows[key])
