"""``grasp=vmrn``: the Visual Manipulation Relationship Network baseline of Table 6.3 (thesis 6.4.2, ref. [153]:
Zhang et al., "Visual manipulation relationship recognition in object-stacking scenes", 2020).

VMRN classifies the manipulation relationship of every ordered pair (i, j) of detected objects from the detector's
features (its Object Pairing Pooling Layer takes the features of object i, of object j and of their union box) into
three classes: i is the *parent* of j (j lies on i: j has to go first), i is the *child* of j, or *none*. No pair is
filtered out (GVMRN_RF's Relation Filter), no pairs are linked (no graph convolution): each pair is classified on its
own. Here the three features are those every Ch.6 method reads, the detector's box-head vectors f_i, f_j and the
union box's (the same path as GVMRN_RF, :class:`hrc_lab.grasp.relation.PairSolver`); VMRN's convolutional layers on
7x7 RoI maps become one fully connected stream per input,

    z = W_c [ReLU(W_s f_i), ReLU(W_o f_j), ReLU(W_u f_union)],

followed by ``grasp.layers`` fully connected ReLU layers of ``grasp.hidden`` units and a 3-way head, trained with
cross-entropy on every pair whose two objects are matched to parts (VMRN has no request input: it learns every
relation of its training images).

Reading (the manipulation relationship tree): j is a child of i when (i, j) is predicted parent or (j, i) child. An
object without children is graspable; otherwise its solution is read from its children's labels the way the
labelling rule reads blockers (:func:`hrc_lab.env.clutter.rule.type_solution`): help when a child has its own type,
else "move" their types. When two parts block each other (the rule allows it, a tree does not) both orders are
labelled parent.
"""

from __future__ import annotations

from itertools import permutations

import numpy as np
import torch
from torch import nn
from torch_geometric.data import Data

from hrc_lab.env.clutter.rule import type_solution
from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.relation import PairSolver
from hrc_lab.grasp.solver import NodeReading

VMRN_RELATIONS = ("parent", "child", "none")  # of the ordered pair (i, j): i is j's parent / child / neither


class VmrnNet(nn.Module):
    """The pair classifier: one stream per input (f_i, f_j, f_union), concatenated, ``cfg.layers`` hidden layers and
    the relation head.

    Shapes: ``batch.x`` (pairs, 2 * object_dim + union_dim) -> logits (pairs, 3)."""

    def __init__(self, object_dim: int, union_dim: int, cfg: GraspSolverConfig) -> None:
        super().__init__()
        self.split = [object_dim, object_dim, union_dim]

        def stream(dim: int) -> nn.Module:
            return nn.Sequential(nn.LayerNorm(dim), nn.Linear(dim, cfg.hidden), nn.ReLU())

        self.streams = nn.ModuleList(stream(dim) for dim in self.split)
        hidden, width = [], 3 * cfg.hidden
        for _ in range(cfg.layers):
            hidden += [nn.Linear(width, cfg.hidden), nn.ReLU()]
            width = cfg.hidden
        self.classifier = nn.Sequential(*hidden, nn.Linear(width, len(VMRN_RELATIONS)))

    def forward(self, batch) -> torch.Tensor:
        parts = batch.x.split(self.split, dim=-1)
        return self.classifier(torch.cat([stream(x) for stream, x in zip(self.streams, parts)], dim=-1))


def vmrn_label(nodes: SceneNodes, i: int, j: int) -> int:
    """Parent when part j is among part i's blockers (its children), child when i is among j's, else none; -1 when
    either object is a false detection."""
    pi, pj = int(nodes.truth[i]), int(nodes.truth[j])
    if pi < 0 or pj < 0:
        return -1
    if pj in nodes.rule_blockers[pi]:
        return VMRN_RELATIONS.index("parent")
    if pi in nodes.rule_blockers[pj]:
        return VMRN_RELATIONS.index("child")
    return VMRN_RELATIONS.index("none")


class VmrnSolver(PairSolver):
    """VMRN behind the solver interface: every ordered pair, [f_i, f_j, f_union] rows, no links."""

    def pairs(self, nodes: SceneNodes) -> list[tuple[int, int]]:
        return list(permutations(range(len(nodes.labels)), 2))

    def pair_features(self, nodes: SceneNodes, requested: np.ndarray, pairs: list[tuple[int, int]]) -> torch.Tensor:
        """[f_i, f_j, f_union(i, j)] per pair (the request flags are not VMRN's input)."""
        rows = [torch.cat([nodes.features[i], nodes.features[j], nodes.union_features[(min(i, j), max(i, j))]])
                for i, j in pairs]
        feature_dim = 2 * nodes.features.shape[1] + self.cfg.detector.representation_size
        return torch.stack(rows).float() if rows else torch.zeros(0, feature_dim)

    def links(self, pairs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        return []

    def pair_label(self, nodes: SceneNodes, i: int, j: int) -> int:
        return vmrn_label(nodes, i, j)

    def trains_on(self, requested: np.ndarray, i: int, j: int) -> bool:
        return True

    def build_network(self, feature_dim: int) -> nn.Module:
        union_dim = self.cfg.detector.representation_size
        object_dim, odd = divmod(feature_dim - union_dim, 2)
        if odd or object_dim <= 0:
            raise ValueError(f"VMRN rows of {feature_dim} features are not [f_i, f_j, f_union] with a "
                             f"{union_dim}-d union feature (grasp.detector.representation_size)")
        return VmrnNet(object_dim, union_dim, self.cfg)

    def readings(self, graph: Data, predicted: list[int]) -> list[NodeReading]:
        children: list[set[int]] = [set() for _ in range(graph.n_objects)]
        for (i, j), relation in zip(graph.pair.tolist(), predicted):
            if VMRN_RELATIONS[relation] == "parent":
                children[i].add(j)
            elif VMRN_RELATIONS[relation] == "child":
                children[j].add(i)
        labels = graph.object_labels
        return [NodeReading(0.0 if kids else 1.0, type_solution(labels[i], [labels[j] for j in kids]))
                for i, kids in enumerate(children)]
