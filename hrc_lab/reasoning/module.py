"""The objective of the torch reasoning methods: the joint cross-entropy L_re of Eq. 4.4-4.6."""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from hrc_lab.training import SupervisedModule, accuracy


def joint_cross_entropy(network: nn.Module, batch) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """L_re = loss_1 + loss_2 (Eq. 4.4-4.6): cross-entropy of P_o and of P_g (teacher forcing), and both accuracies."""
    logits_o, logits_g = network(batch, teacher_forcing=True)
    loss_o = F.cross_entropy(logits_o, batch.o_label)
    loss_g = F.cross_entropy(logits_g, batch.g_label)
    values = {
        "loss_o": loss_o,
        "loss_g": loss_g,
        "acc_o": accuracy(logits_o, batch.o_label),
        "acc_g": accuracy(logits_g, batch.g_label),
    }
    return loss_o + loss_g, values


class ReasoningModule(SupervisedModule):
    """Trains a reasoning network on L_re with Adam; logs ``train_loss``, ``train_loss_o``, ``train_loss_g``,
    ``train_acc_o`` and ``train_acc_g`` per epoch."""

    def __init__(self, network: nn.Module, lr: float = 1e-3) -> None:
        super().__init__(network, joint_cross_entropy, lr)
