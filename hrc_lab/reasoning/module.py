"""Lightning glue shared by the torch reasoning methods: the joint cross-entropy objective and the data module."""

from __future__ import annotations

import lightning.pytorch as pl
import torch
import torch.nn.functional as F
from torch import nn
from torch.utils.data import RandomSampler
from torch_geometric.data import Data
from torch_geometric.loader import DataLoader


class ReasoningModule(pl.LightningModule):
    """Trains a reasoning network on L_re = loss_1 + loss_2 (Eq. 4.4-4.6): cross-entropy of P_o and of P_g."""

    def __init__(self, network: nn.Module, lr: float = 1e-3) -> None:
        super().__init__()
        self.network = network
        self.lr = lr

    def training_step(self, batch, batch_idx: int) -> torch.Tensor:
        logits_o, logits_g = self.network(batch, teacher_forcing=True)
        loss_o = F.cross_entropy(logits_o, batch.o_label)
        loss_g = F.cross_entropy(logits_g, batch.g_label)
        loss = loss_o + loss_g
        size = batch.o_label.numel()
        self.log_dict(
            {
                "train_loss": loss,
                "train_loss_o": loss_o,
                "train_loss_g": loss_g,
                "train_acc_o": (logits_o.argmax(-1) == batch.o_label).float().mean(),
                "train_acc_g": (logits_g.argmax(-1) == batch.g_label).float().mean(),
            },
            on_step=False,
            on_epoch=True,
            batch_size=size,
        )
        return loss

    def configure_optimizers(self):
        return torch.optim.Adam(self.parameters(), lr=self.lr)


class StageDataModule(pl.LightningDataModule):
    """Encoded stage observations, sampled with replacement so that an epoch is a fixed number of steps whatever
    the data set's size (the experiments train on 12 to 2,000 demonstrations)."""

    def __init__(self, samples: list[Data], batch_size: int, steps_per_epoch: int) -> None:
        super().__init__()
        if not samples:
            raise ValueError("no training samples")
        self.samples = samples
        self.batch_size = batch_size
        self.steps_per_epoch = steps_per_epoch

    def train_dataloader(self) -> DataLoader:
        sampler = RandomSampler(self.samples, replacement=True, num_samples=self.batch_size * self.steps_per_epoch)
        return DataLoader(self.samples, batch_size=self.batch_size, sampler=sampler)
