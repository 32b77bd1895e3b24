"""``grasp=gvmrn_rf``: the relationship-reasoning baseline of 6.4.1 (GVMRN with a Relation Filter, refs. [121, 122]).

Instead of one node per object, GVMRN classifies the relation of object pairs. A Relation Filter keeps the ordered
pairs (i, j) whose boxes intersect or whose normalised centre distance is below ``distance_filter``; each kept pair
is a relation node with the detector feature of the union box of the two objects, both labels, the request flag of
i and the offset between the box centres. Relation nodes that share an object are linked, and ``layers`` GCNConv
layers classify each into "none", "above" (j has to go before i can be grasped), "under" (i has to go before j)
or "help" (i and j are parts of one type in each other's way), with cross-entropy on the relation nodes of the
requested objects only, as in the thesis' comparison.

The method does not decode text: the grasp solution of a requested object i is read off its relations, so it can be
scored like the others (6.4.1 assesses its relation predictions): help if any relation (i, j) is "help", else "move"
the types of the objects predicted "above" i, else graspable.

:class:`PairSolver` is the part GVMRN_RF shares with VMRN (``grasp=vmrn``, :mod:`hrc_lab.grasp.vmrn`): object pairs
as the units of classification, their features read from the detector's features of the objects and of the pair's
union box (``scene_nodes(..., union_features=True)``), one graph per image whose nodes are pairs, cross-entropy on
the labelled pairs (:func:`relation_objective`), and each object's solution read off its predicted relations.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from itertools import permutations

import lightning.pytorch as pl
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from torch_geometric.data import Data
from torch_geometric.nn import GCNConv

from hrc_lab.env.clutter.rule import move_tokens
from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.solver import NodeReading, labelled_nodes
from hrc_lab.training import FixedStepDataModule, SupervisedModule, steps_per_epoch

RELATIONS = ("none", "above", "under", "help")


def box_intersection(a: np.ndarray, b: np.ndarray) -> float:
    width = min(a[2], b[2]) - max(a[0], b[0])
    height = min(a[3], b[3]) - max(a[1], b[1])
    return max(0.0, width) * max(0.0, height)


def relation_filter(nodes: SceneNodes, threshold: float) -> list[tuple[int, int]]:
    """Ordered pairs (i, j) whose boxes intersect or lie closer than ``threshold`` (normalised centre distance)."""
    centres = (nodes.boxes[:, :2] + nodes.boxes[:, 2:]) / 2 / nodes.image_size
    return [
        (i, j)
        for i, j in permutations(range(len(nodes.labels)), 2)
        if box_intersection(nodes.boxes[i], nodes.boxes[j]) > 0 or np.linalg.norm(centres[i] - centres[j]) < threshold
    ]


def relation_label(nodes: SceneNodes, i: int, j: int) -> int:
    """The rule's relation of the parts behind objects i and j (-1 when either is a false detection)."""
    pi, pj = int(nodes.truth[i]), int(nodes.truth[j])
    if pi < 0 or pj < 0:
        return -1
    j_blocks_i, i_blocks_j = pj in nodes.rule_blockers[pi], pi in nodes.rule_blockers[pj]
    if (j_blocks_i or i_blocks_j) and nodes.scene.objects[pi].type == nodes.scene.objects[pj].type:
        return RELATIONS.index("help")
    if j_blocks_i:
        return RELATIONS.index("above")
    if i_blocks_j:
        return RELATIONS.index("under")
    return RELATIONS.index("none")


class RelationNet(nn.Module):
    def __init__(self, in_dim: int, cfg: GraspSolverConfig) -> None:
        super().__init__()
        self.input = nn.Sequential(nn.LayerNorm(in_dim), nn.Linear(in_dim, cfg.hidden), nn.ReLU())
        self.convs = nn.ModuleList(GCNConv(cfg.hidden, cfg.hidden) for _ in range(cfg.layers))
        self.head = nn.Linear(cfg.hidden, len(RELATIONS))

    def forward(self, batch) -> torch.Tensor:
        h = self.input(batch.x)
        for conv in self.convs:
            h = F.relu(conv(h, batch.edge_index))
        return self.head(h)


