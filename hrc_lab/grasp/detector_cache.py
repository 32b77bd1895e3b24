"""The Ch.6 detector's cache: one trained detector per config and list of training scenes, in
``<cache_dir>/detector_<key>.pt``, shared by the jobs of a sweep (:func:`hrc_lab.cache.cached`)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import lightning.pytorch as pl
import torch

from hrc_lab.cache import cache_key, cached
from hrc_lab.data.files import DataFileError, load_torch, load_weights
from hrc_lab.env.clutter.spec import ClutterScene
from hrc_lab.grasp.configs import DetectorConfig
from hrc_lab.grasp.detector import ObjectDetector
from hrc_lab.kernels import cpu_kernels


def detector_cache_key(cfg: DetectorConfig, classes: Sequence[str], scene_seeds: Sequence[int]) -> str:
    """A short hash of the config, the classes, the (ordered) seeds of the training scenes and the CPU kernels
    (:func:`hrc_lab.kernels.cpu_kernels`: other kernels train other weights)."""
    # oracle and trained modes, with or without context features, share the network
    settings = {k: v for k, v in asdict(cfg).items() if k not in ("mode", "context_scale")}
    return cache_key({"cfg": settings, "classes": list(classes), "seeds": [int(s) for s in scene_seeds],
                      "kernels": cpu_kernels()}, length=16)


def load_or_train_detector(cfg: DetectorConfig, classes: Sequence[str], scenes: Sequence[ClutterScene],
                           trainer_factory: Callable[[], pl.Trainer], cache_dir: str | os.PathLike,
                           key: str) -> tuple[ObjectDetector, dict]:
    """The detector trained on ``scenes``, from ``<cache_dir>/detector_<key>.pt`` if present, else trained and
    saved there (:func:`hrc_lab.cache.cached`: parallel jobs wait for the first). ``info``: train_seconds (of the
    original training), cached, path."""
    detector = ObjectDetector(cfg, classes)
    trained: list[float] = []

    def train(partial: Path) -> None:
        start = time.perf_counter()
        detector.fit(scenes, trainer_factory())
        trained.append(time.perf_counter() - start)
        # tensors and plain values only (asdict of the config: lists, numbers, strings), so it loads weights-only
        torch.save({"state_dict": detector.model.state_dict(), "config": asdict(cfg), "classes": list(classes),
                    "train_seconds": trained[0], "n_scenes": len(scenes)}, partial)

    path = cached(Path(cache_dir) / f"detector_{key}.pt", train)
    if trained:
        return detector, {"train_seconds": trained[0], "cached": False, "path": str(path)}
    seconds = _load_cached(path, detector)
    return detector.eval(), {"train_seconds": seconds, "cached": True, "path": str(path)}


def _load_cached(path: Path, detector: ObjectDetector) -> float:
    """Load the weights :func:`load_or_train_detector` saved at ``path`` into ``detector``; the original training
    time. :class:`DataFileError` when the file is unreadable, not such a checkpoint, or one of other classes."""
    saved = load_torch(path)
    if not isinstance(saved, dict) or not {"state_dict", "train_seconds"} <= saved.keys():
        raise DataFileError(f"{path}: not a detector checkpoint of hrc_lab (no 'state_dict' and 'train_seconds')")
    if "classes" in saved and tuple(saved["classes"]) != detector.classes:
        raise DataFileError(f"{path}: a detector of the classes {list(saved['classes'])}, not of "
                            f"{list(detector.classes)}")
    load_weights(path, detector.model, saved["state_dict"])
    return saved["train_seconds"]
