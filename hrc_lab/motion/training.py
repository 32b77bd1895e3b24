"""Lightning glue of the motion module: one LightningModule for every supervised objective, trained on tensors
sampled with replacement so that a run is a fixed number of gradient steps whatever the data set's size."""

from __future__ import annotations

from collections.abc import Callable

import lightning.pytorch as pl
import torch
from torch.utils.data import DataLoader, RandomSampler, TensorDataset


class SupervisedModule(pl.LightningModule):
    """Minimises ``objective(network, *batch)``, which returns the loss and a dict of values to log."""

    def __init__(self, network: torch.nn.Module, objective: Callable, lr: float) -> None:
        super().__init__()
        self.network = network
        self.objective = objective
        self.lr = lr

    def training_step(self, batch, batch_idx: int) -> torch.Tensor:
        loss, logs = self.objective(self.network, *batch)
        self.log_dict({"train_loss": loss, **logs}, on_step=False, on_epoch=True, batch_size=len(batch[0]))
        return loss

    def configure_optimizers(self):
        return torch.optim.Adam(self.parameters(), lr=self.lr)


class TensorDataModule(pl.LightningDataModule):
    def __init__(self, tensors: list[torch.Tensor], batch_size: int, steps_per_epoch: int) -> None:
        super().__init__()
        if len(tensors[0]) == 0:
            raise ValueError("no training samples")
        self.dataset = TensorDataset(*tensors)
        self.batch_size = batch_size
        self.steps_per_epoch = steps_per_epoch

    def train_dataloader(self) -> DataLoader:
        sampler = RandomSampler(self.dataset, replacement=True, num_samples=self.batch_size * self.steps_per_epoch)
        return DataLoader(self.dataset, batch_size=self.batch_size, sampler=sampler)


def fit(network: torch.nn.Module, objective: Callable, tensors: list[torch.Tensor], lr: float, steps: int,
        batch_size: int, trainer_factory: Callable[[], pl.Trainer]) -> torch.nn.Module:
    """Train ``network`` for about ``steps`` gradient steps; ``trainer_factory()`` builds the Trainer (from
    ``conf/trainer``, logging into the job's MLflow run). Returns the network in eval mode."""
    module = SupervisedModule(network, objective, lr)
    trainer = trainer_factory()
    steps_per_epoch = max(1, steps // trainer.max_epochs)
    trainer.fit(module, datamodule=TensorDataModule(tensors, batch_size, steps_per_epoch))
    return network.eval()
