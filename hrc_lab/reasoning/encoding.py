"""Observation encodings of the reasoning methods: the chain graph of Sec. 4.2.1, the object-goal graph of the GNN
of [74] (Sec. 4.4.1) and the flat vector of the MLP and RF baselines.

Positions enter every encoding in the ``frame`` of :data:`~hrc_lab.reasoning.configs.POSITION_FRAMES` (the torch
reasoners' ``reasoning.position_frame``): by default relative to the centre of the table top and in decimetres,
so that features are O(1); goals are always relative to the box (below), in the frame's unit.

Every encoding also carries ``goals`` (m+1, 3): row 0 is the goal of the product in the gripper (used when P_o
points at the packaging area), row 1+i the goal of product i (zeros if unselected). The two-stage models read the
selected goal g_selected = goals[argmax P_o] from it (teacher-forced with the label in training).

Goals are expressed in x-y relative to the centre of the box's slots (z above the table, so no goal is all zeros):
a position-specified label names "a specific goal
position ... demonstrated by the predefined goal configuration" (4.2.1), i.e. a place in the box, and the box moves
between episodes when goal positions vary (``env.box_jitter``, 4.4.3). In table coordinates the slot could not be
told from g_selected once the box moves by more than the slot spacing (Table 4.3 with a jitter of 0.1 m and 0.08 m
slots: 42-50 % of closed-loop trials failed on the placing stage's P_g); with a fixed box the two are the same
information.
"""

from __future__ import annotations

import numpy as np
import torch
from torch_geometric.data import Data

from hrc_lab.env.robot.spec import PackageToOrderSpec, StageObservation
from hrc_lab.reasoning.configs import CHAIN_EDGES, DEFAULT_POSITION_FRAME, POSITION_FRAMES


def scaled(positions: np.ndarray, spec: PackageToOrderSpec, frame: str = DEFAULT_POSITION_FRAME) -> np.ndarray:
    """World positions (metres) in ``frame``."""
    origin, scale = POSITION_FRAMES[frame]
    return (positions - np.array([0.0, 0.0, spec.table_z if origin == "table" else 0.0])) * scale


def goal_table(obs: StageObservation, spec: PackageToOrderSpec, frame: str = DEFAULT_POSITION_FRAME) -> np.ndarray:
    """(m+1, 3) scaled goal positions, x-y relative to the centre of the box's slots, indexed like P_o (see module
    docstring); zeros where there is no goal."""
    m = spec.n_objects
    goals = np.zeros((m + 1, 3))
    goals[0] = obs.goal_of(obs.held)
    for product in range(m):
        goals[1 + product] = obs.goal_of(product)
    nonzero = np.any(goals != 0, axis=1)
    goals[nonzero] = (goals[nonzero] - [*box_centre(obs), spec.table_z]) * POSITION_FRAMES[frame][1]
    return goals


def box_centre(obs: StageObservation) -> np.ndarray:
    """(2,) x-y of the centre of the box's slots, in metres: the origin of every goal position in x-y."""
    return obs.slot_positions[:, :2].mean(axis=0)


def task_labels(obs: StageObservation) -> tuple[int, int]:
    """Position-specified labels of the thesis: P_o with the packaging area at placing, P_g with the goal slot."""
    return obs.o_label, obs.g_label


def order_labels(obs: StageObservation) -> tuple[int, int]:
    """Labels of the GNN of [74]: the handled product at both stages and the goal's rank in the packing order."""
    return 1 + obs.target, 1 + obs.order


def _common(obs: StageObservation, spec: PackageToOrderSpec, labels: tuple[int, int], frame: str) -> dict:
    return dict(
        o_label=torch.tensor([labels[0]]),
        g_label=torch.tensor([labels[1]]),
        goals=torch.tensor(goal_table(obs, spec, frame), dtype=torch.float32).unsqueeze(0),
    )


