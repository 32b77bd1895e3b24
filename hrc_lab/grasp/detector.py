"""The object detector of Ch.6 (Sec. 6.2, Fig. 6.1): a Faster R-CNN giving, per detected part, f_i, l_i and d_i.

The thesis detects the parts a, b, c of the cluttered scene with a Faster R-CNN [149] (Detectron2, ResNet-101-FPN,
pretrained, on a GPU) and builds the graph of Eq. 6.1 from each detection's feature vector f_i, its label l_i and
the centre d_i of its box. Here the same architecture is torchvision's ``FasterRCNN`` built from scratch
(``weights=None`` everywhere: nothing can be downloaded) and sized to train on a shared 2-core CPU in ~10 min
(defaults: 1,500 steps of 8 images, ~0.4 s a step with ``torch.set_num_threads(1)``). Its quality on the
held-out scenes is a Table 6.1 run's output: metrics ``detector_map`` (AP at IoU 0.5), ``detector_recall``,
``detector_precision`` and ``detector_scene_exact``. Choices:

- backbone: a narrow ResNet-18-like stack (a stride-2 stem, then three stages of ``blocks`` BasicBlocks with
  ``width``, 2 ``width`` and 4 ``width`` channels at strides 4, 8, 16) and a 3-level FPN of ``fpn_channels``.
  The visible boxes are 3-80 px in a 160 x 160 image (sides: 5th percentile 15, median 24 px): the stride-4
  level keeps a partly hidden a several cells wide, the stride-16 level sees a rotated b (up to ~80 px) whole.
  ResNet-101 and a 1333 px input would be ~500x the compute for 3 classes of flat-shaded boxes on a plain table.
- anchors: one size pair per level (``anchor_sizes``, default 12/20, 28/40, 56/80 px) x aspect ratios 1:2, 1:1,
  2:1 (rotated parts seen from the top have boxes from square to ~1:2.5).
- ``min_size = max_size = image_size``: the transform does not resize (a 160 px image stays 160 px).
- fewer proposals and samples than torchvision's defaults (written for COCO's ~7 objects of 80 classes at 800 px):
  at most 6 parts per scene, so ``rpn_post_nms_train`` = 256 proposals and 64 sampled RoIs per image suffice
  (the CPU ``roi_align`` backward is a third of a step's time; 32 FPN channels halve it again).
- box head: ``TwoMLPHead`` with ``representation_size`` = 128 (Detectron2 uses 1024): f_i is this 128-d vector,
  a GNN node feature small enough for the Ch.6 graph models.
- per-class NMS at ``nms`` = 0.5: 0.6-0.7 recovers a few crossing b parts but adds more duplicates than it finds
  parts (precision 0.97 -> 0.80 at 0.7). That NMS being per class, one part may come out twice with two labels;
  a class-agnostic NMS at ``agnostic_nms`` IoU keeps only the more confident one (each detection is one graph
  node); on the held-out scenes no two labels ever overlapped that much (0.7 and 1.0 gave the same results).

Features of a detection are computed for its FINAL (regressed, post-NMS) box by running ``box_roi_pool`` and
``box_head`` again on it, not taken from the proposal it came from; ``features_for_boxes`` does the same for given
boxes (the ``oracle`` mode: ground-truth boxes, features from the same network). Training is seeded (weights,
sampling order, flips, RoI sampling), so a config and a list of scenes give the same detector.

Augmentation: horizontal and vertical flips only. The gripper closes along the image x axis, so a 90 degree
rotation would change which parts are graspable if the images were reused for the graspability labels; flips keep
the closing direction (and the detector does not need rotations: the parts come at every yaw anyway).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial

import lightning.pytorch as pl
import numpy as np
import torch
from torch import nn
from torch.utils.data import Dataset
from torchvision.models.detection import FasterRCNN
from torchvision.models.detection.anchor_utils import AnchorGenerator
from torchvision.models.detection.faster_rcnn import FastRCNNPredictor, TwoMLPHead
from torchvision.models.resnet import BasicBlock
from torchvision.ops import MultiScaleRoIAlign, box_iou, nms
from torchvision.ops.feature_pyramid_network import FeaturePyramidNetwork

from hrc_lab.env.clutter.spec import PART_TYPES, ClutterScene
from hrc_lab.grasp.configs import LEVELS, DetectorConfig
from hrc_lab.training import FixedStepDataModule, SupervisedModule, steps_per_epoch


class SmallBackbone(nn.Module):
    """A narrow ResNet-18-like backbone with a 3-level FPN (strides 4, 8, 16), trained from scratch."""

    def __init__(self, width: int, blocks: int, fpn_channels: int) -> None:
        super().__init__()
        self.stem = nn.Sequential(
            nn.Conv2d(3, width, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(width), nn.ReLU(inplace=True)
        )
        channels = [width, 2 * width, 4 * width]
        self.stages = nn.ModuleList()
        cin = width
        for cout in channels:
            downsample = nn.Sequential(nn.Conv2d(cin, cout, 1, stride=2, bias=False), nn.BatchNorm2d(cout))
            layers = [BasicBlock(cin, cout, stride=2, downsample=downsample)]
            layers += [BasicBlock(cout, cout) for _ in range(blocks - 1)]
            self.stages.append(nn.Sequential(*layers))
            cin = cout
        self.fpn = FeaturePyramidNetwork(channels, fpn_channels)
        self.out_channels = fpn_channels

    def forward(self, x: torch.Tensor) -> OrderedDict[str, torch.Tensor]:
        x = self.stem(x)
        features = OrderedDict()
        for name, stage in zip(LEVELS, self.stages):
            x = stage(x)
            features[name] = x
        return self.fpn(features)


def build_faster_rcnn(cfg: DetectorConfig) -> FasterRCNN:
    """torchvision's Faster R-CNN with the small backbone, background + the part types as classes."""
    anchors = AnchorGenerator(
        sizes=tuple(tuple(int(s) for s in level) for level in cfg.anchor_sizes),
        aspect_ratios=(tuple(float(r) for r in cfg.aspect_ratios),) * len(LEVELS),
    )
    roi_pool = MultiScaleRoIAlign(featmap_names=list(LEVELS), output_size=7, sampling_ratio=2)
    return FasterRCNN(
        SmallBackbone(cfg.width, cfg.blocks, cfg.fpn_channels),
        num_classes=None,  # given by the predictor: background + the part types
        min_size=cfg.image_size,
        max_size=cfg.image_size,
        image_mean=[0.5, 0.5, 0.5],
        image_std=[0.25, 0.25, 0.25],
        rpn_anchor_generator=anchors,
        rpn_pre_nms_top_n_train=2 * cfg.rpn_post_nms_train,
        rpn_pre_nms_top_n_test=2 * cfg.rpn_post_nms_test,
        rpn_post_nms_top_n_train=cfg.rpn_post_nms_train,
        rpn_post_nms_top_n_test=cfg.rpn_post_nms_test,
        rpn_batch_size_per_image=cfg.rpn_batch_size,
        box_roi_pool=roi_pool,
        box_head=TwoMLPHead(cfg.fpn_channels * 7 * 7, cfg.representation_size),
        box_predictor=FastRCNNPredictor(cfg.representation_size, len(PART_TYPES) + 1),
        box_score_thresh=cfg.score_threshold,
        box_nms_thresh=cfg.nms,
        box_detections_per_img=cfg.max_detections,
        box_batch_size_per_image=cfg.box_batch_size,
    )


