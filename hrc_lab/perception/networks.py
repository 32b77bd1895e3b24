"""The networks of the hand-centric action detector (Sec. 5.2.1) and its baselines (5.4.1).

Every branch maps its input to a feature vector of size ``out_dim``; :class:`ActionDetectorNet` concatenates the
branches that the config selects and classifies the actions with an MLP:

- :class:`LSTMFCN` (Eq. 5.1, ref. [144]): f_temporal = concat(h_T, f_FCN), h_T the LSTM's last hidden state over the
  normalised hand positions s_t = (x_t, y_t) and f_FCN = Avg(ReLU(BN(conv1d(s)))) after the conv1d blocks;
- :class:`PlainLSTM` (baseline "CNN+LSTM"): h_T only;
- :class:`VGGStyleCNN` (Eq. 5.2): f_spatial = CNN(I) on the hand crop I at the last frame. The thesis uses VGG16 [145];
  no pretrained weights exist here and the network is trained from scratch on a 2-core CPU, so the default widths
  are a quarter of VGG16's and there are four blocks (``cnn_widths``/``cnn_convs`` accept VGG16's own layout);
- :class:`FrameSequenceLSTM` (baseline "CNN-LSTM" [146]): the CNN on every frame of the window, an LSTM over the
  frame features, h_T.
"""

from __future__ import annotations

import torch
from torch import nn

from hrc_lab.perception.configs import ActionDetectorConfig


class LSTMFCN(nn.Module):
    """(B, T, 2) hand track -> (B, lstm_hidden + fcn_filters[-1]) = concat(h_T, f_FCN) (Eq. 5.1)."""

    def __init__(self, cfg: ActionDetectorConfig, in_dim: int = 2) -> None:
        super().__init__()
        self.lstm = PlainLSTM(cfg, in_dim)
        blocks, channels = [], in_dim
        for filters, kernel in zip(cfg.fcn_filters, cfg.fcn_kernels):
            same = nn.ConstantPad1d(((kernel - 1) // 2, kernel // 2), 0.0)  # output length T, also for even kernels
            blocks += [same, nn.Conv1d(channels, filters, kernel), nn.BatchNorm1d(filters), nn.ReLU()]
            channels = filters
        self.fcn = nn.Sequential(*blocks)
        self.out_dim = self.lstm.out_dim + channels

    def forward(self, track: torch.Tensor) -> torch.Tensor:
        f_fcn = self.fcn(track.transpose(1, 2)).mean(dim=-1)  # global average pooling over time
        return torch.cat([self.lstm(track), f_fcn], dim=-1)


class PlainLSTM(nn.Module):
    """(B, T, in_dim) -> (B, lstm_hidden): the last hidden state h_T = LSTM(h_{T-1}, s_T), with dropout."""

    def __init__(self, cfg: ActionDetectorConfig, in_dim: int = 2) -> None:
        super().__init__()
        self.lstm = nn.LSTM(in_dim, cfg.lstm_hidden, batch_first=True)
        self.dropout = nn.Dropout(cfg.lstm_dropout)
        self.out_dim = cfg.lstm_hidden

    def forward(self, sequence: torch.Tensor) -> torch.Tensor:
        _, (h, _) = self.lstm(sequence)
        return self.dropout(h[-1])


class VGGStyleCNN(nn.Module):
    """(B, 3, S, S) RGB in [0, 1] -> (B, spatial_dim) (Eq. 5.2): per block, ``cnn_convs[i]`` conv3x3 (+ BatchNorm
    with ``cnn_batch_norm``, the VGG16-BN variant) + ReLU with ``cnn_widths[i]`` channels then a 2x2 max-pool
    (VGG16's layout); a linear layer + ReLU on the flattened output."""

    def __init__(self, cfg: ActionDetectorConfig, size: int) -> None:
        super().__init__()
        layers, channels = [], 3
        for width, convs in zip(cfg.cnn_widths, cfg.cnn_convs):
            for _ in range(convs):
                layers += [nn.Conv2d(channels, width, 3, padding=1)]
                layers += [nn.BatchNorm2d(width), nn.ReLU()] if cfg.cnn_batch_norm else [nn.ReLU()]
                channels = width
            layers.append(nn.MaxPool2d(2))
        self.features = nn.Sequential(*layers)
        side = size // 2 ** len(cfg.cnn_widths)
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(channels * side * side, cfg.spatial_dim), nn.ReLU())
        self.out_dim = cfg.spatial_dim
        for module in self.modules():  # torchvision's VGG initialisation (the network is trained from scratch)
            if isinstance(module, nn.Conv2d):
                nn.init.kaiming_normal_(module.weight, mode="fan_out", nonlinearity="relu")
                nn.init.zeros_(module.bias)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(2 * image - 1))  # pixels centred on 0


class FrameSequenceLSTM(nn.Module):
    """(B, T', 3, F, F) frames -> (B, lstm_hidden): :class:`VGGStyleCNN` on every frame, LSTM over their features."""

    def __init__(self, cfg: ActionDetectorConfig) -> None:
        super().__init__()
        self.cnn = VGGStyleCNN(cfg, cfg.frame_size)
        self.lstm = PlainLSTM(cfg, self.cnn.out_dim)
        self.out_dim = self.lstm.out_dim

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        features = self.cnn(frames.flatten(0, 1)).view(*frames.shape[:2], -1)
        return self.lstm(features)


TEMPORAL_BRANCHES = {"lstm_fcn": LSTMFCN, "lstm": PlainLSTM}
SPATIAL_BRANCHES = {"crop": lambda cfg: VGGStyleCNN(cfg, cfg.crop_size), "frames": FrameSequenceLSTM}


class ActionDetectorNet(nn.Module):
    """The config's branches on a batch dict (``track`` (B, T, 2), ``crop`` (B, 3, S, S), ``frames``
    (B, T', 3, F, F)), concatenated and classified by an MLP -> logits (B, n_classes)."""

    def __init__(self, cfg: ActionDetectorConfig, n_classes: int) -> None:
        super().__init__()
        self.temporal = None if cfg.temporal == "none" else TEMPORAL_BRANCHES[cfg.temporal](cfg)
        self.spatial = None if cfg.spatial == "none" else SPATIAL_BRANCHES[cfg.spatial](cfg)
        self.spatial_key = cfg.spatial  # "crop" or "frames": the batch entry the spatial branch reads
        features = sum(branch.out_dim for branch in (self.temporal, self.spatial) if branch is not None)
        self.classifier = nn.Sequential(
            nn.Linear(features, cfg.fusion_hidden),
            nn.ReLU(),
            nn.Dropout(cfg.dropout),
            nn.Linear(cfg.fusion_hidden, n_classes),
        )

    def forward(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        features = []
        if self.temporal is not None:
            features.append(self.temporal(batch["track"]))
        if self.spatial is not None:
            features.append(self.spatial(batch[self.spatial_key]))
        return self.classifier(torch.cat(features, dim=-1))
