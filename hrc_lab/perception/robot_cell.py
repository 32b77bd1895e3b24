"""The robot cell in Algorithm 3's video loop (thesis 5.2.3, Figs. 5.8-5.10): the cell as the loop's two hands,
and the side-by-side video of the worker and the cell.

:class:`CellHands` gives :class:`~hrc_lab.reasoning.hrc_loop.SemanticPlannerLoop` its ``robot`` (PickandPlace in the
:class:`~hrc_lab.env.robot.assembly_cell.AssemblyCell`; a refused or failed command asks for help and returns
nothing placed), its ``human`` (the worker's recorded placement appears in the cell) and, with recovery, its
``fix`` (clear a position and place the goal's part), and keeps what happened.
:class:`SideBySide` composes the worker's annotated frame with the rendered cell.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from hrc_lab.env.robot.assembly_cell import AssemblyCell, Placement
    from hrc_lab.env.robot.recorder import FrameRecorder

log = logging.getLogger("hrc_lab")


class SideBySide:
    """The side-by-side video: the worker's annotated frame | the robot cell (``view``, a
    :class:`~hrc_lab.env.robot.recorder.FrameRecorder` used for its ``frame()``), the cell re-rendered only when it
    changed; while the robot moves, every ``view.frame_skip``-th control step adds a frame with the worker's last
    annotated frame held."""

    def __init__(self, view: FrameRecorder, frames: list) -> None:
        self.view, self.frames = view, frames
        self.last: np.ndarray | None = None  # the worker's last annotated frame
        self.caption = ""
        self.cell_image = view.frame()

    def refresh(self) -> None:
        self.view.text = self.caption
        self.cell_image = self.view.frame()

    def add(self, worker: np.ndarray) -> None:
        self.last = worker
        self.frames.append(self.compose(worker, self.cell_image))

    def robot_step(self, step: int) -> None:
        if step % self.view.frame_skip == 0 and self.last is not None:
            self.view.text = "robot: moving"
            self.frames.append(self.compose(self.last, self.view.frame()))

    @staticmethod
    def compose(worker: np.ndarray, cell: np.ndarray) -> np.ndarray:
        if cell.shape[0] != worker.shape[0]:
            scale = worker.shape[0] / cell.shape[0]
            cell = cv2.resize(cell, (round(cell.shape[1] * scale), worker.shape[0]), interpolation=cv2.INTER_AREA)
        return np.hstack([worker, cell])


class CellHands:
    """The cell as the loop's robot and human (module docstring). Call :meth:`frame_started` before each frame
    is pushed through the pipeline: a command's latency runs from there to the robot's first motion command."""

    def __init__(self, cell: AssemblyCell, side: SideBySide | None = None) -> None:
        self.cell, self.side = cell, side
        self.placements: list[Placement] = []
        self.human_placements: list[Placement] = []
        self.removals: list[Placement] = []  # parts the recovery took back to their bins
        self.latency_s: list[float] = []
        self._frame_t = time.perf_counter()

    def frame_started(self) -> None:
        self._frame_t = time.perf_counter()

    def robot(self, part: str, position: int) -> tuple[str, int] | None:
        """PickandPlace(part, position): what the robot placed, or None (it asked for help)."""
        observer = self.side.robot_step if self.side is not None else None
        placement = self.cell.pick_and_place(part, position, observer=observer)
        self.placements.append(placement)
        if placement.steps:  # the robot moved
            self.latency_s.append(placement.started_at - self._frame_t)
        if self.side is not None:
            self.side.caption = f"robot: PickandPlace({part}, p{position}) " + (
                "done" if placement.success else f"help: {placement.reason}")
            self.side.refresh()
        if not placement.success:
            log.info("robot asks for help: PickandPlace(%s, p%d): %s", part, position, placement.reason)
        return (part, position) if placement.success else None

    def fix(self, position: int, part: str) -> tuple[str, int] | None:
        """hrc_lab's recovery (:class:`~hrc_lab.reasoning.hrc_loop.SemanticPlannerLoop`): make ``part`` sit on
        ``position``: the robot returns the part there to its bin (if another), then places ``part``. What the
        position holds afterwards, or None when a step failed (the robot asks for help)."""
        if self.cell.part_at(position) == part:
            return part, position
        if self.cell.part_at(position) is not None:
            observer = self.side.robot_step if self.side is not None else None
            removal = self.cell.return_to_bin(position, observer=observer)
            self.removals.append(removal)
            if self.side is not None:
                self.side.caption = f"robot: recovery, {removal.part} off p{position} " + (
                    "done" if removal.success else f"help: {removal.reason}")
                self.side.refresh()
            if not removal.success:
                log.info("robot asks for help: clearing p%d: %s", position, removal.reason)
                return None
        return self.robot(part, position)

    def human(self, part: str, position: int) -> None:
        """The worker placed ``part`` on ``position`` (as the loop recorded it)."""
        placement = self.cell.human_place(part, position)
        if not placement.success:
            log.info("the cell cannot hold the worker's %s at p%d: %s", part, position, placement.reason)
        self.human_placements.append(placement)
        if self.side is not None:
            self.side.refresh()

    def result(self, goal: list[str]) -> dict:
        """What happened: placements, human placements, latencies, the final assembly and whether it is ``goal``
        (the part type at p1, p2, ...)."""
        target = [(part, p) for p, part in enumerate(goal, start=1)]
        assembly = self.cell.assembly()
        return {"placements": self.placements, "human": self.human_placements, "removals": self.removals,
                "latency_s": self.latency_s, "assembly": assembly, "complete": assembly == target}
