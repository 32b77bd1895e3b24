"""Config schema of the Ch.5 hand-centric action detector and its baselines (light: no torch import), and their
registry.

``hand_lstm_fcn`` is the thesis' method (Sec. 5.2.1): LSTM-FCN on the hand track (Eq. 5.1) and a VGG16-style CNN on
the hand crop at the last frame (Eq. 5.2), fused by an MLP. The baselines of 5.4.1 differ from it in the two branch
fields only: ``cnn_lstm`` (plain LSTM on the track), ``hand_cnn`` (crop only) and ``cnn_lstm_video`` (ref. [146]:
the CNN on every ``frame_stride``-th downscaled frame of the window, then an LSTM; no hand tracking).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc_lab.registry import Registry

PERCEPTIONS = Registry("perception")

TEMPORALS = ("lstm_fcn", "lstm", "none")
SPATIALS = ("crop", "frames", "none")


@dataclass
class ActionDetectorConfig:
    """Branches, sizes and training of the action detector; the defaults are the thesis' method (``hand_lstm_fcn``)
    and ``conf/perception/<name>.yaml`` names what a baseline changes. The thesis gives no sizes or training
    settings besides the 45-frame segments; the LSTM-FCN blocks are those of Karim et al. [144]."""

    temporal: str = "lstm_fcn"  # hand-track branch: "lstm_fcn" (Eq. 5.1), "lstm" (last hidden state only), "none"
    spatial: str = "crop"  # "crop": CNN on the hand crop (Eq. 5.2); "frames": CNN per frame -> LSTM; "none"
    window: int = 45  # frames per segment (the thesis' 3 s at 15 FPS, 5.3)
    lstm_hidden: int = 64
    # on the LSTM's last hidden state h_T; [144] uses 0.8 with its dimension shuffle (one step of T variables), not
    # used here: the thesis feeds the LSTM one position per frame
    lstm_dropout: float = 0.3
    # conv1d + BatchNorm + ReLU blocks of LSTM-FCN, then global average pooling [144]
    fcn_filters: list[int] = field(default_factory=lambda: [128, 256, 128])
    fcn_kernels: list[int] = field(default_factory=lambda: [8, 5, 3])
    crop_size: int = 64  # px side of the hand crop (divisible by 2**len(cnn_widths))
    # VGG16-style blocks of conv3x3 + ReLU then 2x2 max-pool, trained from scratch (no pretrained weights here);
    # VGG16 itself: widths [64, 128, 256, 512, 512], convs [2, 2, 3, 3, 3]
    cnn_widths: list[int] = field(default_factory=lambda: [16, 32, 64, 128])
    cnn_convs: list[int] = field(default_factory=lambda: [2, 2, 2, 2])  # conv3x3 per block
    # BatchNorm after every conv (the VGG16-BN variant). From scratch, ours reached a train accuracy of 0.58 in 15
    # epochs without it and 0.98 with it (seed 0, Fig. 5.6 data)
    cnn_batch_norm: bool = True
    spatial_dim: int = 128  # CNN feature size (a linear layer on the flattened last block)
    frame_size: int = 64  # px side of the downscaled frames (spatial="frames")
    # spatial="frames" reads every frame_stride-th frame of the window (15 of 45), ending at the last
    frame_stride: int = 3
    fusion_hidden: int = 128  # MLP on the concatenated features
    dropout: float = 0.3  # in the fusion MLP
    lr: float = 1e-3  # AdamW
    weight_decay: float = 1e-4
    batch_size: int = 32
    # training only: random shift/zoom and brightness of the images, noise on the track
    augment: bool = True

    def __post_init__(self) -> None:
        for key, allowed in (("temporal", TEMPORALS), ("spatial", SPATIALS)):
            if getattr(self, key) not in allowed:
                raise ValueError(f"perception.{key} must be one of {allowed}, got '{getattr(self, key)}'")
        if self.temporal == "none" and self.spatial == "none":
            raise ValueError("perception.temporal and perception.spatial cannot both be 'none'")
        for key in ("window", "lstm_hidden", "crop_size", "spatial_dim", "frame_size", "frame_stride",
                    "fusion_hidden", "lr", "batch_size"):
            if getattr(self, key) <= 0:
                raise ValueError(f"perception.{key} must be > 0, got {getattr(self, key)}")
        for key in ("lstm_dropout", "dropout"):
            if not 0 <= getattr(self, key) < 1:
                raise ValueError(f"perception.{key} must be in [0, 1), got {getattr(self, key)}")
        if self.weight_decay < 0:
            raise ValueError(f"perception.weight_decay must be >= 0, got {self.weight_decay}")
        if self.frame_stride > self.window:
            raise ValueError(f"perception.frame_stride must be <= perception.window, got {self.frame_stride}")
        for first, second in (("fcn_filters", "fcn_kernels"), ("cnn_widths", "cnn_convs")):
            values = {key: [int(v) for v in getattr(self, key)] for key in (first, second)}  # plain lists
            for key, value in values.items():
                if not value or min(value) <= 0:
                    raise ValueError(f"perception.{key} must be a non-empty list of positive ints, got {value}")
                setattr(self, key, value)
            if len(values[first]) != len(values[second]):
                raise ValueError(
                    f"perception.{first} and perception.{second} must have the same length, got {values[first]} and "
                    f"{values[second]}"
                )
        reduction = 2 ** len(self.cnn_widths)  # one 2x2 max-pool per CNN block
        for key in ("crop_size", "frame_size"):
            if getattr(self, key) % reduction:
                raise ValueError(
                    f"perception.{key} must be divisible by 2**len(perception.cnn_widths) = {reduction}, "
                    f"got {getattr(self, key)}"
                )

    @property
    def frame_indices(self) -> list[int]:
        """The frames of a window that ``spatial="frames"`` reads: every ``frame_stride``-th, ending at the last."""
        return list(range(self.window - 1, -1, -self.frame_stride))[::-1]


DETECTOR = "hrc_lab.perception.action_detector:ActionDetector"
for _name in ("hand_lstm_fcn", "cnn_lstm", "hand_cnn", "cnn_lstm_video"):
    PERCEPTIONS.register(_name, ActionDetectorConfig, DETECTOR)
