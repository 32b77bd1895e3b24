"""The object detector of Ch.6 (Sec. 6.2, Fig. 6.1): a Faster R-CNN giving, per detected part, f_i, l_i and d_i.

The thesis detects the parts a, b, c of the cluttered scene with a Faster R-CNN [149] (Detectron2, ResNet-101-FPN,
pretrained, on a GPU) and builds the graph of Eq. 6.1 from each detection's feature vector f_i, its label l_i and
the centre d_i of its box. Here the same architecture is torchvision's ``FasterRCNN`` built from scratch
(``weights=None`` everywhere: nothing can be downloaded) and sized to train on a shared 2-core CPU in ~10 min
(defaults: 1,500 steps of 8 images, ~0.4 s a step with ``torch.set_num_threads(1)``);
:mod:`hrc_lab.grasp.detector_model` builds it and explains its sizes. This module trains it on scenes
(:class:`ObjectDetector`, :class:`DetectorModule`) and runs it. Its quality on the held-out scenes is a Table 6.1
run's output (:func:`hrc_lab.grasp.detection_metrics.detection_quality`): metrics ``detector_map`` (AP at IoU 0.5),
``detector_recall``, ``detector_precision`` and ``detector_scene_exact``.

NMS: per class at ``nms`` = 0.5 inside the model: 0.6-0.7 recovers a few crossing b parts but adds more duplicates
than it finds parts (precision 0.97 -> 0.80 at 0.7). That NMS being per class, one part may come out twice with two
labels; :meth:`ObjectDetector.detect` then applies a class-agnostic NMS at ``agnostic_nms`` IoU that keeps only the
more confident one (each detection is one graph node); on the held-out scenes no two labels ever overlapped that
much (0.7 and 1.0 gave the same results).

Features of a detection are computed for its FINAL (regressed, post-NMS) box by running ``box_roi_pool`` and
``box_head`` again on it, not taken from the proposal it came from; ``features_for_boxes`` does the same for given
boxes (the ``oracle`` mode: ground-truth boxes, features from the same network). Training is seeded (weights,
sampling order, flips, RoI sampling), so a config and a list of scenes give the same detector.

Augmentation: horizontal and vertical flips only. The gripper closes along the image x axis, so a 90 degree
rotation would change which parts are graspable if the images were reused for the graspability labels; flips keep
the closing direction (and the detector does not need rotations: the parts come at every yaw anyway).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial

import lightning.pytorch as pl
import numpy as np
import torch
from torch import nn
from torch.utils.data import Dataset
from torchvision.models.detection import FasterRCNN
from torchvision.ops import nms

from hrc_lab.env.clutter.spec import ClutterScene
from hrc_lab.grasp.configs import DetectorConfig
from hrc_lab.grasp.detector_model import build_faster_rcnn
from hrc_lab.training import FixedStepDataModule, SupervisedModule, steps_per_epoch


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


def scene_target(scene: ClutterScene, classes: Sequence[str],
                 min_side: float = 1.0) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """A scene as a training sample: the (3, H, W) uint8 image and its boxes and labels (1 + index in ``classes``).
    Parts whose visible box is under ``min_side`` px wide or high (hidden) are left out."""
    image = torch.as_tensor(scene.image).permute(2, 0, 1).contiguous()
    boxes = scene.boxes.reshape(-1, 4) if scene.objects else np.zeros((0, 4), np.float32)
    keep = ((boxes[:, 2] - boxes[:, 0]) >= min_side) & ((boxes[:, 3] - boxes[:, 1]) >= min_side)
    labels = [classes.index(t) + 1 for t, k in zip(scene.types, keep) if k]
    target = {"boxes": torch.as_tensor(boxes[keep], dtype=torch.float32).reshape(-1, 4),
              "labels": torch.as_tensor(labels, dtype=torch.int64)}
    return image, target


class _SceneDataset(Dataset):
    def __init__(self, scenes: Sequence[ClutterScene], classes: Sequence[str]) -> None:
        self.samples = [scene_target(s, classes) for s in scenes]

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
        super().__init__(model, partial(detection_objective, flip=cfg.flip), cfg.lr, cfg.weight_decay, "adamw",
                         schedule="cosine", warmup_steps=cfg.warmup_steps)


class ObjectDetector(nn.Module):
    """The Faster R-CNN of Fig. 6.1 (``model``) for objects of ``classes`` (our part types, or a data set's):
    ``fit`` on scenes, then ``detect`` objects with their f_i. Saved and loaded by
    :mod:`hrc_lab.grasp.detector_cache`."""

    def __init__(self, cfg: DetectorConfig, classes: Sequence[str]) -> None:
        super().__init__()
        self.cfg, self.classes = cfg, tuple(classes)
        if not self.classes or len(set(self.classes)) != len(self.classes):
            raise ValueError(f"the detector's classes must be distinct and at least one, got {list(classes)}")
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(cfg.seed)
            self.model = build_faster_rcnn(cfg, len(self.classes))

    def fit(self, scenes: Sequence[ClutterScene], trainer: pl.Trainer) -> ObjectDetector:
        """Train on the scenes for about ``cfg.steps`` steps (split over ``trainer.max_epochs``); returns self in
        eval mode. Scenes are sampled with replacement so an epoch is a fixed number of steps."""
        if not scenes:
            raise ValueError("no training scenes")
        steps = steps_per_epoch(self.cfg.steps, trainer)
        torch.manual_seed(self.cfg.seed)  # RoI/anchor sampling and flips draw from the global generator
        generator = torch.Generator().manual_seed(self.cfg.seed)
        data = FixedStepDataModule(_SceneDataset(scenes, self.classes), self.cfg.batch_size, steps, generator=generator,
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
                labels=[self.classes[int(k) - 1] for k in r["labels"]],
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
