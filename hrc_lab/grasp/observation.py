"""What the Ch.6 solvers see of a rendered scene: the detected (or oracle) objects with their box-head features,
matched to the scene's parts so that the labelling rule can score and label them."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from itertools import combinations

import numpy as np
import torch

from hrc_lab.env.clutter.rule import blocker_solution, blockers
from hrc_lab.env.clutter.spec import ClutterScene, ClutterSpec
from hrc_lab.grasp.configs import DetectorConfig
from hrc_lab.grasp.detection_metrics import match_detections
from hrc_lab.grasp.detector import Detections


@dataclass
class SceneNodes:
    """One image as a solver sees it, with the rule's ground truth for the parts its objects match."""

    scene: ClutterScene
    boxes: np.ndarray  # (n, 4) px, detected (or ground-truth) boxes
    labels: list[str]
    features: torch.Tensor  # (n, d) box-head features f_i
    truth: np.ndarray  # per object, index of the matched part or -1 (a false detection)
    rule_graspable: np.ndarray  # per part
    rule_solution: list[list[str]]  # per part
    rule_blockers: list[list[int]]  # per part
    union_features: dict[tuple[int, int], torch.Tensor] = field(default_factory=dict)  # (i < j) -> f of the union box

    @property
    def image_size(self) -> int:
        return int(self.scene.image.shape[0])

    def requested(self, request: set[str]) -> np.ndarray:
        return np.array([label in request for label in self.labels], dtype=bool)


def union_box(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.concatenate([np.minimum(a[:2], b[:2]), np.maximum(a[2:], b[2:])])


def enlarged_boxes(boxes: np.ndarray, scale: float, image_size: int) -> np.ndarray:
    """(n, 4) x0, y0, x1, y1 boxes scaled by ``scale`` about their centres, clipped to the image."""
    boxes = np.asarray(boxes, dtype=np.float32).reshape(-1, 4)
    centre, half = (boxes[:, :2] + boxes[:, 2:]) / 2, (boxes[:, 2:] - boxes[:, :2]) * scale / 2
    return np.clip(np.hstack([centre - half, centre + half]), 0, image_size).astype(np.float32)


def scene_nodes(
    spec: ClutterSpec, scenes: list[ClutterScene], detector, reading: DetectorConfig, union_features: bool = False,
    annotated_blockers: list[list[list[int]]] | None = None,
) -> list[SceneNodes]:
    """Detections (``reading.mode`` trained) or ground-truth boxes (``oracle``) with box-head features, matched to
    parts; with ``reading.context_scale`` > 1 each f_i is followed by the feature of its box enlarged by that
    factor; with ``union_features`` also the feature of every pair's union box (GVMRN_RF). The ground truth is the
    rule's (:mod:`hrc_lab.env.clutter.rule`), or with ``annotated_blockers`` (per scene, per part, the parts to move
    first: a data set's annotation, :mod:`hrc_lab.data.vmrd`) derived from those as the rule derives it from its
    own: graspable when there is none, the solution from their types."""
    images = [s.image for s in scenes]
    if reading.mode == "oracle":
        features = detector.features_for_boxes(images, [s.boxes for s in scenes])
        found = [Detections(s.boxes, s.types, np.ones(len(s.objects), np.float32), f) for s, f in zip(scenes, features)]
    else:
        found = detector.detect(images)
    if reading.context_scale:
        size = images[0].shape[0]
        context = detector.features_for_boxes(
            images, [enlarged_boxes(d.boxes, reading.context_scale, size) for d in found])
        found = [replace(d, features=torch.cat([torch.as_tensor(d.features).float(), c.float()], dim=-1))
                 for d, c in zip(found, context)]
    unions = None
    if union_features:
        pairs = [list(combinations(range(len(d.labels)), 2)) for d in found]
        boxes = [
            np.array([union_box(d.boxes[i], d.boxes[j]) for i, j in p], dtype=np.float32).reshape(-1, 4)
            for d, p in zip(found, pairs)
        ]
        unions = [dict(zip(p, f)) for p, f in zip(pairs, detector.features_for_boxes(images, boxes))]
    if annotated_blockers is None:
        annotated_blockers = [blockers(spec, scene) for scene in scenes]
    nodes = []
    for k, (scene, det, blocked_by) in enumerate(zip(scenes, found, annotated_blockers, strict=True)):
        match = match_detections(det.boxes, det.labels, scene.boxes, scene.types)  # per part: detection or -1
        truth = np.full(len(det.labels), -1)
        for part, node in enumerate(match):
            if node >= 0:
                truth[node] = part
        nodes.append(
            SceneNodes(
                scene=scene,
                boxes=np.asarray(det.boxes, dtype=np.float32).reshape(-1, 4),
                labels=list(det.labels),
                features=torch.as_tensor(det.features).float(),
                truth=truth,
                rule_graspable=np.array([not b for b in blocked_by], dtype=bool),
                rule_solution=[blocker_solution(scene, i, b) for i, b in enumerate(blocked_by)],
                rule_blockers=[list(b) for b in blocked_by],
                union_features=unions[k] if unions else {},
            )
        )
    return nodes
