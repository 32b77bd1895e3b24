"""From tracked frames to the detector's inputs (Sec. 5.2.1): the hand trajectory s of a window, the hand-centric
crop I at its last tracked frame (Eq. 5.2) and, for the ``cnn_lstm_video`` baseline, the downscaled frames.

:class:`WindowStream` cuts a live stream into windows as Algorithm 3 does: a window opens when the hand appears and
closes after ``window`` frames, or earlier when the hand has been gone for ``gap`` frames (then the missing start
of the track repeats its first position). A window's assembly label may only change the graph once the hand motion
has finished, i.e. the hand left the view before another window closed (:attr:`Window.finished`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hrc_lab.perception.hand_tracking import HandObservation


def fill_track(positions: np.ndarray) -> np.ndarray:
    """Linear interpolation over frames without a hand (NaN rows); the ends repeat the nearest tracked position."""
    positions = np.asarray(positions, float).copy()
    known = ~np.isnan(positions[:, 0])
    if not known.any():
        raise ValueError("fill_track: no frame of the window has a hand")
    t = np.arange(len(positions))
    for axis in range(2):
        positions[:, axis] = np.interp(t, t[known], positions[known, axis])
    return positions


def hand_crop(frame: np.ndarray, landmarks: np.ndarray, size: int, margin: float = 1.5) -> np.ndarray:
    """A square crop around the hand (``margin`` x the landmarks' larger extent), moved inside the image where it
    sticks out (landmarks may lie outside the frame), resized to ``size`` x ``size``."""
    h, w = frame.shape[:2]
    low, high = landmarks.min(axis=0), landmarks.max(axis=0)
    side = int(np.clip(margin * (high - low).max(), 16, min(h, w)))
    centre = (low + high) / 2
    x0 = int(np.clip(round(centre[0] - side / 2), 0, w - side))
    y0 = int(np.clip(round(centre[1] - side / 2), 0, h - side))
    return cv2.resize(frame[y0 : y0 + side, x0 : x0 + side], (size, size), interpolation=cv2.INTER_AREA)


def downscale_frames(frames: np.ndarray, size: int, stride: int) -> np.ndarray:
    """Every ``stride``-th frame, ending with the last one, resized to ``size`` x ``size`` (T', size, size, 3)."""
    chosen = frames[::-1][::stride][::-1]
    return np.stack([cv2.resize(f, (size, size), interpolation=cv2.INTER_AREA) for f in chosen])


@dataclass
class WindowFeatures:
    """The detector's inputs for one window: track (T, 2) in [0, 1], crop (S, S, 3) and frames (T', F, F, 3)."""

    track: np.ndarray
    crop: np.ndarray
    frames: np.ndarray
    tracked: float  # fraction of the window's frames with a hand


def window_features(frames: np.ndarray, observations: list[HandObservation | None], window: int, crop_size: int,
                    frame_size: int, frame_stride: int) -> WindowFeatures | None:
    """Features of a window of at most ``window`` frames (shorter ones are front-padded); None without a hand."""
    h, w = frames.shape[1:3]
    positions = np.array([o.position(w, h) if o is not None else [np.nan, np.nan] for o in observations])
    if np.isnan(positions[:, 0]).all():
        return None
    track = fill_track(positions)
    last = max(i for i, o in enumerate(observations) if o is not None)
    crop = hand_crop(frames[last], observations[last].landmarks, crop_size)
    if len(track) < window:  # a short window: the hand held still before it
        pad = window - len(track)
        track = np.concatenate([np.repeat(track[:1], pad, 0), track])
        frames = np.concatenate([np.repeat(frames[:1], pad, 0), frames])
    return WindowFeatures(
        track=track[-window:].astype(np.float32),
        crop=crop,
        frames=downscale_frames(frames[-window:], frame_size, frame_stride),
        tracked=float(np.mean([o is not None for o in observations])),
    )


@dataclass
class Window:
    """A closed window of a stream: its frame range [start, end), features, and whether the hand left after it."""

    start: int
    end: int
    features: WindowFeatures
    finished: bool = False
    label: str | None = None  # what the detector called it


class WindowStream:
    """Feed frames one by one with :meth:`push`; it returns the windows that closed at that frame (Algorithm 3).
    A window closes after ``window`` frames or when the hand has been gone for ``gap`` frames; windows with fewer
    than ``min_frames`` tracked frames are dropped. :meth:`push` also marks the previous window ``finished`` when
    the hand leaves before the next window closes."""

    def __init__(self, window: int, crop_size: int, frame_size: int, frame_stride: int, gap: int = 3,
                 min_frames: int = 15) -> None:
        self.window, self.gap, self.min_frames = window, gap, min_frames
        self.sizes = (crop_size, frame_size, frame_stride)
        self._frames: list[np.ndarray] = []
        self._observations: list[HandObservation | None] = []
        self._start = 0
        self._missing = 0
        self._index = 0
        self.last: Window | None = None

    def push(self, frame: np.ndarray, observation: HandObservation | None) -> tuple[Window | None, Window | None]:
        """(a window that closed now or None, the previous window if the hand just left after it, else None)."""
        index, self._index = self._index, self._index + 1
        closed = finished = None
        if observation is None:
            self._missing += 1
            if self._missing == self.gap:
                if self._frames:
                    closed = self._close(index + 1 - self.gap, trim=self.gap - 1)
                if self.last is not None and not self.last.finished:
                    self.last.finished = True
                    finished = self.last
            elif self._frames:
                self._frames.append(frame)
                self._observations.append(None)
            return closed, finished
        self._missing = 0
        if not self._frames:
            self._start = index
        self._frames.append(frame)
        self._observations.append(observation)
        if len(self._frames) == self.window:
            closed = self._close(index + 1, trim=0)
        return closed, finished

    def _close(self, end: int, trim: int) -> Window | None:
        frames, observations = self._frames, self._observations
        if trim:
            frames, observations = frames[:-trim], observations[:-trim]
        self._frames, self._observations = [], []
        if sum(o is not None for o in observations) < self.min_frames:
            return None
        features = window_features(np.stack(frames), observations, self.window, *self.sizes)
        self.last = Window(self._start, end, features)
        return self.last
