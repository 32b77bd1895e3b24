"""The second stage of the thesis' reasoning module (Sec. 4.2.1, Fig. 4.3): a classifier of P_g on [P_o, g].

Shared by ``ours`` (GraphSAGE encoder) and ``mlp`` (flat encoder): only the encoder producing P_o differs.
"""

from __future__ import annotations

import torch
from torch import nn


def mlp(sizes: list[int]) -> nn.Sequential:
    """Linear layers with ReLU between them (none after the last)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class StageClassifier(nn.Module):
    """Three fully connected layers with ReLU on the m+4 features [P_o (m+1), g_selected (3)] giving the n+1
    logits of P_g: the picking stage l_pi or one position-specified goal label l_g."""

    def __init__(self, n_o: int, n_g: int, hidden: int = 64) -> None:
        super().__init__()
        self.net = mlp([n_o + 3, hidden, hidden, n_g])

    def forward(self, p_o: torch.Tensor, g_selected: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([p_o, g_selected], dim=-1))


class TwoStageNet(nn.Module):
    """encoder(batch) -> logits of P_o; g_selected = goals[argmax P_o] (the label when teacher forcing);
    StageClassifier(softmax P_o, g_selected) -> logits of P_g. Trained jointly (Eq. 4.6)."""

    def __init__(self, encoder: nn.Module, classifier: StageClassifier) -> None:
        super().__init__()
        self.encoder = encoder
        self.classifier = classifier

    def forward(self, batch, teacher_forcing: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        logits_o = self.encoder(batch)
        chosen = batch.o_label if teacher_forcing else logits_o.argmax(-1)
        g_selected = batch.goals[torch.arange(len(chosen)), chosen]
        return logits_o, self.classifier(logits_o.softmax(-1), g_selected)
