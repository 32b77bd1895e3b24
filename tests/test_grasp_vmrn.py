"""VMRN, Table 6.3's pair classifier (thesis 6.4.2, hrc_lab/grasp/vmrn.py): every ordered pair, [f_i, f_j, f_union]
rows, parent / child / none labels from the blockers, the (pairs, 3) logits, a toy relation it must learn, and the
solutions read off its predicted children."""

import numpy as np
import pytest
import torch
from torch_geometric.loader import DataLoader

from hrc_lab.env.clutter.spec import PART_TYPES, ClutterObject, ClutterScene
from hrc_lab.grasp import GRASPS
from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.relation import RelationModule
from hrc_lab.grasp.vmrn import VMRN_RELATIONS, VmrnSolver

DIM = 4  # f_i and union-box features of the hand-made scenes


def stacked(types: list[str], heights: list[float]) -> SceneNodes:
    """:func:`scene_nodes_of` where every higher object lies on every lower one (the blockers of i: the objects
    higher than i)."""
    return scene_nodes_of(types, heights, [[j for j, h in enumerate(heights) if h > hi] for hi in heights])


def scene_nodes_of(types: list[str], heights: list[float], blockers: list[list[int]]) -> SceneNodes:
    """Objects side by side whose feature is [height, 1, 0, 0]; union features all zero (oracle boxes)."""
    boxes = np.array([[10 * k, 0, 10 * k + 8, 8] for k in range(len(types))], dtype=np.float32)
    objects = [ClutterObject(t, np.zeros(3), np.array([1.0, 0, 0, 0]), b) for t, b in zip(types, boxes)]
    scene = ClutterScene(0, np.zeros((64, 64, 3), np.uint8), objects, -np.ones((64, 64), int))
    features = torch.tensor([[h, 1.0, 0.0, 0.0] for h in heights])
    return SceneNodes(scene=scene, boxes=boxes, labels=list(types), features=features, truth=np.arange(len(types)),
                      rule_graspable=np.array([not b for b in blockers]), rule_solution=[["grasp"]] * len(types),
                      rule_blockers=blockers,
                      union_features={(i, j): torch.zeros(DIM) for i in range(len(types))
                                      for j in range(i + 1, len(types))})


def solver() -> VmrnSolver:
    cfg = GraspSolverConfig(hidden=32, layers=2, lr=1e-2, schedule="constant")
    cfg.detector.representation_size = DIM
    return VmrnSolver(None, cfg, PART_TYPES, seed=0)


def test_vmrn_is_a_grasp_choice_that_classifies_every_ordered_pair():
    assert GRASPS.load("vmrn") is VmrnSolver
    vmrn = solver()
    nodes = scene_nodes_of(["a", "b", "c"], [0, 1, 0], [[1], [], []])  # b lies on a
    graph = vmrn.training_graph(nodes, {"c"})
    assert graph.pair.tolist() == [[0, 1], [0, 2], [1, 0], [1, 2], [2, 0], [2, 1]]
    assert graph.x.shape == (6, 3 * DIM) and graph.edge_index.shape == (2, 0)  # [f_i, f_j, f_union], no links
    assert graph.x[0, :DIM].tolist() == [0, 1, 0, 0] and graph.x[0, DIM:2 * DIM].tolist() == [1, 1, 0, 0]
    assert [VMRN_RELATIONS[r] for r in graph.relation] == ["parent", "none", "child", "none", "none", "none"]
    assert graph.labelled.all()  # every relation trains, whatever was requested (VMRN has no request input)
    logits = vmrn.build_network(3 * DIM)(graph)
    assert logits.shape == (6, len(VMRN_RELATIONS))
    with pytest.raises(ValueError, match="not \\[f_i, f_j, f_union\\]"):
        vmrn.build_network(3 * DIM + 1)
    nodes.truth = np.array([0, -1, 2])  # b is a false detection: its pairs carry no loss
    assert vmrn.training_graph(nodes, {"a"}).labelled.tolist() == [False, True, False, False, True, False]
    assert vmrn.graph(scene_nodes_of(["a"], [0], [[]]), np.array([True])).x.shape == (0, 3 * DIM)


def test_vmrn_learns_a_toy_relation_and_reads_solutions_off_the_children():
    """The higher object of a pair lies on the lower one (parent: j higher than i), equal heights are unrelated:
    separable from [f_i, f_j] alone. After training, the readings follow the rule's words."""
    vmrn = solver()
    heights = ([0, 1, 2], [0, 0, 1], [2, 1, 0], [1, 1, 2], [2, 2, 0], [1, 0, 1])
    train = [stacked(["c", "a", "b"], h) for h in heights]
    graphs = [vmrn.training_graph(n, set()) for n in train]
    torch.manual_seed(0)
    vmrn.network = vmrn.build_network(graphs[0].x.shape[1])
    module = RelationModule(vmrn.network, vmrn.cfg)
    module.log_dict = module.log = lambda *a, **k: None
    optimiser = module.configure_optimizers()
    batch = next(iter(DataLoader(graphs, batch_size=len(graphs))))
    for _ in range(200):
        optimiser.zero_grad()
        module.training_step(batch, 0).backward()
        optimiser.step()
    predicted = vmrn.network(batch).argmax(-1)
    assert torch.equal(predicted, batch.relation)
    test = [stacked(["a", "b", "c"], [0, 1, 2]), stacked(["a", "a", "c"], [0, 1, 1])]  # labels unseen in train
    readings = vmrn.read([vmrn.graph(n, np.ones(3, bool)) for n in test])
    assert [r.solution for r in readings[0]] == [["move", "b", "and", "c"], ["move", "c"], ["grasp"]]
    assert [r.graspable for r in readings[0]] == [False, False, True]
    assert [r.solution for r in readings[1]] == [["help"], ["grasp"], ["grasp"]]  # an a lies on the first a
