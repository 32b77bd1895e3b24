"""``reasoning=mlp``: the MLP baseline of Sec. 4.4.1. The chain graph's node features enter as one flat vector;
an MLP gives P_o and the thesis' stage classifier gives P_g, so only the graph encoder is replaced."""

from __future__ import annotations

from torch import nn
from torch_geometric.data import Data

from hrc_lab.env.robot.spec import StageObservation
from hrc_lab.reasoning.base import TorchReasoner
from hrc_lab.reasoning.configs import FlatMLPConfig
from hrc_lab.reasoning.encoding import flat_data
from hrc_lab.reasoning.two_stage import StageClassifier, TwoStageNet, mlp


class FlatEncoder(nn.Module):
    def __init__(self, in_features: int, hidden: int, n_out: int, layers: int = 3) -> None:
        super().__init__()
        self.net = mlp([in_features] + [hidden] * layers + [n_out])

    def forward(self, batch):
        return self.net(batch.x_flat)


class FlatMLPReasoner(TorchReasoner):
    cfg: FlatMLPConfig
    handles_missing_products = False

    def build_network(self) -> nn.Module:
        encoder = FlatEncoder(4 * self.spec.n_objects, self.cfg.hidden, self.n_o, self.cfg.layers)
        return TwoStageNet(encoder, StageClassifier(self.n_o, self.n_g, self.cfg.classifier_hidden))

    def encode(self, obs: StageObservation) -> Data:
        return flat_data(obs, self.spec, self.cfg.position_frame)