@dataclass
class Detections:
    """The detected parts of one image: box (x0, y0, x1, y1 px), label l_i, score and feature f_i."""

    boxes: np.ndarray  # (n, 4) float32
    labels: list[str]
    scores: np.ndarray  # (n,) float32, decreasing
    features: torch.Tensor  # (n, representation_size)

    @property
    def centres(self) -> np.ndarray:
        """d_i of Eq. 6.1: the centre of each box, (n, 2) px."""
        return (self.boxes[:, :2] + self.boxes[:, 2:]) / 2

    def __len__(self) -> int:
        return len(self.labels)


def _image_tensor(image) -> torch.Tensor:
    """(H, W, 3) uint8 array or (3, H, W) float tensor in [0, 1] -> (3, H, W) float tensor."""
    if isinstance(image, torch.Tensor) and image.dtype.is_floating_point:
        return image
    image = torch.as_tensor(np.asarray(image))
    if image.ndim != 3 or image.shape[-1] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 image or a (3, H, W) float tensor, got {tuple(image.shape)}")
    return image.permute(2, 0, 1).float() / 255


def scene_target(scene: ClutterScene, min_side: float = 1.0) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """A scene as a training sample: the (3, H, W) uint8 image and its boxes and labels (1 + index in PART_TYPES).
    Parts whose visible box is under ``min_side`` px wide or high (hidden) are left out."""
    image = torch.as_tensor(scene.image).permute(2, 0, 1).contiguous()
    boxes = scene.boxes.reshape(-1, 4) if scene.objects else np.zeros((0, 4), np.float32)
    keep = ((boxes[:, 2] - boxes[:, 0]) >= min_side) & ((boxes[:, 3] - boxes[:, 1]) >= min_side)
    labels = [PART_TYPES.index(t) + 1 for t, k in zip(scene.types, keep) if k]
    target = {"boxes": torch.as_tensor(boxes[keep], dtype=torch.float32).reshape(-1, 4),
              "labels": torch.as_tensor(labels, dtype=torch.int64)}
    return image, target


