"""The scene graph of Ch.6 (Sec. 6.2, Eq. 6.1): one node per detected object, fully linked by directed edges.

A node carries v_i = [f_i, one-hot l_i, g_i]: the detector's box-head feature, the object label and the binary
request flag. The edge j -> i carries the normalised inverse distance between box centres (Eq. 6.1),

    e_ij = (1 / ||d_i - d_j||) / sum_k (1 / ||d_i - d_k||),

so the weights into each node sum to one and near neighbours dominate. Box centres are normalised by the image
size, the unit of GNN_DF_Att's distance filter (0.16).

Each edge also carries the pair's box geometry (:func:`pair_geometry`, ``edge_attr``), which only ★ the relational
convolution (``grasp.conv=relation``, :class:`hrc_lab.grasp.solver.RelationConv`) reads.
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


GEOMETRY_SCALE = 10.0  # image-normalised offsets x this: a part's box (~1/10 of the image side) is about 1
PAIR_GEOMETRY_DIM = 7


def pair_geometry(boxes: np.ndarray, image_size: int) -> np.ndarray:
    """(n(n-1), :data:`PAIR_GEOMETRY_DIM`) geometry of :func:`fully_connected`'s edges j -> i from (n, 4) xyxy px
    boxes: the gaps between the boxes along x and y, each side (j's left edge minus i's right, i's left minus j's
    right, and the same in y; a gap < 0 on both sides of an axis: the boxes overlap along it), the centre offset of j
    from i, in image-normalised units x :data:`GEOMETRY_SCALE`, and the share of i's box that j's covers. Along x the
    gaps are where the rule's fingers close (:mod:`hrc_lab.env.clutter.rule`); an overlap is a part that may rest on
    another."""
    b = np.asarray(boxes, dtype=np.float32).reshape(-1, 4) / image_size
    source, target = np.nonzero(~np.eye(len(b), dtype=bool))
    j, i = b[source], b[target]
    gaps = np.stack([j[:, 0] - i[:, 2], i[:, 0] - j[:, 2], j[:, 1] - i[:, 3], i[:, 1] - j[:, 3]], axis=-1)
    offset = (j @ _CENTRE) - (i @ _CENTRE)
    width = np.clip(np.minimum(i[:, 2], j[:, 2]) - np.maximum(i[:, 0], j[:, 0]), 0, None)
    height = np.clip(np.minimum(i[:, 3], j[:, 3]) - np.maximum(i[:, 1], j[:, 1]), 0, None)
    area = np.maximum((i[:, 2] - i[:, 0]) * (i[:, 3] - i[:, 1]), 1e-9)
    covered = (width * height / area)[:, None]
    return np.hstack([gaps * GEOMETRY_SCALE, offset * GEOMETRY_SCALE, covered]).astype(np.float32)


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
        edge_attr=torch.as_tensor(pair_geometry(boxes, image_size)),
        num_nodes=len(labels),
        **targets,
    )


_CENTRE = np.array([[0.5, 0.0], [0.0, 0.5], [0.5, 0.0], [0.0, 0.5]], dtype=np.float32)  # xyxy -> (cx, cy)
