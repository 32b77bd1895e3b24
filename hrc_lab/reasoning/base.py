"""The interface every reasoning method implements."""

from __future__ import annotations

from abc import ABC, abstractmethod

import lightning.pytorch as pl
import numpy as np
import torch
from torch import nn
from torch_geometric.data import Data
from torch_geometric.loader import DataLoader

from hrc_lab.env.robot.spec import PackageToOrderSpec, StageObservation
from hrc_lab.reasoning.configs import TorchReasonerConfig
from hrc_lab.reasoning.encoding import task_labels


class Reasoner(ABC):
    """Learns the importance distribution P_o (m+1) and the stage/goal distribution P_g (n_slots+1) from the
    observations at the start of each picking and placing stage (Sec. 4.2.1)."""

    #: whether the method copes with products missing from the scene (a varying number of inputs, 4.4.5)
    handles_missing_products = True

    def __init__(self, spec: PackageToOrderSpec, cfg, seed: int = 0) -> None:
        self.spec = spec
        self.cfg = cfg
        self.seed = seed

    @property
    def n_o(self) -> int:
        return self.spec.n_objects + 1

    @property
    def n_g(self) -> int:
        return self.spec.slots + 1

    @abstractmethod
    def fit(self, observations: list[StageObservation], trainer: pl.Trainer | None) -> None:
        """Train on expert observations; learned torch methods use the given Lightning trainer."""

    @abstractmethod
    def predict(self, observations: list[StageObservation]) -> np.ndarray:
        """(N, 2) predicted class indices of P_o and P_g."""

    def labels(self, observations: list[StageObservation]) -> np.ndarray:
        """(N, 2) the ground-truth class indices this method is trained and scored on: the thesis'
        position-specified labels unless a method overrides it."""
        return np.array([task_labels(o) for o in observations])


class TorchReasoner(Reasoner):
    """A reasoning network trained by Lightning on encoded observations (PyG ``Data`` samples).

    The network's ``forward(batch, teacher_forcing)`` returns the logits of P_o and P_g.
    """

    network: nn.Module

    def __init__(self, spec: PackageToOrderSpec, cfg: TorchReasonerConfig, seed: int = 0) -> None:
        super().__init__(spec, cfg, seed)
        self.network = self.build_network()

    @abstractmethod
    def build_network(self) -> nn.Module: ...

    @abstractmethod
    def encode(self, obs: StageObservation) -> Data: ...

    def training_observations(self, observations: list[StageObservation]) -> list[StageObservation]:
        """What :meth:`fit` trains on: the expert observations themselves unless a method augments them."""
        return observations

    def fit(self, observations: list[StageObservation], trainer: pl.Trainer | None) -> None:
        from hrc_lab.reasoning.module import ReasoningModule
        from hrc_lab.training import FixedStepDataModule, steps_per_epoch

        if trainer is None:
            raise ValueError(f"{type(self).__name__} is trained by Lightning and needs a trainer")
        samples = [self.encode(o) for o in self.training_observations(observations)]
        data = FixedStepDataModule(samples, self.cfg.batch_size, steps_per_epoch(self.cfg.steps, trainer))
        trainer.fit(ReasoningModule(self.network, lr=self.cfg.lr), datamodule=data)

    @torch.no_grad()
    def predict(self, observations: list[StageObservation], batch_size: int = 1024) -> np.ndarray:
        self.network.eval()
        loader = DataLoader([self.encode(o) for o in observations], batch_size=batch_size, shuffle=False)
        predictions = []
        for batch in loader:
            logits_o, logits_g = self.network(batch, teacher_forcing=False)
            predictions.append(torch.stack([logits_o.argmax(-1), logits_g.argmax(-1)], dim=1))
        return torch.cat(predictions).numpy()
