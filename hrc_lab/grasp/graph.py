"""The scene graph of Ch.6 (Sec. 6.2, Eq. 6.1): one node per detected object, fully linked by directed edges.

A node carries v_i = [f_i, one-hot l_i, g_i]: the detector's box-head feature, the object label and the binary
request flag. The edge j -> i carries the normalised inverse distance between box centres (Eq. 6.1),

    e_ij = (1 / ||d_i - d_j||) / sum_k (1 / ||d_i - d_k||),

so the weights into each node sum to one and near neighbours dominate. Box centres are normalised by the image
size, the unit of GNN_DF_Att's distance filter (0.16).
"""

from __future__ import annotations

import numpy as np
import torch
from torch_geometric.data import Data

MIN_DISTANCE = 1e-3  # two boxes with (almost) the same centre: cap the inverse distance


def fully_connected(n: int) -> torch.Tensor:
    """Every directed edge j -> i with j != i, as a (2, n(n-1)) edge index (row 0 source, row 1 target)."""
    source, target = np.nonzero(~np.eye(n, dtype=bool))
    return torch.as_tensor(np.stack([source, target]), dtype=torch.long)


def edge_weights(centres: np.ndarray, mode: str = "inverse_distance", threshold: float = 0.16) -> np.ndarray:
    """Weights of :func:`fully_connected`'s edges from (n, 2) normalised box centres.

    ``inverse_distance``: Eq. 6.1; ``ones``: every weight 1 (GNN_Att w/o WE); ``distance_filter``: 1 for pairs
    closer than ``threshold``, else 0 (GNN_DF_Att)."""
    n = len(centres)
    source, target = np.nonzero(~np.eye(n, dtype=bool))
    distance = np.linalg.norm(centres[source] - centres[target], axis=-1)
    if mode == "ones":
        return np.ones_like(distance, dtype=np.float32)
    if mode == "distance_filter":
        return (distance < threshold).astype(np.float32)
    if mode != "inverse_distance":
        raise ValueError(f"unknown edge mode '{mode}'")
    inverse = 1.0 / np.maximum(distance, MIN_DISTANCE)
    totals = np.zeros(n)
    np.add.at(totals, target, inverse)
    return (inverse / totals[target]).astype(np.float32)


def scene_graph(
    features: torch.Tensor,
    labels: list[str],
    boxes: np.ndarray,
    image_size: int,
    requested: np.ndarray,
    classes: tuple[str, ...],
    mode: str = "inverse_distance",
    threshold: float = 0.16,
    **targets,
) -> Data:
    """The graph of one scene and request: node features [f_i, one-hot l_i over ``classes``, g_i], weighted edges
    (Eq. 6.1).

    ``targets`` are per-node tensors stored on the graph for training (graspability, solution tokens, a mask of the
    nodes that carry labels)."""
    unknown = sorted(set(labels) - set(classes))
    if unknown:
        raise ValueError(f"labels {unknown} are not among the classes {list(classes)}")
    label = torch.tensor([classes.index(t) for t in labels], dtype=torch.long)
    one_hot = torch.nn.functional.one_hot(label, len(classes)).float()
    centres = (np.asarray(boxes, dtype=np.float32).reshape(-1, 4) @ _CENTRE) / image_size
    request = torch.as_tensor(np.asarray(requested, dtype=np.float32)).reshape(-1, 1)
    return Data(
        x=torch.cat([features.float(), one_hot, request], dim=-1),
        label=label,
        edge_index=fully_connected(len(labels)),
        edge_weight=torch.as_tensor(edge_weights(centres, mode, threshold)),
        num_nodes=len(labels),
        **targets,
    )


_CENTRE = np.array([[0.5, 0.0], [0.0, 0.5], [0.5, 0.0], [0.0, 0.5]], dtype=np.float32)  # xyxy -> (cx, cy)
