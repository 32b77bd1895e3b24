"""``reasoning=ours``: the thesis' reasoning module (Sec. 4.2.1, Eq. 4.1-4.6, Fig. 4.3).

A chain graph of the m products with node features (x, y, z, I) passes through three GraphSAGE layers,

    h_N(i)^k = mean_{j in N(i)} h_j^{k-1}                                   (Eq. 4.1)
    h_i^k    = ReLU(W_1 h_i^{k-1} + W_2 h_N(i)^k),  h_i^k <- h_i^k / ||h_i^k||_2   (Eq. 4.2)

a mean readout G = mean_i h_i^K (Eq. 4.3) and a linear layer giving the m+1 logits of P_o. The stage classifier
of :mod:`hrc_lab.reasoning.two_stage` maps [P_o, g_selected] to P_g; both are trained on L_re (Eq. 4.4-4.6).

Ablations (``reasoning.edges``, ``reasoning.readout``; see :class:`ChainSAGEConfig`): the edge set, and a
permutation-equivariant readout that is hrc_lab's, not the thesis': each product node scores itself, the packaging
area is scored from G, and P_o is the softmax over these m+1 scores (absent products get none).

``reasoning=hrc`` (:class:`HRCReasoner`, hrc_lab's reasoning module) is this network with a pointer readout (the
packaging area scored by the node that scores it highest, :class:`PointerEncoder`), a choice of the aggregation of
Eq. 4.1 (``reasoning.aggr``) and training on identity-augmented observations (:mod:`hrc_lab.reasoning.augment`).
"""

from __future__ import annotations

import torch
from torch import nn
from torch_geometric.data import Data
from torch_geometric.nn import SAGEConv, global_max_pool, global_mean_pool

from hrc_lab.env.robot.spec import StageObservation
from hrc_lab.reasoning.augment import augmented
from hrc_lab.reasoning.base import TorchReasoner
from hrc_lab.reasoning.configs import ChainSAGEConfig, HRCConfig
from hrc_lab.reasoning.encoding import chain_graph
from hrc_lab.reasoning.two_stage import StageClassifier, TwoStageNet


class SAGEStack(nn.Module):
    """``layers`` SAGEConv layers with mean aggregation (Eq. 4.1; ``aggr="max"`` takes the element-wise maximum over
    the neighbours instead), ReLU and L2-normalised embeddings (Eq. 4.2)."""

    def __init__(self, in_channels: int, hidden: int, layers: int = 3, aggr: str = "mean") -> None:
        super().__init__()
        sizes = [in_channels] + [hidden] * layers
        self.convs = nn.ModuleList(
            SAGEConv(a, b, aggr=aggr, normalize=True) for a, b in zip(sizes, sizes[1:], strict=False)
        )

    def forward(self, x: torch.Tensor, edge_index: torch.Tensor) -> torch.Tensor:
        for conv in self.convs:
            x = conv(x, edge_index).relu()
        return x


class ChainSAGEEncoder(nn.Module):
    """SAGEConv stack, mean readout (Eq. 4.3) and a linear layer giving the m+1 logits of P_o."""

    def __init__(self, in_channels: int, hidden: int, n_out: int, layers: int = 3, aggr: str = "mean") -> None:
        super().__init__()
        self.sage = SAGEStack(in_channels, hidden, layers, aggr)
        self.head = nn.Linear(hidden, n_out)

    def logits(self, x: torch.Tensor, edge_index: torch.Tensor, batch: torch.Tensor | None = None) -> torch.Tensor:
        return self.head(global_mean_pool(self.sage(x, edge_index), batch))

    def forward(self, batch) -> torch.Tensor:
        return self.logits(batch.x, batch.edge_index, batch.batch)


class NodeScoreEncoder(nn.Module):
    """SAGEConv stack; logit of product i = a linear score of its node, logit of the packaging area = a linear
    score of the mean readout G (hrc_lab's ablation; absent products get ``ABSENT``, a softmax weight of 0)."""

    ABSENT = -1e9

    def __init__(self, in_channels: int, hidden: int, n_out: int, layers: int = 3, aggr: str = "mean") -> None:
        super().__init__()
        self.sage = SAGEStack(in_channels, hidden, layers, aggr)
        self.node_score = nn.Linear(hidden, 1)
        self.area_score = nn.Linear(hidden, 1)
        self.n_out = n_out

    def area(self, h: torch.Tensor, batch: torch.Tensor) -> torch.Tensor:
        """(B, 1) logit of the packaging area: a linear score of the mean readout G (Eq. 4.3)."""
        return self.area_score(global_mean_pool(h, batch))

    def forward(self, batch) -> torch.Tensor:
        h = self.sage(batch.x, batch.edge_index)
        area = self.area(h, batch.batch)
        products = torch.full((len(area), self.n_out - 1), self.ABSENT, dtype=h.dtype)
        products = products.index_put((batch.batch, batch.product), self.node_score(h).squeeze(-1))
        return torch.cat([area, products], dim=1)


class PointerEncoder(NodeScoreEncoder):
    """A pointer over the product nodes and the packaging area (``reasoning.readout=pointer``, hrc_lab's): each
    node scores itself as the product to pick and, separately, as the one to place; the packaging area's logit is
    the highest placing score of any node. A placing stage is told by the held product's own node, however many
    products the scene holds or has packed (the mean readout of G dilutes it with every other node)."""

    def area(self, h: torch.Tensor, batch: torch.Tensor) -> torch.Tensor:
        return global_max_pool(self.area_score(h), batch)


ENCODERS = {"mean": ChainSAGEEncoder, "node_scores": NodeScoreEncoder, "pointer": PointerEncoder}


class ChainSAGEReasoner(TorchReasoner):
    cfg: ChainSAGEConfig

    def aggregation(self) -> str:
        """The neighbour aggregation of Eq. 4.1: the thesis' mean."""
        return "mean"

    def build_network(self) -> nn.Module:
        encoder = ENCODERS[self.cfg.readout](4, self.cfg.hidden, self.n_o, self.cfg.layers, self.aggregation())
        return TwoStageNet(encoder, StageClassifier(self.n_o, self.n_g, self.cfg.classifier_hidden))

    def encode(self, obs: StageObservation) -> Data:
        return chain_graph(obs, self.spec, self.cfg.edges, self.cfg.position_frame)


class HRCReasoner(ChainSAGEReasoner):
    """``reasoning=hrc``, hrc_lab's reasoning module: the chain-graph GraphSAGE network of ``ours`` with the
    all-earlier edges, the pointer readout (:class:`PointerEncoder`) and the aggregation ``reasoning.aggr``,
    trained on the observations plus ``reasoning.augment_copies`` identity-relabelled copies of each
    (:func:`hrc_lab.reasoning.augment.relabel`; none when ``reasoning.augment`` is false). The same stage
    classifier, loss L_re (Eq. 4.4-4.6) and training schedule as ``ours``."""

    cfg: HRCConfig

    def aggregation(self) -> str:
        return self.cfg.aggr

    def training_observations(self, observations: list[StageObservation]) -> list[StageObservation]:
        if not self.cfg.augment:
            return observations
        return augmented(observations, self.cfg.augment_copies, self.seed)
