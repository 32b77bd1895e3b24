"""Networks of the two-level motion planner (thesis 3.2.1-3.2.2, Fig. 3.2-3.3)."""

from __future__ import annotations

import math

import torch
from torch import nn


class TaskConditionedVI(nn.Module):
    """Task-conditioned variational sub-goal planner (Fig. 3.2, Eq. 3.1-3.4).

    Two Tanh layers on the raw observation x, the task label (one-hot) concatenated, then the mean and the std of
    the latent q(z | O) = N(mu, delta) over the 3-D sub-goal. ``use_labels=False`` drops the label (VI baseline);
    ``stochastic=False`` keeps only the mean head (the deterministic MLP baseline).
    """

    def __init__(self, obs_dim: int, n_labels: int, hidden: int = 64, out_dim: int = 3, use_labels: bool = True,
                 stochastic: bool = True) -> None:
        super().__init__()
        self.use_labels = use_labels
        self.stochastic = stochastic
        self.encoder = nn.Sequential(nn.Linear(obs_dim, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh())
        self.head = nn.Sequential(nn.Linear(hidden + (n_labels if use_labels else 0), hidden), nn.Tanh())
        self.mean = nn.Linear(hidden, out_dim)
        self.log_std = nn.Linear(hidden, out_dim) if stochastic else None

    def forward(self, x: torch.Tensor, labels: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.encoder(x)
        if self.use_labels:
            h = torch.cat([h, labels], dim=-1)
        h = self.head(h)
        mean = self.mean(h)
        if self.log_std is None:
            return mean, torch.zeros_like(mean)
        return mean, self.log_std(h).clamp(-7.0, 2.0).exp()


def variational_loss(mean: torch.Tensor, std: torch.Tensor, target: torch.Tensor, likelihood_std: float,
                     kl_weight: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Negative ELBO of Eq. 3.2-3.4 with one reparameterised sample z = mu + delta * eps:

    -log N(s; z, sigma_lik^2) (Gaussian negative log-likelihood, Eq. 3.4) + kl_weight * D_kl[N(mu, delta) || N(0, 1)]
    (the unit-Gaussian prior on standardised sub-goals). Returns (loss, nll, kl), each a batch mean.
    """
    z = mean + std * torch.randn_like(std)
    nll = (0.5 * ((target - z) / likelihood_std) ** 2 + math.log(likelihood_std) + 0.5 * math.log(2 * math.pi))
    nll = nll.sum(-1).mean()
    kl = (0.5 * (mean**2 + std**2 - 1.0) - torch.log(std)).sum(-1).mean()
    return nll + kl_weight * kl, nll, kl


class NeuralDynamicPlanner(nn.Module):
    """a_t = D(Delta_t), Delta_t = s_t - r_t (Fig. 3.3, Eq. 3.5): three ReLU layers. ``directions=True`` gives
    logits over {-1, 0, 1} per joint (the direction-only planner of 3.3)."""

    def __init__(self, hidden: int = 64, n_joints: int = 3, directions: bool = False) -> None:
        super().__init__()
        self.directions = directions
        self.n_joints = n_joints
        out = 3 * n_joints if directions else n_joints
        self.net = nn.Sequential(nn.Linear(3, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                                 nn.Linear(hidden, out))

    def forward(self, delta: torch.Tensor) -> torch.Tensor:
        out = self.net(delta)
        return out.view(*out.shape[:-1], self.n_joints, 3) if self.directions else out


class FullObservationActor(nn.Module):
    """pi(r, s): the actor Fig. 3.10 compares with, fed the end effector and the sub-goal instead of their
    difference (same depth and width as the neural dynamic planner)."""

    def __init__(self, hidden: int = 64, n_joints: int = 3) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Linear(6, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                                 nn.Linear(hidden, n_joints))

    def forward(self, inputs: torch.Tensor) -> torch.Tensor:
        return self.net(inputs)


class TaskClassifier(nn.Module):
    """l = c(x; theta_c) (3.2.1): an MLP from the raw observation to the stage label."""

    def __init__(self, obs_dim: int, n_labels: int, hidden: int = 64) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Linear(obs_dim, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                                 nn.Linear(hidden, n_labels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)
