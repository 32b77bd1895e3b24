"""Scoring the Ch.6 object detector (:mod:`hrc_lab.grasp.detector`) against the parts of the scenes: one-to-one box
matching (:func:`match_detections`, also what links detections to the scene's parts for the solvers) and the
VOC-style AP, precision and recall of Table 6.1's ``detector_*`` metrics (:func:`detection_quality`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torchvision.ops import box_iou

from hrc_lab.grasp.detector import Detections


def match_detections(pred_boxes, pred_labels: Sequence[str], gt_boxes, gt_types: Sequence[str],
                     iou: float = 0.5) -> np.ndarray:
    """For each ground-truth part the index of the detection matched to it, or -1: one-to-one, same label, IoU >=
    ``iou``, the pairs of highest IoU first."""
    pred = torch.as_tensor(np.asarray(pred_boxes, dtype=np.float32)).reshape(-1, 4)
    gt = torch.as_tensor(np.asarray(gt_boxes, dtype=np.float32)).reshape(-1, 4)
    match = np.full(len(gt), -1, dtype=np.int64)
    if len(pred) == 0 or len(gt) == 0:
        return match
    overlap = box_iou(gt, pred).numpy()
    same = np.asarray(gt_types)[:, None] == np.asarray(pred_labels)[None, :]
    overlap = np.where(same & (overlap >= iou), overlap, -1.0)
    rows, cols = np.unravel_index(np.argsort(-overlap, axis=None, kind="stable"), overlap.shape)
    used = set()
    for g, p in zip(rows, cols):
        if overlap[g, p] < 0:
            break
        if match[g] < 0 and p not in used:
            match[g] = p
            used.add(p)
    return match


def _score_order_hits(det: Detections, gt_boxes, gt_types: Sequence[str], iou: float) -> np.ndarray:
    """VOC matching for AP: in decreasing score, each detection takes the unmatched same-label part it overlaps
    most, if by >= ``iou``; True where it did."""
    hits = np.zeros(len(det), dtype=bool)
    gt = torch.as_tensor(np.asarray(gt_boxes, dtype=np.float32)).reshape(-1, 4)
    if len(det) == 0 or len(gt) == 0:
        return hits
    overlap = box_iou(torch.as_tensor(det.boxes).reshape(-1, 4), gt).numpy()
    free = np.ones(len(gt), dtype=bool)
    types = np.asarray(gt_types)
    for i in np.argsort(-det.scores, kind="stable"):
        candidates = np.where(free & (types == det.labels[i]), overlap[i], -1.0)
        g = int(np.argmax(candidates))
        if candidates[g] >= iou:
            hits[i], free[g] = True, False
    return hits


def _average_precision(scores: np.ndarray, hits: np.ndarray, n_gt: int) -> float:
    """VOC-style AP: the area under the interpolated precision-recall curve (all points)."""
    if n_gt == 0:
        return float("nan")
    order = np.argsort(-scores, kind="stable")
    tp = np.cumsum(hits[order])
    fp = np.cumsum(~hits[order])
    recall = np.concatenate([[0.0], tp / n_gt, [1.0]])
    precision = np.concatenate([[1.0], tp / np.maximum(tp + fp, 1), [0.0]])
    precision = np.maximum.accumulate(precision[::-1])[::-1]
    return float(np.sum((recall[1:] - recall[:-1]) * precision[1:]))


def detection_quality(detections: Sequence[Detections], gt_boxes: Sequence, gt_types: Sequence[Sequence[str]],
                      iou: float = 0.5, score_threshold: float = 0.5) -> dict[str, float]:
    """Per class (each class of the ground truth or the detections) and overall: AP at ``iou`` over all given
    detections (detect with a low threshold for it), and precision and recall of the detections scoring >=
    ``score_threshold``. Also the fraction of scenes whose parts are all detected at that threshold with no extra
    detection (``scene_exact``)."""
    classes = sorted({t for types in gt_types for t in types} | {t for det in detections for t in det.labels})
    per_class = {t: {"scores": [], "hits": [], "n_gt": 0, "tp": 0, "n_pred": 0} for t in classes}
    exact = []
    for det, boxes, types in zip(detections, gt_boxes, gt_types):
        types = list(types)
        hits = _score_order_hits(det, boxes, types, iou)
        confident = det.scores >= score_threshold
        idx = np.flatnonzero(confident)
        match_conf = match_detections(det.boxes[idx], [det.labels[i] for i in idx], boxes, types, iou)
        for label, score, hit in zip(det.labels, det.scores, hits):
            per_class[label]["scores"].append(score)
            per_class[label]["hits"].append(hit)
        for t in classes:
            per_class[t]["n_gt"] += types.count(t)
            per_class[t]["tp"] += int(sum(m >= 0 for m, g in zip(match_conf, types) if g == t))
            per_class[t]["n_pred"] += sum(det.labels[i] == t for i in idx)
        exact.append(bool((match_conf >= 0).all()) and len(idx) == len(types))
    out, aps = {}, []
    for t, c in per_class.items():
        ap = _average_precision(np.asarray(c["scores"], dtype=float), np.asarray(c["hits"], dtype=bool), c["n_gt"])
        out[f"ap_{t}"] = ap
        out[f"recall_{t}"] = c["tp"] / c["n_gt"] if c["n_gt"] else float("nan")
        out[f"precision_{t}"] = c["tp"] / c["n_pred"] if c["n_pred"] else float("nan")
        if c["n_gt"]:
            aps.append(ap)
    tp = sum(c["tp"] for c in per_class.values())
    out["map"] = float(np.mean(aps)) if aps else float("nan")
    out["recall"] = tp / max(1, sum(c["n_gt"] for c in per_class.values()))
    out["precision"] = tp / max(1, sum(c["n_pred"] for c in per_class.values()))
    out["scene_exact"] = float(np.mean(exact)) if exact else float("nan")
    return out
