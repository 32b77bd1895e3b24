"""Algorithm 3 on a video stream: MediaPipe tracking of every frame -> windows -> action detector -> the semantic
planner's event loop (:class:`hrc_lab.reasoning.hrc_loop.SemanticPlannerLoop`).

A screw window triggers the robot at once; an assembly window changes the graph only when the hand motion has
finished (the hand left the view before another window closed, 5.2.3); fetch and transport change nothing.
:func:`annotate` draws what the system saw and said on a frame (landmarks, crop box, action, plan);
:func:`annotate_frames` runs the pipeline on a whole video and annotates every frame.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cv2
import numpy as np
from tqdm import tqdm

from hrc_lab.env.assembly.spec import SCREW, parse_assembly, plan_text
from hrc_lab.perception.hand_tracking import HandObservation, HandTracker
from hrc_lab.perception.windows import Window, WindowStream
from hrc_lab.reasoning.hrc_loop import LoopEvent, SemanticPlannerLoop

if TYPE_CHECKING:
    from hrc_lab.perception.robot_cell import CellHands, SideBySide


@dataclass
class PipelineState:
    """What the pipeline knows after a frame: the hand, the windows so far and the planner's events."""

    observation: HandObservation | None = None
    windows: list[Window] = field(default_factory=list)
    events: list[tuple[int, LoopEvent]] = field(default_factory=list)  # (frame index, event)
    tracking_s: list[float] = field(default_factory=list)
    classify_s: list[float] = field(default_factory=list)


class ActionPipeline:
    """Feed RGB frames with :meth:`push`. ``loop`` may be None (detection only)."""

    def __init__(self, detector, labels: list[str], tracker: HandTracker, stream: WindowStream,
                 loop: SemanticPlannerLoop | None = None) -> None:
        self.detector, self.labels, self.tracker, self.stream, self.loop = detector, labels, tracker, stream, loop
        self.state = PipelineState()
        self._index = 0

    def push(self, frame: np.ndarray) -> PipelineState:
        index, self._index = self._index, self._index + 1
        start = time.perf_counter()
        observation = self.tracker(frame)
        self.state.tracking_s.append(time.perf_counter() - start)
        self.state.observation = observation
        closed, finished = self.stream.push(frame, observation)
        if closed is not None:
            start = time.perf_counter()
            f = closed.features
            label_index, _ = self.detector.classify(f.track, f.crop, f.frames)
            self.state.classify_s.append(time.perf_counter() - start)
            closed.label = self.labels[label_index]
            self.state.windows.append(closed)
            if closed.label == SCREW:
                self._step(index, SCREW)
        if finished is not None and finished.label is not None and parse_assembly(finished.label):
            self._step(index, finished.label)
        return self.state

    def _step(self, index: int, label: str) -> None:
        if self.loop is None or self.loop.finished:
            return
        event = self.loop.step(label)
        if event is not None:
            self.state.events.append((index, event))


def annotate(frame: np.ndarray, state: PipelineState, loop: SemanticPlannerLoop | None) -> np.ndarray:
    """A copy of ``frame`` (RGB) at double size with the landmarks, the last window's action and the current plan."""
    scale = 2
    out = cv2.resize(frame, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
    if state.observation is not None:
        points = state.observation.landmarks * scale
        for p in points:
            cv2.circle(out, (int(p[0]), int(p[1])), 2, (255, 255, 0), -1, cv2.LINE_AA)
        low, high = points.min(0), points.max(0)
        cv2.rectangle(out, (int(low[0]), int(low[1])), (int(high[0]), int(high[1])), (0, 255, 255), 1)
    lines = []
    if state.windows:
        lines.append(f"action: {state.windows[-1].label}")
    if loop is not None and state.events:
        plan = state.events[-1][1].plan
        lines.append(f"goal: g{plan.goal}")
        lines += [plan_text(tokens) for tokens in plan.guidance.values()]
        if state.events[-1][1].command:
            part, position = state.events[-1][1].command
            lines.append(f"robot: PickandPlace({part}, p{position})")
    for k, text in enumerate(lines):
        y = 18 + 16 * k
        cv2.putText(out, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(out, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def annotate_frames(detector, labels: list[str], loop: SemanticPlannerLoop | None, frames: Sequence[np.ndarray],
                    complexity: int, cell: CellHands | None = None,
                    side: SideBySide | None = None) -> tuple[list[np.ndarray], PipelineState, int]:
    """Every frame through the pipeline (MediaPipe model ``complexity``), each :func:`annotate`-d: the annotated
    frames, the final state and the number of frames with a hand. With the robot ``cell`` (the loop's hands) each
    frame's start is marked for its latency; with ``side`` (writing into the returned list) every frame is the
    worker's beside the cell, plus the robot's motion."""
    cfg = detector.cfg
    stream = WindowStream(cfg.window, cfg.crop_size, cfg.frame_size, cfg.frame_stride)
    out, hands = (side.frames if side is not None else []), 0
    with HandTracker(model_complexity=complexity) as tracker:
        pipeline = ActionPipeline(detector, labels, tracker, stream, loop)
        for frame in tqdm(frames, desc="annotate", unit="frame"):
            if cell is not None:
                cell.frame_started()
            state = pipeline.push(frame)
            hands += state.observation is not None
            if side is not None:
                side.add(annotate(frame, state, loop))
            else:
                out.append(annotate(frame, state, loop))
    return out, pipeline.state, hands
