"""Human-error correction cell of Ch.3 (thesis 3.3, Fig. 3.4-3.7, Table 3.1): green, blue and red cuboids.

The end goal (Fig. 3.5) is a row green - blue - red; green is the benchmark a human placed correctly, and the blue
and red goals are fixed offsets from it. The human's errors, from Table 3.1 and Fig. 3.11:

- ``one_object`` case 1: blue is left at a wrong place (red is correct); case 2: red is wrong (blue is correct).
- ``two_object`` case 1: blue occupies red's place and red lies elsewhere, so blue is corrected, then red;
  case 2: red occupies blue's place and blue lies elsewhere, so red first, then blue.
- ``place`` and ``stack`` (Fig. 3.4): blue starts at a fixed pose and goes to a target on the table, or on top of
  green.

Stage labels as in 3.3: 0 picking blue, 1 placing blue, 2 picking red, 3 placing red.
"""

from __future__ import annotations

import numpy as np

from hrc_lab.env.robot.cell import CellObject, HRCCell

GREEN, BLUE, RED = 0, 1, 2
HALF = (0.025, 0.025, 0.02)  # cuboid half sizes, m
TASKS = ("one_object", "two_object", "place", "stack")


class ErrorCorrection(HRCCell):
    """Correct the human's misplaced cuboids; ``task`` and ``case`` choose the scenario."""

    goal_spacing = 0.09  # between neighbouring goals along y
    green_nominal = np.array([0.0, 0.05])  # x-y of green's place
    green_jitter = np.array([0.06, 0.05])
    wrong_region = (np.array([-0.15, -0.36]), np.array([0.15, -0.12]))  # where a misplaced cuboid lies (x-y box)
    place_start = np.array([0.0, -0.25])  # fixed initial pose of the place/stack tasks (thesis: "fixed initial state")

    def __init__(self, task: str = "one_object", case: int = 1, **cell_kwargs) -> None:
        if task not in TASKS:
            raise ValueError(f"env.task must be one of {TASKS}, got '{task}'")
        if case not in (1, 2):
            raise ValueError(f"env.case must be 1 or 2, got {case}")
        self.task, self.case = task, case
        self.plan: list[int] = []
        objects = [
            CellObject("green", HALF, (0.2, 0.7, 0.2, 1)),
            CellObject("blue", HALF, (0.15, 0.3, 0.85, 1)),
            CellObject("red", HALF, (0.85, 0.15, 0.15, 1)),
        ]
        super().__init__(objects, **cell_kwargs)

    def stage_label(self, obj: int, stage: int) -> int:
        """Thesis 3.3 labels: 0 pick blue, 1 place blue, 2 pick red, 3 place red."""
        return 2 * (obj - 1) + stage

    def expert_plan(self) -> list[int]:
        return list(self.plan)

    def _table_point(self, xy: np.ndarray, below: int | None = None) -> np.ndarray:
        z = self.table_offset[2] + HALF[2]
        if below is not None:
            z = self.goals[below][2] + 2 * HALF[2]
        return np.array([xy[0], xy[1], z])

    def _wrong_place(self, avoid: list[np.ndarray]) -> np.ndarray:
        """A random spot in the misplaced region at least 0.1 m from the given points."""
        low, high = self.wrong_region
        for _ in range(100):
            xy = self.np_random.uniform(low, high)
            if all(np.linalg.norm(xy - a[:2]) >= 0.1 for a in avoid):
                return self._table_point(xy)
        raise RuntimeError("could not place a misplaced cuboid; widen ErrorCorrection.wrong_region")

    def _sample_scene(self) -> None:
        rng = self.np_random
        green_xy = self.green_nominal + rng.uniform(-self.green_jitter, self.green_jitter)
        step = np.array([0.0, self.goal_spacing])
        self.goals = np.array([self._table_point(green_xy + k * step) for k in range(3)])
        start = self.goals.copy()
        if self.task == "one_object":
            wrong = BLUE if self.case == 1 else RED
            start[wrong] = self._wrong_place(list(self.goals))
            self.plan = [wrong]
        elif self.task == "two_object":
            first, second = (BLUE, RED) if self.case == 1 else (RED, BLUE)
            start[first] = self.goals[second]  # occupies the other's place
            start[second] = self._wrong_place(list(self.goals))
            self.plan = [first, second]
        else:
            start[RED] = self._table_point(self.place_start + np.array([0.0, -0.12]))
            start[BLUE] = self._table_point(self.place_start)
            if self.task == "stack":
                self.goals[BLUE] = self._table_point(green_xy, below=GREEN)
            self.goals[RED] = start[RED]
            self.plan = [BLUE]
        for i, position in enumerate(start):
            self.set_object_pose(i, position)

    def task_objects(self) -> list[int]:
        return [GREEN, BLUE, RED]

    def allowed_supports(self, index: int) -> set[int]:
        supports = set(self._table_geoms)
        if self.task == "stack" and index == BLUE:
            supports |= self._object_geoms[GREEN]
        return supports

    def structured_observation(self) -> dict[str, np.ndarray | int]:
        """The 16-dim observation of 3.3 is ``positions`` (9) + ``eef`` (3) + the one-hot stage label (4)."""
        return {
            "positions": self.object_positions(),
            "goals": self.goals.copy(),
            "eef": self.eef_position(),
            "held": self.suction.held,
            "stage": int(self.suction.held >= 0),
        }