class _SceneDataset(Dataset):
    def __init__(self, scenes: Sequence[ClutterScene]) -> None:
        self.samples = [scene_target(s) for s in scenes]

    def __len__(self) -> int:
        return len(self.samples)

    def __getitem__(self, i: int):
        return self.samples[i]


def _collate(batch):
    return tuple(zip(*batch))


def random_flips(images: list[torch.Tensor], targets: list[dict]) -> tuple[list[torch.Tensor], list[dict]]:
    """Each image and its boxes flipped horizontally, then vertically, each with probability 0.5 (torch's global
    generator)."""
    out_images, out_targets = [], []
    for image, target in zip(images, targets):
        boxes = target["boxes"].clone()
        height, width = image.shape[-2:]
        if torch.rand(()) < 0.5:
            image = image.flip(-1)
            boxes[:, [0, 2]] = width - boxes[:, [2, 0]]
        if torch.rand(()) < 0.5:
            image = image.flip(-2)
            boxes[:, [1, 3]] = height - boxes[:, [3, 1]]
        out_images.append(image)
        out_targets.append({**target, "boxes": boxes})
    return out_images, out_targets


def detection_objective(model: FasterRCNN, batch, flip: bool) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The sum of the Faster R-CNN's losses (RPN objectness and box regression, box-head classification and
    regression) on a batch of (images, targets), with random flips when ``flip``; each loss by name."""
    images, targets = batch
    images = [im if im.dtype.is_floating_point else im.float() / 255 for im in images]
    targets = list(targets)
    if flip:
        images, targets = random_flips(images, targets)
    losses = model(images, targets)
    return sum(losses.values()), losses


class DetectorModule(SupervisedModule):
    """The detector's training: :func:`detection_objective` with AdamW, a linear warm-up over ``warmup_steps``
    then a cosine decay to 0 over the fit's steps; logs ``train_loss`` and ``train_<each loss>`` per epoch."""

    def __init__(self, model: FasterRCNN, cfg: DetectorConfig) -> None:
        super().__init__(model, partial(detection_objective, flip=cfg.flip), cfg.lr, cfg.weight_decay, "adamw")
        self.warmup_steps = cfg.warmup_steps

    def configure_optimizers(self):
        optimizer = super().configure_optimizers()
        total = max(1, int(self.trainer.estimated_stepping_batches))
        warmup = min(self.warmup_steps, total // 2)

        def factor(step: int) -> float:
            if step < warmup:
                return (step + 1) / warmup
            return 0.5 * (1 + np.cos(np.pi * min(1.0, (step - warmup) / max(1, total - warmup))))

        scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, factor)
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}


