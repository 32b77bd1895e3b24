"""What the Ch.6 solvers see of a rendered scene: the detected (or oracle) objects with their box-head features,
matched to the scene's parts so that the labelling rule can score and label them."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from itertools import combinations

import numpy as np
import torch

from hrc_lab.env.clutter.rule import blocker_solution, blockers
from hrc_lab.env.clutter.spec import ClutterScene, ClutterSpec, box_centre_median
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


HEIGHT_UNIT = 0.05  # m: heights above the table enter the depth features in this unit (about a part's size)


def height_grids(spec: ClutterSpec, depth: np.ndarray, boxes: np.ndarray, grid: int) -> torch.Tensor:
    """(n, grid * grid + 2) depth features of (n, 4) px boxes, heights above the table (``spec.camera_height`` minus
    the depth) in :data:`HEIGHT_UNIT`: the heights max-pooled over a grid x grid partition of each box (a part that
    another one covers shows the other's height inside its own box), then, for the rule's two finger volumes
    beside the box (:func:`finger_clearances`), how far the highest point in each rises above the finger tips (★ the
    thesis' future work, 6.5: "utilize depth images")."""
    heights = (spec.camera_height - np.asarray(depth, dtype=np.float32)) / HEIGHT_UNIT
    size_y, size_x = heights.shape
    features = []
    for box in np.asarray(boxes, dtype=float).reshape(-1, 4):
        x0, y0, x1, y1 = box
        c0, r0 = min(int(np.floor(x0)), size_x - 1), min(int(np.floor(y0)), size_y - 1)
        c1, r1 = max(int(np.ceil(x1)), c0 + 1), max(int(np.ceil(y1)), r0 + 1)
        crop = torch.as_tensor(heights[r0:r1, c0:c1])[None, None]
        pooled = torch.nn.functional.adaptive_max_pool2d(crop, grid).flatten()
        features.append(torch.cat([pooled, torch.as_tensor(finger_clearances(spec, heights, box))]))
    return torch.stack(features) if features else torch.zeros(0, grid * grid + 2)


def finger_clearances(spec: ClutterSpec, heights: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(2,) for the left and right finger volumes of the rule (:func:`hrc_lab.env.clutter.rule.finger_boxes`:
    ``finger_thickness`` beyond ``finger_gap`` either side of the box in x, ``finger_width`` about its centre in y),
    the highest point seen in each minus the finger tips' height (``grasp_depth`` below the part's top, the median
    height of the box's central third), in :data:`HEIGHT_UNIT`; > 0: something there reaches above the tips."""
    x0, y0, x1, y1 = np.asarray(box, dtype=float)
    size_y, size_x = heights.shape
    cy = (y0 + y1) / 2
    top = box_centre_median(heights, box)  # the part's top, as ClutterCell.locate reads it
    px_per_m = spec.pixel_scale / max(spec.camera_height - top * HEIGHT_UNIT, 1e-3)
    gap, reach = spec.finger_gap * px_per_m, (spec.finger_gap + spec.finger_thickness) * px_per_m
    half_width = max(spec.finger_width / 2 * px_per_m, 0.5)
    rows = slice(max(int(np.floor(cy - half_width)), 0), min(int(np.ceil(cy + half_width)), size_y))
    tips = top - spec.grasp_depth / HEIGHT_UNIT
    clearances = []
    for start, stop in ((x0 - reach, x0 - gap), (x1 + gap, x1 + reach)):
        cols = slice(max(int(np.floor(start)), 0), min(int(np.ceil(stop)), size_x))
        strip = heights[rows, cols]
        clearances.append((float(strip.max()) if strip.size else 0.0) - tips)
    return np.asarray(clearances, dtype=np.float32)


def scene_nodes(
    spec: ClutterSpec, scenes: list[ClutterScene], detector, reading: DetectorConfig, union_features: bool = False,
    annotated_blockers: list[list[list[int]]] | None = None, depth_grid: int = 0,
) -> list[SceneNodes]:
    """Detections (``reading.mode`` trained) or ground-truth boxes (``oracle``) with box-head features, matched to
    parts; with ``reading.context_scale`` > 1 each f_i is followed by the feature of its box enlarged by that
    factor; with ``depth_grid`` > 0 by its :func:`height_grids` from the scene's depth image; with
    ``union_features`` also the feature of every pair's union box (GVMRN_RF). The ground truth is the
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
    if depth_grid:
        missing = [s.seed for s in scenes if s.depth is None]
        if missing:
            raise ValueError(f"grasp.depth_grid={depth_grid} reads depth images, but {len(missing)} scene(s) have "
                             f"none (e.g. seed {missing[0]}; a data set's RGB images have no depth): use 0")
        found = [replace(d, features=torch.cat([torch.as_tensor(d.features).float(),
                                                height_grids(spec, s.depth, d.boxes, depth_grid)], dim=-1))
                 for d, s in zip(found, scenes)]
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
