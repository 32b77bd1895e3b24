"""The Ch.5 action detector trained on a tracked clip set (:mod:`hrc_lab.perception.dataset`), and its cache: one
detector per clip set and perception config in ``<cache_dir>/detector_<key>.pt``, shared by the jobs of a sweep
(:func:`hrc_lab.cache.cached`)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import lightning.pytorch as pl
import torch

from hrc_lab.cache import cache_key, cached
from hrc_lab.data.files import load_torch, load_weights
from hrc_lab.kernels import cpu_kernels
from hrc_lab.perception.action_detector import ActionDetector, action_windows
from hrc_lab.perception.configs import PERCEPTIONS, ActionDetectorConfig
from hrc_lab.perception.dataset import ActionSet


def train_action_detector(cfg: ActionDetectorConfig, data: ActionSet, seed: int,
                          trainer_factory: Callable[[], pl.Trainer]) -> ActionDetector:
    """The ``cfg`` method (seed ``seed``) fitted on every window of ``data``."""
    detector = PERCEPTIONS.build(cfg, n_classes=len(data.names), seed=seed)
    return detector.fit(action_windows(cfg, data, train=True), trainer_factory())


def load_or_train_action_detector(cfg: ActionDetectorConfig, data: ActionSet, data_key: str, seed: int,
                                  trainer_factory: Callable[[], pl.Trainer],
                                  cache_dir: str | os.PathLike) -> ActionDetector:
    """The detector :func:`train_action_detector` gives on ``data`` (whose :func:`action_set_key
    <hrc_lab.perception.dataset.action_set_key>` is ``data_key``), in eval mode: from ``<cache_dir>/detector_<key>.pt``
    when another job already trained it with the same CPU kernels (:mod:`hrc_lab.kernels`), else trained and saved
    there (parallel jobs wait for the first)."""
    key = cache_key({"data": data_key, "perception": asdict(cfg), "kernels": cpu_kernels()})

    def build(path: Path) -> None:
        detector = train_action_detector(cfg, data, seed, trainer_factory)
        torch.save(detector.state_dict(), path)

    path = cached(Path(cache_dir) / f"detector_{key}.pt", build)
    detector = PERCEPTIONS.build(cfg, n_classes=len(data.names), seed=seed)
    load_weights(path, detector, load_torch(path))
    return detector.eval()
