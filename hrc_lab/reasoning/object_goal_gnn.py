"""``reasoning=gnn`` and ``reasoning=gnn_task``: the GNN high-level policy of [74] as described in Sec. 4.4.1.

A fully connected graph of object and goal nodes (type, fulfilment and selection features, see
:func:`hrc_lab.reasoning.encoding.object_goal_graph`) passes through GraphSAGE layers; a mean readout feeds two
heads that give P_o and P_g directly, with no stage classifier.

- ``gnn`` is trained and scored on [74]'s own labels: the product to handle at both stages and the goal's rank in
  the packing order (it cannot tell goal positions apart).
- ``gnn_task`` is the same network trained on the thesis' position-specified labels.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch_geometric.data import Data
from torch_geometric.nn import global_mean_pool

from hrc_lab.env.robot.spec import StageObservation
from hrc_lab.reasoning.base import TorchReasoner
from hrc_lab.reasoning.chain_sage import SAGEStack
from hrc_lab.reasoning.configs import ObjectGoalGNNConfig
from hrc_lab.reasoning.encoding import object_goal_graph, order_labels, task_labels


class ObjectGoalGNN(nn.Module):
    def __init__(self, in_channels: int, hidden: int, n_o: int, n_g: int, layers: int = 3) -> None:
        super().__init__()
        self.sage = SAGEStack(in_channels, hidden, layers)
        self.head_o = nn.Linear(hidden, n_o)
        self.head_g = nn.Linear(hidden, n_g)

    def forward(self, batch, teacher_forcing: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        graph = global_mean_pool(self.sage(batch.x, batch.edge_index), batch.batch)
        return self.head_o(graph), self.head_g(graph)


class ObjectGoalGNNReasoner(TorchReasoner):
    cfg: ObjectGoalGNNConfig

    def build_network(self) -> nn.Module:
        in_channels = 3 + 1 + self.spec.n_objects + 2
        return ObjectGoalGNN(in_channels, self.cfg.hidden, self.n_o, self.n_g, self.cfg.layers)

    def encode(self, obs: StageObservation) -> Data:
        return object_goal_graph(obs, self.spec, self.cfg.label_scheme, self.cfg.position_frame)

    def labels(self, observations: list[StageObservation]) -> np.ndarray:
        scheme = order_labels if self.cfg.label_scheme == "order" else task_labels
        return np.array([scheme(o) for o in observations])
