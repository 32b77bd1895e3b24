"""``perception=hand_lstm_fcn`` and its baselines: the hand-centric action detector of Sec. 5.2.1.

A window of ``window`` frames is classified into one of the assembly actions of Table 5.1 (18 in the thesis) from
the normalised hand track (Eq. 5.1) and the hand crop at the last frame (Eq. 5.2), or from the downscaled frames
(``cnn_lstm_video``), by :class:`~hrc_lab.perception.networks.ActionDetectorNet`, trained end to end. Eq. 5.3
writes the loss as a binary cross-entropy over the one-hot action vector; the actions of a window are mutually
exclusive, so the softmax cross-entropy is used instead (the same argmax decision, probabilities that sum to 1).
"""

from __future__ import annotations

import lightning.pytorch as pl
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from torch.utils.data import DataLoader, Dataset

from hrc_lab.perception.configs import ActionDetectorConfig
from hrc_lab.perception.dataset import STORED_STRIDE, ActionSet, resized_images
from hrc_lab.perception.networks import ActionDetectorNet
from hrc_lab.training import ValidatedModule, accuracy

# Training-time augmentation (cfg.augment): one random affine and brightness per window, on the crop and on every
# frame alike, and independent noise on every track point.
SHIFT = 0.05  # max shift of the images, fraction of their side
SCALE = 0.1  # max relative zoom in or out
BRIGHTNESS = 0.2  # max relative brightness change
TRACK_NOISE = 0.005  # std of the noise on the normalised hand positions (about 3 px on a 640 px image)


def _check(name: str, array: np.ndarray, shape: tuple[int, ...], dtype: type) -> None:
    if array.shape != shape or array.dtype != dtype:
        raise ValueError(f"{name} must be {np.dtype(dtype).name} of shape {shape}, got {array.dtype} {array.shape}")


def _unit_chw(images: torch.Tensor) -> torch.Tensor:
    """uint8 RGB (..., H, W, 3) -> float (..., 3, H, W) in [0, 1]."""
    return images.movedim(-1, -3).float() / 255


def _jitter(images: torch.Tensor) -> torch.Tensor:
    """One random shift, zoom and brightness change applied to all of ``images`` (..., 3, H, W)."""
    flat = images.reshape(-1, *images.shape[-3:])
    zoom, shift_x, shift_y, brightness = (2 * torch.rand(4) - 1).tolist()  # each uniform in [-1, 1]
    scale = 1 + SCALE * zoom
    shift_x, shift_y = 2 * SHIFT * shift_x, 2 * SHIFT * shift_y  # affine_grid's coordinates span [-1, 1]
    theta = torch.tensor([[scale, 0.0, shift_x], [0.0, scale, shift_y]])
    grid = F.affine_grid(theta.expand(len(flat), 2, 3), list(flat.shape), align_corners=False)
    moved = F.grid_sample(flat, grid, padding_mode="border", align_corners=False)
    return (moved * (1 + BRIGHTNESS * brightness)).clamp(0, 1).view(images.shape)


def _image_array(cfg: ActionDetectorConfig, crops: np.ndarray | None, frames: np.ndarray | None) -> np.ndarray | None:
    """The image array the method reads (``crops`` or ``frames``, per ``cfg.spatial``; None for "none")."""
    if cfg.spatial == "none":
        return None
    images = crops if cfg.spatial == "crop" else frames
    if images is None:
        raise ValueError(f"perception.spatial='{cfg.spatial}' needs the {cfg.spatial} images")
    return images


class ActionWindows(Dataset):
    """Labelled windows for the detector: ``tracks`` float32 (N, window, 2) hand positions normalised by the image
    width and height (gaps already filled), ``labels`` int64 (N,), ``crops`` uint8 (N, crop_size, crop_size, 3) RGB
    hand crops at the last frame, ``frames`` uint8 (N, len(cfg.frame_indices), frame_size, frame_size, 3) RGB
    downscaled frames; only the images that ``cfg.spatial`` reads are kept (the other array may be None). Items are
    dicts of tensors: ``track``, ``label`` and ``crop`` (3, S, S) or ``frames`` (T', 3, F, F) in [0, 1], augmented
    when ``train`` and ``cfg.augment``."""

    def __init__(
        self,
        cfg: ActionDetectorConfig,
        tracks: np.ndarray,
        labels: np.ndarray,
        crops: np.ndarray | None = None,
        frames: np.ndarray | None = None,
        train: bool = False,
    ) -> None:
        n = len(labels)
        _check("labels", labels, (n,), np.int64)
        _check("tracks", tracks, (n, cfg.window, 2), np.float32)
        images = _image_array(cfg, crops, frames)
        if images is not None:
            side = cfg.crop_size if cfg.spatial == "crop" else cfg.frame_size
            lead = (n,) if cfg.spatial == "crop" else (n, len(cfg.frame_indices))
            _check(cfg.spatial, images, (*lead, side, side, 3), np.uint8)
        self.tracks, self.labels = torch.from_numpy(tracks), torch.from_numpy(labels)
        self.images = None if images is None else torch.from_numpy(images)
        self.image_key = cfg.spatial  # the batch entry of the images: "crop" or "frames"
        self.augment = train and cfg.augment

    def __len__(self) -> int:
        return len(self.labels)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        item = {"track": self.tracks[i], "label": self.labels[i]}
        if self.augment:
            item["track"] = item["track"] + TRACK_NOISE * torch.randn_like(item["track"])
        if self.images is not None:
            images = _unit_chw(self.images[i])
            item[self.image_key] = _jitter(images) if self.augment else images
        return item


