"""The network of the Ch.6 object detector (:mod:`hrc_lab.grasp.detector`): torchvision's ``FasterRCNN`` with a
small backbone, built from scratch (``weights=None`` everywhere: nothing can be downloaded) and sized to train on a
shared 2-core CPU. Choices:

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
- per-class NMS at ``nms`` (:mod:`hrc_lab.grasp.detector` explains the value and the class-agnostic NMS after it).
"""

from __future__ import annotations

from collections import OrderedDict

import torch
from torch import nn
from torchvision.models.detection import FasterRCNN
from torchvision.models.detection.anchor_utils import AnchorGenerator
from torchvision.models.detection.faster_rcnn import FastRCNNPredictor, TwoMLPHead
from torchvision.models.resnet import BasicBlock
from torchvision.ops import MultiScaleRoIAlign
from torchvision.ops.feature_pyramid_network import FeaturePyramidNetwork

from hrc_lab.grasp.configs import LEVELS, DetectorConfig


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


def build_faster_rcnn(cfg: DetectorConfig, n_classes: int) -> FasterRCNN:
    """torchvision's Faster R-CNN with the small backbone, background + ``n_classes`` object classes."""
    anchors = AnchorGenerator(
        sizes=tuple(tuple(int(s) for s in level) for level in cfg.anchor_sizes),
        aspect_ratios=(tuple(float(r) for r in cfg.aspect_ratios),) * len(LEVELS),
    )
    roi_pool = MultiScaleRoIAlign(featmap_names=list(LEVELS), output_size=7, sampling_ratio=2)
    return FasterRCNN(
        SmallBackbone(cfg.width, cfg.blocks, cfg.fpn_channels),
        num_classes=None,  # given by the predictor: background + the object classes
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
        box_predictor=FastRCNNPredictor(cfg.representation_size, n_classes + 1),
        box_score_thresh=cfg.score_threshold,
        box_nms_thresh=cfg.nms,
        box_detections_per_img=cfg.max_detections,
        box_batch_size_per_image=cfg.box_batch_size,
    )