def relation_objective(network: nn.Module, batch) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Cross-entropy of the relation classes on the labelled relation nodes."""
    mask = batch.labelled
    return F.cross_entropy(network(batch)[mask], batch.relation[mask]), {}


class RelationModule(SupervisedModule):
    """:func:`relation_objective` with Adam and ``grasp.schedule`` (GVMRN_RF's and VMRN's networks); logs
    ``train_loss`` per epoch, averaged over labelled nodes."""

    def __init__(self, network: nn.Module, cfg: GraspSolverConfig) -> None:
        super().__init__(network, relation_objective, cfg.lr, batch_size=labelled_nodes, schedule=cfg.schedule,
                         warmup_steps=cfg.warmup_steps)


class PairSolver(ABC):
    """Object pairs as the units of classification, behind the solver interface of
    :class:`hrc_lab.grasp.solver.GraspSolver`. A method names which ordered pairs it classifies (:meth:`pairs`),
    their features (:meth:`pair_features`) and links (:meth:`links`), a pair's label and whether it trains
    (:meth:`pair_label`, :meth:`trains_on`), its network (:meth:`build_network`: relation logits per pair node)
    and how each object's graspability and solution are read off the predicted relations (:meth:`readings`)."""

    needs_union_features = True

    def __init__(self, spec, cfg: GraspSolverConfig, classes: tuple[str, ...], seed: int = 0) -> None:
        self.spec, self.cfg, self.classes, self.seed = spec, cfg, tuple(classes), seed
        self.network: nn.Module | None = None

    @abstractmethod
    def pairs(self, nodes: SceneNodes) -> list[tuple[int, int]]:
        """The ordered object pairs (i, j) classified in this image: the graph's nodes, in order."""

    @abstractmethod
    def pair_features(self, nodes: SceneNodes, requested: np.ndarray, pairs: list[tuple[int, int]]) -> torch.Tensor:
        """(len(pairs), feature_dim) node features, also for no pair."""

    @abstractmethod
    def links(self, pairs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Directed edges (a, b) between pair nodes (indices into ``pairs``)."""

    @abstractmethod
    def pair_label(self, nodes: SceneNodes, i: int, j: int) -> int:
        """The relation class of pair (i, j), -1 when either object is a false detection (no loss)."""

    @abstractmethod
    def trains_on(self, requested: np.ndarray, i: int, j: int) -> bool:
        """Whether pair (i, j) carries a loss, given the request flags of the objects."""

    @abstractmethod
    def build_network(self, feature_dim: int) -> nn.Module:
        """The network: ``network(batch)`` -> (pair nodes, relations) logits."""

    @abstractmethod
    def readings(self, graph: Data, predicted: list[int]) -> list[NodeReading]:
        """Per object of the image, its graspability and solution from the predicted relation of each pair."""

    def graph(self, nodes: SceneNodes, requested: np.ndarray, **targets) -> Data:
        pairs = self.pairs(nodes)
        return Data(
            x=self.pair_features(nodes, requested, pairs),
            edge_index=torch.tensor(self.links(pairs), dtype=torch.long).reshape(-1, 2).T,
            pair=torch.tensor(pairs, dtype=torch.long).reshape(-1, 2),
            n_objects=len(nodes.labels),
            object_labels=list(nodes.labels),
            num_nodes=len(pairs),
            **targets,
        )

    def training_graph(self, nodes: SceneNodes, request: set[str]) -> Data:
        """Labels on the pairs :meth:`trains_on` keeps whose objects are both matched to parts."""
        requested = nodes.requested(request)
        pairs = self.pairs(nodes)
        labels = torch.tensor([self.pair_label(nodes, i, j) for i, j in pairs], dtype=torch.long)
        trained = torch.tensor([self.trains_on(requested, i, j) for i, j in pairs], dtype=torch.bool)
        return self.graph(nodes, requested, relation=labels.clamp(min=0), labelled=trained & (labels >= 0))

    def fit(self, graphs: list[Data], trainer: pl.Trainer) -> None:
        graphs = [g for g in graphs if bool(g.labelled.any())]
        if not graphs:
            raise ValueError("no training relations")
        torch.manual_seed(self.seed)
        self.network = self.build_network(graphs[0].x.shape[1])
        data = FixedStepDataModule(graphs, self.cfg.batch_size, steps_per_epoch(self.cfg.steps, trainer))
        trainer.fit(RelationModule(self.network, self.cfg), datamodule=data)

    @torch.no_grad()
    def read(self, graphs: list[Data]) -> list[list[NodeReading]]:
        """Per graph, per object: its reading from the argmax relation of every pair."""
        if self.network is None:
            raise RuntimeError(f"{type(self).__name__}.read before fit")
        self.network.eval()
        return [self.readings(graph, self.network(graph).argmax(-1).tolist() if graph.num_nodes else [])
                for graph in graphs]


class RelationSolver(PairSolver):
    """GVMRN_RF: the Relation Filter's pairs, union-box rows, relation nodes linked when they share an object,
    GCNConv layers; trained on the relations of the requested objects."""

    def pairs(self, nodes: SceneNodes) -> list[tuple[int, int]]:
        return relation_filter(nodes, self.cfg.distance_filter)

    def pair_features(self, nodes: SceneNodes, requested: np.ndarray, pairs: list[tuple[int, int]]) -> torch.Tensor:
        """[union-box f, one-hot l_i, one-hot l_j, g_i, centre offset d_j - d_i] per pair."""
        one_hot = torch.eye(len(self.classes))
        centres = torch.as_tensor((nodes.boxes[:, :2] + nodes.boxes[:, 2:]) / 2 / nodes.image_size)
        rows = [
            torch.cat(
                [
                    nodes.union_features[(min(i, j), max(i, j))].float(),
                    one_hot[self.classes.index(nodes.labels[i])],
                    one_hot[self.classes.index(nodes.labels[j])],
                    torch.tensor([float(requested[i])]),
                    (centres[j] - centres[i]).float(),
                ]
            )
            for i, j in pairs
        ]
        feature_dim = self.cfg.detector.representation_size + 2 * len(self.classes) + 3  # union-box f only
        return torch.stack(rows) if rows else torch.zeros(0, feature_dim)

    def links(self, pairs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        return [(a, b) for a, pa in enumerate(pairs) for b, pb in enumerate(pairs) if a != b and set(pa) & set(pb)]

    def pair_label(self, nodes: SceneNodes, i: int, j: int) -> int:
        return relation_label(nodes, i, j)

    def trains_on(self, requested: np.ndarray, i: int, j: int) -> bool:
        return bool(requested[i])

    def build_network(self, feature_dim: int) -> nn.Module:
        return RelationNet(feature_dim, self.cfg)

    def readings(self, graph: Data, predicted: list[int]) -> list[NodeReading]:
        """Graspable unless a relation puts something above the object; the solution from those relations."""
        above: dict[int, set[str]] = {i: set() for i in range(graph.n_objects)}
        helps: set[int] = set()
        for (i, j), relation in zip(graph.pair.tolist(), predicted):
            if RELATIONS[relation] == "help":
                helps.add(i)
            elif RELATIONS[relation] == "above":
                above[i].add(graph.object_labels[j])
        nodes = []
        for i in range(graph.n_objects):
            if i in helps:
                nodes.append(NodeReading(0.0, ["help"]))
            elif above[i]:
                nodes.append(NodeReading(0.0, move_tokens(above[i])))
            else:
                nodes.append(NodeReading(1.0, ["grasp"]))
        return nodes
