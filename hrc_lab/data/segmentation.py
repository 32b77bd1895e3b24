"""Stage segmentation of demonstrations (thesis 3.3: "segmented according to objects' position with change point
detection in slope [132]") and re-sampling of each stage to a fixed number of sub-goals.

Every object's trajectory is split by PELT (ruptures) with the continuous piecewise-linear cost, i.e. at changes of
slope. Of the resulting segments, those where the object moves are its handling: the first moving segment is the
lift that ends the picking stage, the last one ends the placing stage. Picking starts where the previous object's
placing ended. The detected stages are then compared step by step with the expert's own labels.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import ruptures as rpt

from hrc_lab.motion.configs import SUBGOAL_PATHS

PICK, PLACE = 0, 1


@dataclass(frozen=True)
class Stage:
    obj: int
    stage: int  # PICK or PLACE
    start: int  # first step (inclusive)
    end: int  # last step (exclusive)


def moving_segments(trajectory: np.ndarray, penalty: float = 1e-4, min_speed: float = 1e-3) -> list[tuple[int, int]]:
    """[start, end) of the PELT segments (continuous linear cost) in which the object moves faster than
    ``min_speed`` metres per step."""
    if np.ptp(trajectory, axis=0).max() < 0.01:
        return []
    breakpoints = rpt.Pelt(model="clinear", min_size=2, jump=1).fit(trajectory).predict(pen=penalty)
    bounds = [0, *breakpoints]
    segments = []
    for start, end in zip(bounds[:-1], bounds[1:]):
        speed = np.linalg.norm(trajectory[end - 1] - trajectory[start]) / max(end - 1 - start, 1)
        if speed > min_speed:
            segments.append((start, end))
    return segments


def detect_stages(object_positions: np.ndarray, penalty: float = 1e-4, pick_ends: str = "lift") -> list[Stage]:
    """Picking and placing stages of every moved object, in time order, from (T, m, 3) object positions.

    ``pick_ends="lift"``: picking ends when the lift ends (the designed sub-goals of 4.3 put "grab and lift" in
    picking; the expert's labels follow it). ``pick_ends="contact"``: picking ends when the object starts to move,
    i.e. at the grip (a segmentation "according to objects' position" alone, 3.3).
    """
    if pick_ends not in ("lift", "contact"):
        raise ValueError(f"pick_ends must be 'lift' or 'contact', got '{pick_ends}'")
    handled = []
    for obj in range(object_positions.shape[1]):
        segments = moving_segments(object_positions[:, obj], penalty)
        if segments:
            handled.append((segments[0][0], obj, segments))
    stages, previous_end = [], 0
    for _, obj, segments in sorted(handled):
        lift_end, place_end = segments[0][1], segments[-1][1]
        if len(segments) == 1:  # one straight motion: no lift visible; split it in the middle
            lift_end = (segments[0][0] + segments[0][1]) // 2
        if pick_ends == "contact":
            lift_end = max(segments[0][0], previous_end + 1)
        stages.append(Stage(obj, PICK, previous_end, lift_end))
        stages.append(Stage(obj, PLACE, lift_end, place_end))
        previous_end = place_end
    return stages


def stage_labels(stages: list[Stage], length: int, label_of: Callable[[int, int], int]) -> np.ndarray:
    """Per-step labels of detected stages (-1 outside every stage)."""
    labels = np.full(length, -1)
    for s in stages:
        labels[s.start : s.end] = label_of(s.obj, s.stage)
    return labels


def agreement(detected: np.ndarray, expert: np.ndarray) -> float:
    """Share of steps where the detected stage label equals the expert's."""
    return float(np.mean(detected == expert))


def resample(points: np.ndarray, k: int) -> np.ndarray:
    """``k`` points evenly spaced in time along a stage's (L, 3) end-effector path, the last one at its end
    (thesis 3.3: "the time series data is re-sampled in order to keep their time length equal to 5")."""
    if len(points) == 0:
        raise ValueError("cannot resample an empty stage")
    times = np.linspace(0, len(points) - 1, k + 1)[1:]
    return np.stack([np.interp(times, np.arange(len(points)), points[:, d]) for d in range(points.shape[1])], 1)


def stage_subgoals(demo, label_of: Callable[[int, int], int], k: int, mode: str = "resample",
                   penalty: float = 1e-3, path: str = "eef") -> tuple[np.ndarray, np.ndarray]:
    """Segment a demo into stages and give every stage ``k`` sub-goals.

    ``mode="resample"`` (Ch.3): stages split where the object starts to move (picking ends at the grip, so its
    last sub-goal is the part's top face), each stage's end-effector path (``path``, a key of
    :data:`SUBGOAL_PATHS`; the commanded lip's one step earlier, as it leads the measured one by a step) re-sampled
    to ``k`` points.
    ``mode="designed"`` (Ch.4, k = 3): the designed sub-goals the expert recorded for that stage.
    Returns ``bounds`` (S, 4) rows of (object, stage, start, end) and ``subgoals`` (S, k, 3).
    """
    if mode not in ("resample", "designed"):
        raise ValueError(f"mode must be 'resample' or 'designed', got '{mode}'")
    if path not in SUBGOAL_PATHS:
        raise ValueError(f"sub-goal path must be one of {list(SUBGOAL_PATHS)}, got '{path}'")
    pick_ends = "contact" if mode == "resample" else "lift"
    stages = detect_stages(demo.obs["object_pos"].reshape(len(demo), -1, 3), penalty, pick_ends)
    key, lead = SUBGOAL_PATHS[path]  # a stage's path starts and ends ``lead`` steps earlier than the measured lip's
    lip = demo.obs[key]
    bounds, points = [], []
    for s in stages:
        if mode == "resample":
            stage_path = lip[min(s.start + 1 - lead, len(lip) - 1) : s.end + 1 - lead]
            if s.stage == PICK and pick_ends == "contact":  # end at the grip: the path's lowest point
                stage_path = stage_path[: int(np.argmin(stage_path[:, 2])) + 1]
            if len(stage_path) == 0:
                continue  # a change point at the stage's start (e.g. a part nudged as the cup arrives): no path
            points.append(resample(stage_path, k))
        else:
            steps = demo.stage_labels == label_of(s.obj, s.stage)
            targets = [demo.subgoals[steps & (demo.subgoal_indices == i)] for i in range(k)]
            if any(len(t) == 0 for t in targets):
                continue  # the expert skipped a sub-goal of this stage (timed out before it)
            points.append(np.stack([t[0] for t in targets]))
        bounds.append((s.obj, s.stage, s.start, s.end))
    return np.asarray(bounds, dtype=np.int64).reshape(-1, 4), np.asarray(points, dtype=np.float32).reshape(-1, k, 3)
