"""MediaPipe hand tracking (Sec. 5.2.1, ref. [143]): the first stage of the action detector.

Uses the legacy ``mp.solutions.hands`` API of mediapipe 0.10.21, the newest release that bundles the hand models (no
download at run time). In video mode the palm detector runs only when the landmark tracker has lost the hand, which
makes a frame several times cheaper than in static mode. One hand is tracked: the assembly cell has one worker.
MediaPipe's handedness assumes a mirrored (selfie) image; the camera above the cell is not mirrored, so the label is
reported as MediaPipe gives it and never used to select the hand.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

os.environ.setdefault("GLOG_minloglevel", "2")  # MediaPipe's C++ logs every graph start on stderr


@dataclass(frozen=True)
class HandObservation:
    """The 21 landmarks in pixels (MediaPipe's order: wrist, thumb ... little finger, base to tip), the
    handedness label as MediaPipe gives it and its score."""

    landmarks: np.ndarray
    handedness: str
    score: float

    def position(self, width: int, height: int) -> np.ndarray:
        """s_t = (x_t, y_t): the landmarks' centroid, normalised by the image size (Sec. 5.2.1)."""
        return self.landmarks.mean(axis=0) / np.array([width, height], dtype=float)


class HandTracker:
    """``tracker(frame_rgb) -> HandObservation | None``; :meth:`reset` before an unrelated video."""

    def __init__(self, model_complexity: int = 0, min_detection_confidence: float = 0.5,
                 min_tracking_confidence: float = 0.5, static_image_mode: bool = False) -> None:
        import mediapipe as mp

        self._options = dict(
            static_image_mode=static_image_mode,
            max_num_hands=1,
            model_complexity=model_complexity,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )
        self._hands_class = mp.solutions.hands.Hands
        self._hands = self._hands_class(**self._options)

    def reset(self) -> None:
        self._hands.close()
        self._hands = self._hands_class(**self._options)

    def close(self) -> None:
        self._hands.close()

    def __enter__(self) -> HandTracker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, frame: np.ndarray) -> HandObservation | None:
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"HandTracker expects an RGB uint8 frame (H, W, 3), got {frame.dtype} {frame.shape}")
        result = self._hands.process(frame)
        if not result.multi_hand_landmarks:
            return None
        h, w = frame.shape[:2]
        points = np.array([[p.x * w, p.y * h] for p in result.multi_hand_landmarks[0].landmark])
        label = result.multi_handedness[0].classification[0]
        return HandObservation(points, label.label, float(label.score))

    def track(self, frames: np.ndarray) -> list[HandObservation | None]:
        """Observations of every frame of one video (the tracker is reset first)."""
        self.reset()
        return [self(frame) for frame in frames]