def chain_edges(n: int, edges: str = "chain") -> np.ndarray:
    """(2, E) directed edges between n nodes in product order: "chain" links node i to node i+1 (Sec. 4.2.1),
    "bidirectional" adds i+1 -> i, "all_earlier" links every node i to every later node j > i."""
    if edges == "all_earlier":
        src, dst = np.triu_indices(n, k=1)
        return np.stack([src, dst])
    src = np.arange(n - 1)
    links = [np.stack([src, src + 1])]
    if edges == "bidirectional":
        links.append(np.stack([src + 1, src]))
    elif edges not in CHAIN_EDGES:
        raise ValueError(f"edges must be one of {CHAIN_EDGES}, got {edges!r}")
    return np.concatenate(links, axis=1)


def chain_graph(obs: StageObservation, spec: PackageToOrderSpec, edges: str = "chain",
                frame: str = DEFAULT_POSITION_FRAME) -> Data:
    """Sec. 4.2.1: one node per present product in product order with features (x, y, z, I), linked by
    :func:`chain_edges`. Absent products (4.4.5) simply have no node."""
    present = np.flatnonzero(obs.present)
    x = np.column_stack([scaled(obs.positions[present], spec, frame), obs.selected[present]])
    edge_index = torch.tensor(chain_edges(len(present), edges), dtype=torch.long)
    return Data(
        x=torch.tensor(x, dtype=torch.float32),
        edge_index=edge_index,
        product=torch.tensor(present),
        **_common(obs, spec, task_labels(obs), frame),
    )


def object_goal_graph(obs: StageObservation, spec: PackageToOrderSpec, label_scheme: str,
                      frame: str = DEFAULT_POSITION_FRAME) -> Data:
    """The graph of [74] as described in 4.4.1: fully connected object and goal nodes with features
    (x, y, z, is_goal, type one-hot over the m products, fulfilled, I). A goal node exists for every selected
    product, at its assigned slot, and carries that product's type; "fulfilled" marks a packed product / filled goal.

    Goal nodes sit relative to the box in x-y, as every method's goals (:func:`goal_table`): a position-specified label
    names a place in the box (4.2.1), which GNN-task is trained on (4.4.1). At table coordinates, with the box moving
    more than a slot spacing (``env.box_jitter``), GNN-task could not fit P_g at placing (issue 45)."""
    m = spec.n_objects
    box = np.array([*box_centre(obs), 0.0]) * POSITION_FRAMES[frame][1]
    rows = []
    for product in np.flatnonzero(obs.present):
        kind = np.eye(m)[product]
        rows.append([*scaled(obs.positions[product], spec, frame), 0.0, *kind, obs.packed[product],
                     obs.selected[product]])
    for product in np.flatnonzero(obs.selected):
        kind = np.eye(m)[product]
        goal = scaled(obs.goal_of(product), spec, frame) - box
        rows.append([*goal, 1.0, *kind, obs.packed[product], 1.0])
    n = len(rows)
    src, dst = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    off_diagonal = src != dst
    edge_index = torch.tensor(np.stack([src[off_diagonal], dst[off_diagonal]]), dtype=torch.long)
    labels = order_labels(obs) if label_scheme == "order" else task_labels(obs)
    return Data(x=torch.tensor(rows, dtype=torch.float32), edge_index=edge_index,
                **_common(obs, spec, labels, frame))


def flat_vector(obs: StageObservation, spec: PackageToOrderSpec, frame: str = DEFAULT_POSITION_FRAME) -> np.ndarray:
    """(4m,) the chain graph's node features side by side. Needs every product present: a flat input has a fixed
    size, which is why the thesis runs the missing-products scenario with graph methods only."""
    if not obs.present.all():
        raise ValueError("flat observations need every product present (missing products change the input size)")
    return np.column_stack([scaled(obs.positions, spec, frame), obs.selected]).reshape(-1)


def flat_data(obs: StageObservation, spec: PackageToOrderSpec, frame: str = DEFAULT_POSITION_FRAME) -> Data:
    """The flat vector wrapped as a one-row graph-level sample, so every torch method shares one data loader."""
    x_flat = torch.tensor(flat_vector(obs, spec, frame), dtype=torch.float32).unsqueeze(0)
    return Data(x_flat=x_flat, num_nodes=1, **_common(obs, spec, task_labels(obs), frame))