class ObjectDetector(nn.Module):
    """The Faster R-CNN of Fig. 6.1 (``model``): ``fit`` on scenes, then ``detect`` parts with their f_i. Saved and
    loaded by :mod:`hrc_lab.grasp.detector_cache`."""

    def __init__(self, cfg: DetectorConfig) -> None:
        super().__init__()
        self.cfg = cfg
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(cfg.seed)
            self.model = build_faster_rcnn(cfg)

    def fit(self, scenes: Sequence[ClutterScene], trainer: pl.Trainer) -> ObjectDetector:
        """Train on the scenes for about ``cfg.steps`` steps (split over ``trainer.max_epochs``); returns self in
        eval mode. Scenes are sampled with replacement so an epoch is a fixed number of steps."""
        if not scenes:
            raise ValueError("no training scenes")
        steps = steps_per_epoch(self.cfg.steps, trainer)
        torch.manual_seed(self.cfg.seed)  # RoI/anchor sampling and flips draw from the global generator
        generator = torch.Generator().manual_seed(self.cfg.seed)
        data = FixedStepDataModule(_SceneDataset(scenes), self.cfg.batch_size, steps, generator=generator,
                                   collate_fn=_collate)
        trainer.fit(DetectorModule(self.model, self.cfg), datamodule=data)
        return self.eval()

    # --- inference --------------------------------------------------------------------------------------------
    @torch.no_grad()
    def detect(self, images: Sequence, score_threshold: float | None = None, batch_size: int = 16) -> list[Detections]:
        """Detected parts of each image ((H, W, 3) uint8 arrays or (3, H, W) float tensors), with the features of
        their final boxes. ``score_threshold`` overrides ``cfg.score_threshold`` (e.g. 0.05 for mAP)."""
        was_training = self.training
        self.eval()
        heads = self.model.roi_heads
        heads.score_thresh = self.cfg.score_threshold if score_threshold is None else score_threshold
        out = []
        try:
            for start in range(0, len(images), batch_size):
                out += self._detect_batch([_image_tensor(im) for im in images[start:start + batch_size]])
        finally:
            heads.score_thresh = self.cfg.score_threshold
            self.train(was_training)
        return out

    def _detect_batch(self, images: list[torch.Tensor]) -> list[Detections]:
        model = self.model
        original_sizes = [tuple(im.shape[-2:]) for im in images]
        batch, _ = model.transform(images)
        features = model.backbone(batch.tensors)
        proposals, _ = model.rpn(batch, features)
        results, _ = model.roi_heads(features, proposals, batch.image_sizes)
        if self.cfg.agnostic_nms < 1:
            for r in results:
                keep = nms(r["boxes"], r["scores"], self.cfg.agnostic_nms)  # sorted by decreasing score
                for key in ("boxes", "scores", "labels"):
                    r[key] = r[key][keep]
        pooled = model.roi_heads.box_roi_pool(features, [r["boxes"] for r in results], batch.image_sizes)
        f = model.roi_heads.box_head(pooled).split([len(r["boxes"]) for r in results])
        results = model.transform.postprocess(results, batch.image_sizes, original_sizes)
        return [
            Detections(
                boxes=r["boxes"].numpy().astype(np.float32).reshape(-1, 4),
                labels=[PART_TYPES[int(k) - 1] for k in r["labels"]],
                scores=r["scores"].numpy().astype(np.float32),
                features=fi,
            )
            for r, fi in zip(results, f)
        ]

    @torch.no_grad()
    def features_for_boxes(self, images: Sequence, boxes_list: Sequence) -> list[torch.Tensor]:
        """f_i for given boxes ((n, 4) x0, y0, x1, y1 px per image), e.g. the ground truth: the ``oracle`` mode."""
        if len(images) != len(boxes_list):
            raise ValueError(f"{len(images)} images but {len(boxes_list)} box lists")
        was_training = self.training
        self.eval()
        try:
            model = self.model
            images = [_image_tensor(im) for im in images]
            targets = [{"boxes": torch.as_tensor(np.asarray(b), dtype=torch.float32).reshape(-1, 4)}
                       for b in boxes_list]
            batch, targets = model.transform(images, targets)
            features = model.backbone(batch.tensors)
            pooled = model.roi_heads.box_roi_pool(features, [t["boxes"] for t in targets], batch.image_sizes)
            f = model.roi_heads.box_head(pooled)
        finally:
            self.train(was_training)
        return list(f.split([len(t["boxes"]) for t in targets]))


# --- scoring ----------------------------------------------------------------------------------------------------
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
    """Per class and overall: AP at ``iou`` over all given detections (detect with a low threshold for it), and
    precision and recall of the detections scoring >= ``score_threshold``. Also the fraction of scenes whose
    parts are all detected at that threshold with no extra detection (``scene_exact``)."""
    per_class = {t: {"scores": [], "hits": [], "n_gt": 0, "tp": 0, "n_pred": 0} for t in PART_TYPES}
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
        for t in PART_TYPES:
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
