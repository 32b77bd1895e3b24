"""The labelling rule as a solver (``grasp=rule``, not in the thesis): Algorithm 4 read with the rule's own
graspability and solution of every part an object matches (Sec. 6.3.2's labels, :class:`SceneNodes`' ``rule_*``).

Nothing is learned, so its rows are the ceiling of the learned solvers on the same observations: with ground-truth
boxes (``grasp.detector.mode=oracle``) every single-image answer is right, and Table 6.2's robot row measures the
robot alone (grasp, slip, neighbours moved). An object matched to no part (a false detection) reads as not
graspable, with help as its solution."""

from __future__ import annotations

import pytorch_lightning as pl
import torch
from torch_geometric.data import Data

from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.grasp.iterative import HELP
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.solver import NodeReading


class RuleSolver:
    """Reads each node's graspability and solution off the rule's labels of the part it matches."""

    needs_union_features = False

    def __init__(self, spec, cfg: GraspSolverConfig, classes: tuple[str, ...], seed: int = 0) -> None:
        self.spec, self.cfg, self.classes, self.seed = spec, cfg, tuple(classes), seed

    def graph(self, nodes: SceneNodes, requested, **targets) -> Data:
        """The rule's reading of every node, carried in a graph as the learned solvers' readings are."""
        matched = [int(p) for p in nodes.truth]
        return Data(
            p_grasp=torch.tensor([float(nodes.rule_graspable[p]) if p >= 0 else 0.0 for p in matched]),
            solutions=[list(nodes.rule_solution[p]) if p >= 0 else [HELP] for p in matched],
            num_nodes=len(matched),
        )

    def training_graph(self, nodes: SceneNodes, request: set[str]) -> Data:
        return self.graph(nodes, nodes.requested(request))

    def fit(self, graphs: list[Data], trainer: pl.Trainer) -> None:
        """Nothing to learn."""

    def read(self, graphs: list[Data]) -> list[list[NodeReading]]:
        return [[NodeReading(float(p), words) for p, words in zip(g.p_grasp, g.solutions)] for g in graphs]
