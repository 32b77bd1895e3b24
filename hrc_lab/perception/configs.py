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
    """Branches, sizes and training of the action detector (``conf/perception/<name>.yaml`` explains each value)."""

    temporal: str = "lstm_fcn"  # hand-track branch: "lstm_fcn" (Eq. 5.1), "lstm" (last hidden state only), "none"
    spatial: str = "crop"  # "crop": CNN on the hand crop (Eq. 5.2); "frames": CNN per frame -> LSTM; "none"
    window: int = 45  # frames per segment (the thesis' 3 s at 15 FPS)
    lstm_hidden: int = 64
    lstm_dropout: float = 0.3  # on the LSTM's last hidden state
    fcn_filters: list[int] = field(default_factory=lambda: [128, 256, 128])  # conv1d blocks of LSTM-FCN [144]
    fcn_kernels: list[int] = field(default_factory=lambda: [8, 5, 3])
    crop_size: int = 64  # px side of the hand crop
    cnn_widths: list[int] = field(default_factory=lambda: [16, 32, 64, 128])  # VGG16: [64, 128, 256, 512, 512]
    cnn_convs: list[int] = field(default_factory=lambda: [2, 2, 2, 2])  # conv3x3 per block; VGG16: [2, 2, 3, 3, 3]
    cnn_batch_norm: bool = True  # BatchNorm after every conv (VGG16-BN): from scratch, plain VGG barely trains here
    spatial_dim: int = 128  # CNN feature size (a linear layer on the flattened last block)
    frame_size: int = 64  # px side of the downscaled frames (spatial="frames")
    frame_stride: int = 3  # spatial="frames" reads every frame_stride-th frame of the window, ending at the last
    fusion_hidden: int = 128
    dropout: float = 0.3  # in the fusion MLP
    lr: float = 1e-3  # AdamW
    weight_decay: float = 1e-4
    batch_size: int = 32
    epochs: int = 20  # the protocol's Trainer max_epochs
    augment: bool = True  # random shift/scale and brightness of the images, noise on the track (training only)

    def __post_init__(self) -> None:
        for key, allowed in (("temporal", TEMPORALS), ("spatial", SPATIALS)):
            if getattr(self, key) not in allowed:
                raise ValueError(f"perception.{key} must be one of {allowed}, got '{getattr(self, key)}'")
        if self.temporal == "none" and self.spatial == "none":
            raise ValueError("perception.temporal and perception.spatial cannot both be 'none'")
        for key in ("window", "lstm_hidden", "crop_size", "spatial_dim", "frame_size", "frame_stride",
                    "fusion_hidden", "lr", "batch_size", "epochs"):
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