def action_windows(cfg: ActionDetectorConfig, data: ActionSet, train: bool = False) -> ActionWindows:
    """The cached windows of ``data`` (:mod:`hrc_lab.perception.dataset`) at the method's crop and frame sizes."""
    frames = None
    if cfg.spatial == "frames":
        if cfg.frame_stride != STORED_STRIDE:
            raise ValueError(f"perception.frame_stride must be {STORED_STRIDE} (cached frames), got {cfg.frame_stride}")
        frames = resized_images(data.frames, cfg.frame_size)
    return ActionWindows(cfg, data.tracks, data.labels, crops=resized_images(data.crops, cfg.crop_size), frames=frames,
                         train=train)


def action_objective(network: nn.Module, batch: dict[str, torch.Tensor]) -> tuple[torch.Tensor, dict]:
    """Softmax cross-entropy of the actions (Eq. 5.3, see the module docstring) and the accuracy."""
    logits = network(batch)
    return F.cross_entropy(logits, batch["label"]), {"acc": accuracy(logits, batch["label"])}


class ActionDetector(nn.Module):
    """The action detector: its :class:`~hrc_lab.perception.networks.ActionDetectorNet` (``network``), trained by
    ``fit`` as a :class:`~hrc_lab.training.ValidatedModule` of :func:`action_objective` with AdamW (logs
    ``train_loss``/``train_acc`` and ``val_loss``/``val_acc`` per epoch), and read by ``predict_proba`` and
    ``classify``."""

    def __init__(self, cfg: ActionDetectorConfig, n_classes: int, seed: int = 0) -> None:
        super().__init__()
        if n_classes < 2:
            raise ValueError(f"an action detector needs at least 2 classes, got {n_classes}")
        self.cfg, self.n_classes, self.seed = cfg, n_classes, seed
        torch.manual_seed(seed)
        self.network = ActionDetectorNet(cfg, n_classes)

    def forward(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.network(batch)

    def fit(self, train: ActionWindows, trainer: pl.Trainer, val: ActionWindows | None = None) -> ActionDetector:
        """Train for the Trainer's ``max_epochs`` (full passes over the windows, ~11 batches each on the Fig. 5.6
        training split) on shuffled
        batches of ``cfg.batch_size``; shuffling, dropout and augmentation are seeded from ``seed``."""
        torch.manual_seed(self.seed)
        shuffle = torch.Generator().manual_seed(self.seed)
        loader = DataLoader(train, batch_size=self.cfg.batch_size, shuffle=True, generator=shuffle, num_workers=0)
        val_loader = None if val is None else DataLoader(val, batch_size=self.cfg.batch_size, num_workers=0)
        module = ValidatedModule(self.network, action_objective, self.cfg.lr, self.cfg.weight_decay, "adamw")
        trainer.fit(module, loader, val_loader)
        self._recalibrate_batch_norm(loader)
        return self

    @torch.no_grad()
    def _recalibrate_batch_norm(self, loader: DataLoader) -> None:
        """Precise BatchNorm (Wu & Johnson, 2021): replace the running statistics of every BatchNorm by their average
        over one pass of the training data with the final weights. The running averages lag the changing weights and
        start from a variance of 1, far above that of the first block's features (hand positions move a few percent
        of the image per window), which made eval-mode predictions collapse after short trainings. ``val_acc``
        during training still uses the running averages."""
        norms = [module for module in self.modules() if isinstance(module, nn.modules.batchnorm._BatchNorm)]
        if not norms:
            return
        self.eval()
        momenta = [norm.momentum for norm in norms]
        for norm in norms:
            norm.reset_running_stats()
            norm.momentum = None  # cumulative average
            norm.train()
        for batch in loader:
            self(batch)
        for norm, momentum in zip(norms, momenta):
            norm.momentum = momentum
        self.eval()

    @torch.no_grad()
    def predict_proba(self, windows: ActionWindows, batch_size: int = 64) -> np.ndarray:
        """Action probabilities (N, n_classes) of un-augmented windows."""
        if windows.augment:
            raise ValueError("predict_proba needs windows built with train=False (no augmentation)")
        self.eval()
        probabilities = [self(batch).softmax(-1) for batch in DataLoader(windows, batch_size=batch_size)]
        return torch.cat(probabilities).numpy()

    @torch.no_grad()
    def classify(
        self, track: np.ndarray, crop: np.ndarray | None = None, frames: np.ndarray | None = None
    ) -> tuple[int, np.ndarray]:
        """One window of the real-time loop -> (action index, probabilities (n_classes,)); the arrays are one item
        of :class:`ActionWindows`' inputs (``track`` (window, 2), ``crop`` (S, S, 3) uint8, ``frames``)."""
        self.eval()
        batch = {"track": torch.as_tensor(track, dtype=torch.float32)[None]}
        images = _image_array(self.cfg, crop, frames)
        if images is not None:
            batch[self.cfg.spatial] = _unit_chw(torch.from_numpy(images))[None]
        probabilities = self(batch).softmax(-1)[0].numpy()
        return int(probabilities.argmax()), probabilities
