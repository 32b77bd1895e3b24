"""Measurements that explain the Ch.6 results rather than score them (issue 20).

- :func:`scene_geometry`: how dense the scenes are in the units of Eq. 6.1 and of GNN_DF_Att's distance filter
  (image-normalised box-centre distance, 0.16): the distance of every part pair, and of the pairs the labelling rule
  links (a blocker and the part it blocks), the neighbours each part has within the filter, and the Eq. 6.1 weight a
  blocker receives: which share of the edges a solution depends on the filter keeps, and how much more weight Eq. 6.1
  gives them than an unweighted mean would.
- :func:`failure_cause`: why one Algorithm 4 answer on a single image is wrong (Table 6.2), in the order the
  pipeline meets them: a detection error on a part the answer depends on, a wrong graspability at a request, a
  decoded solution that differs from the rule's, or none of these (the nearest-part resolution or the iteration
  limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrc_lab.grasp.graph import edge_weights
from hrc_lab.grasp.iterative import IterativeAnswer
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.solver import NodeReading

FAILURE_CAUSES = ("detection", "graspability", "solution", "other")
# Algorithm 4 with the robot (hrc_lab.grasp.robot_grasping): the single-image causes, then the robot's own
ROBOT_FAILURES = (*FAILURE_CAUSES, "slip", "collision", "iteration_bound")
GEOMETRY_METRICS = ("geometry_pair_distance_median", "geometry_pairs_within_filter",
                    "geometry_blocker_distance_median", "geometry_blocker_distance_max",
                    "geometry_blockers_within_filter", "geometry_neighbours_within_filter",
                    "geometry_blocker_weight_ratio")


@dataclass
class SceneGeometry:
    """Per pair of parts (both orders): normalised centre distance and whether the rule links them; per part: the
    number of other parts within the distance filter."""

    pair_distance: np.ndarray
    pair_blocks: np.ndarray  # bool: one part of the pair blocks the other
    blocker_weight: np.ndarray  # Eq. 6.1 weight of the edge blocker -> blocked part
    uniform_weight: np.ndarray  # 1 / (n - 1) of that part's scene: what an unweighted mean would give it
    neighbours: np.ndarray

    def metrics(self, threshold: float) -> dict[str, float]:
        """``geometry_*`` metrics; NaN when the scenes have no pair of parts (or no blocker)."""
        blocks = self.pair_distance[self.pair_blocks]
        if not self.pair_distance.size:
            return dict.fromkeys(GEOMETRY_METRICS, float("nan"))
        return {
            "geometry_pair_distance_median": float(np.median(self.pair_distance)),
            "geometry_pairs_within_filter": float(np.mean(self.pair_distance < threshold)),
            "geometry_blocker_distance_median": float(np.median(blocks)) if blocks.size else float("nan"),
            "geometry_blocker_distance_max": float(np.max(blocks)) if blocks.size else float("nan"),
            "geometry_blockers_within_filter": float(np.mean(blocks < threshold)) if blocks.size else float("nan"),
            "geometry_neighbours_within_filter": float(np.mean(self.neighbours)),
            "geometry_blocker_weight_ratio": float(np.mean(self.blocker_weight / self.uniform_weight))
            if self.blocker_weight.size else float("nan"),
        }


def scene_geometry(nodes: list[SceneNodes], threshold: float) -> SceneGeometry:
    """The geometry of the scenes' ground-truth parts (the scenes, not the detector: Fig. 6.3's quantities)."""
    distance, blocks, weight, uniform, neighbours = [], [], [], [], []
    for n in nodes:
        boxes = n.scene.boxes
        count = len(boxes)
        if count < 2:
            continue
        centres = (boxes[:, :2] + boxes[:, 2:]) / 2 / n.image_size
        source, target = np.nonzero(~np.eye(count, dtype=bool))  # the edge order of graph.fully_connected
        pair = np.linalg.norm(centres[source] - centres[target], axis=-1)
        linked = np.array([s in n.rule_blockers[t] for s, t in zip(source, target)], dtype=bool)
        weights = edge_weights(centres, "inverse_distance")
        distance.append(pair)
        blocks.append(linked)
        weight.append(weights[linked])
        uniform.append(np.full(int(linked.sum()), 1.0 / (count - 1)))
        neighbours.append(np.bincount(target[pair < threshold], minlength=count))
    if not distance:
        empty = np.zeros(0)
        return SceneGeometry(empty, empty.astype(bool), empty, empty, empty)
    return SceneGeometry(*(np.concatenate(v) for v in (distance, blocks, weight, uniform, neighbours)))


def failure_cause(
    nodes: SceneNodes, goal_type: str, answer: IterativeAnswer, readings: list[list[NodeReading]]
) -> str:
    """The first of :data:`FAILURE_CAUSES` that explains a wrong answer. ``readings``: the solver's reading of every
    node at each request of ``answer`` (in order).

    - ``detection``: a part of the goal's type, or a part the rule's iteration from it passes through, is not
      detected, or a detection of the goal's type matches no part;
    - ``graspability``: at some request the solver's graspability of a requested part differs from the rule's;
    - ``solution``: at some request the decoded solution of the chosen part differs from the rule's;
    - ``other``: every step agrees with the rule (the nearest-part resolution chose another part than the rule's
      iteration would, or the iteration limit ended the answer)."""
    goals = [i for i, t in enumerate(nodes.scene.types) if t == goal_type]
    relevant, frontier = set(goals), list(goals)
    while frontier:
        for part in nodes.rule_blockers[frontier.pop()]:
            if part not in relevant:
                relevant.add(part)
                frontier.append(part)
    detected = {int(p) for p in nodes.truth if p >= 0}
    spurious = any(label == goal_type and p < 0 for label, p in zip(nodes.labels, nodes.truth))
    if not relevant <= detected or spurious:
        return "detection"
    for request, reading in zip(answer.requests, readings):
        parts = [int(nodes.truth[i]) for i in request]
        if any(p >= 0 and reading[i].graspable != bool(nodes.rule_graspable[p]) for i, p in zip(request, parts)):
            return "graspability"
    for request, reading in zip(answer.requests, readings):
        best = max(request, key=lambda i: reading[i].p_grasp)
        part = int(nodes.truth[best])
        if not reading[best].graspable and part >= 0 and reading[best].solution != nodes.rule_solution[part]:
            return "solution"
    return "other"
