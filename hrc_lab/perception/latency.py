"""Latency of the Ch.5 pipeline on this CPU (Fig. 5.6 metrics): MediaPipe tracking per frame and the action
detector per window, each the median of repeated timings."""

from __future__ import annotations

import time

import numpy as np

from hrc_lab.perception.action_detector import ActionDetector
from hrc_lab.perception.dataset import ActionSet, resized_images
from hrc_lab.perception.hand_tracking import HandTracker


def tracking_ms_per_frame(frames: np.ndarray, complexity: int) -> float:
    """Median ms MediaPipe (model ``complexity``) takes on a frame of ``frames``, the first (warm-up) left out."""
    with HandTracker(model_complexity=complexity) as tracker:
        times = []
        for frame in frames:
            start = time.perf_counter()
            tracker(frame)
            times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times[1:]))


def classify_ms(detector: ActionDetector, data: ActionSet, count: int) -> float:
    """Median ms the detector takes to classify one window, over the first ``count`` windows of ``data``."""
    cfg, times = detector.cfg, []
    for i in range(min(count, len(data))):
        crop, frames = resized_images(data.crops[i], cfg.crop_size), resized_images(data.frames[i], cfg.frame_size)
        start = time.perf_counter()
        detector.classify(data.tracks[i], crop, frames)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))
