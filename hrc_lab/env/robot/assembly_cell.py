"""Assemble-to-order robot cell of Ch.5 (thesis 5.2.3, 5.3, Figs. 5.8-5.10): the robot side of Algorithm 3.

The worker and the robot build one product on a bracket with six positions, p1 on the worker's right (+y) to p6
on the left, from typed parts waiting in bins (o1 x3, o2 x2, o3 x1 by default; ``env.product``). The cell is
built from the same spec as the semantic planner (``conf/env/ato*.yaml``, :class:`AssembleToOrderConfig`) plus
its layout (``env.robot``, :class:`~hrc_lab.env.robot.settings.AssemblyCellLayout`). The thesis used a UR10 with a
suction cup at a real bench; here the UR5e and suction cup of the Ch.3/Ch.4 cells (:mod:`hrc_lab.env.robot.cell`).
Parts are cuboids whose size and height differ by type; each has a flat top face, so the suction cup grips every
type (the thesis notes that other part shapes would need their own grasping strategy).

- :meth:`AssemblyCell.pick_and_place` is Algorithm 3's ``PickandPlace(o, p)``: the scripted expert of
  :mod:`hrc_lab.env.robot.expert` (designed sub-goals, damped least-squares joint steps, collision checks of
  the cell at every physics substep) picks the first part of type ``o`` left in its bin and puts it on ``p``. A
  placement succeeds when the part rests, released, within ``place_tolerance`` of ``p`` in x-y with no
  collision; every failure comes back with its reason, and a command that cannot be carried out (no ``o`` left,
  ``p`` occupied, ``o`` not allowed at ``p`` by Table 5.1) moves nothing.
- :meth:`AssemblyCell.human_place` is the worker's side: there is no human model, so when the perception
  pipeline records a human placement the part appears at its position (taken from its bin), and the robot works
  around it.
- :meth:`AssemblyCell.return_to_bin` takes a part off the bracket and back into its bin slot: hrc_lab's recovery
  from a wrong placement (``protocol.recovery``, not in Algorithm 3).
"""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hrc_lab.env.robot.cell import CellObject, HRCCell  # first: it imports robosuite quietly
from hrc_lab.env.robot.expert import ScriptedExpert
from hrc_lab.env.robot.settings import AssembleToOrderConfig

PART_COLOURS = {"o1": (0.15, 0.35, 0.85, 1), "o2": (0.93, 0.55, 0.13, 1), "o3": (0.30, 0.70, 0.25, 1)}
OTHER_COLOUR = (0.6, 0.6, 0.6, 1)
RELEASE = np.array([0.0, 0.0, 0.0, -1.0])
SETTLE_STEPS = 10  # control steps with the cup off after a placement, before it is scored (0.5 s at 20 Hz)
MOVED = 0.02  # a part farther than this from its bin slot has left the bin, m


@dataclass
class Placement:
    """The outcome of one PickandPlace(o, p) (or a human placement): ``reason`` is empty on success."""

    part: str
    position: int
    success: bool
    reason: str = ""
    index: int | None = None  # the cell object that was moved
    steps: int = 0  # control steps the robot spent
    sim_s: float = 0.0  # simulated seconds
    wall_s: float = 0.0
    error_m: float = float("nan")  # x-y distance of the part from the position when scored
    started_at: float = float("nan")  # time.perf_counter() at the first motion command (NaN: the robot never moved)


class AssemblyCell(HRCCell):
    """The Ch.5 cell: parts in bins, a bracket with ``n_positions`` positions, a UR5e with a suction cup."""

    def __init__(self, spec: AssembleToOrderConfig | None = None, **cell_kwargs) -> None:
        self.spec = spec or AssembleToOrderConfig()
        self.layout = self.spec.robot
        self.part_types = [part for part, count in self.spec.product.items() for _ in range(count)]
        ordinal = {part: 0 for part in self.spec.product}
        objects = []
        for part in self.part_types:
            ordinal[part] += 1
            half = tuple(self.layout.part_half_sizes[part])
            objects.append(CellObject(f"{part}_{ordinal[part]}", half, PART_COLOURS.get(part, OTHER_COLOUR)))
        self.assembled: dict[int, int] = {}  # position -> cell object on it
        self.bin_slots = np.zeros((len(objects), 3))
        self._plan: list[int] = []
        super().__init__(objects, **cell_kwargs)

    # --- model -------------------------------------------------------------------------------------------------

    def _bracket_centre(self) -> np.ndarray:
        ends = np.array([self.position_xy(1), self.position_xy(self.spec.n_positions)])
        return ends.mean(axis=0)

    def _add_fixtures(self, arena) -> None:
        layout, table_z = self.layout, self.table_offset[2]
        centre = self._bracket_centre()
        half_y = (self.spec.n_positions - 1) * layout.position_spacing / 2 + 0.05
        half_z = layout.bracket_thickness / 2
        bracket = ET.Element("body", name="bracket", pos=f"{centre[0]} {centre[1]} {table_z + half_z}")
        size = f"0.05 {half_y} {half_z}"
        bracket.append(ET.Element("geom", name="bracket_plate", type="box", size=size, rgba="0.7 0.7 0.72 1",
                                  group="0"))
        bracket.append(ET.Element("geom", name="bracket_plate_vis", type="box", size=size, rgba="0.7 0.7 0.72 1",
                                  group="1", contype="0", conaffinity="0"))
        for p in range(1, self.spec.n_positions + 1):  # position marks, visual only
            x, y = self.position_xy(p) - centre
            bracket.append(ET.Element("geom", name=f"mark_p{p}", type="cylinder", size=f"0.008 {half_z + 0.0005}",
                                      pos=f"{x} {y} 0", rgba="0.2 0.2 0.2 1", group="1", contype="0",
                                      conaffinity="0"))
        arena.worldbody.append(bracket)
        for part, count in self.spec.product.items():  # bin pads, visual only
            x, y = self.layout.bins[part]
            length = (count - 1) * self.layout.bin_spacing / 2 + 0.045
            pad = ET.Element("geom", name=f"bin_{part}", type="box", size=f"{length} 0.045 0.0005",
                             pos=f"{x + (count - 1) * self.layout.bin_spacing / 2} {y} {table_z + 0.0005}",
                             rgba=" ".join(str(c * 0.5 + 0.4) for c in PART_COLOURS.get(part, OTHER_COLOUR)[:3])
                             + " 1", contype="0", conaffinity="0", group="1")
            arena.worldbody.append(pad)

    def _setup_references(self) -> None:
        super()._setup_references()
        self._bracket_geoms = {self.sim.model._model.geom("bracket_plate").id}

    def allowed_supports(self, index: int) -> set[int]:
        return self._table_geoms | self._bracket_geoms

    # --- layout ------------------------------------------------------------------------------------------------

    def position_xy(self, position: int) -> np.ndarray:
        """x-y of bracket position ``position`` (1-based; p1 on the worker's right, +y)."""
        x, y = self.layout.bracket_p1
        return np.array([x, y - (position - 1) * self.layout.position_spacing])

    def position_pose(self, position: int, part: str) -> np.ndarray:
        """Where a part of type ``part`` rests on ``position``: its centre, m."""
        top = self.table_offset[2] + self.layout.bracket_thickness
        return np.array([*self.position_xy(position), top + self.layout.part_half_sizes[part][2]])

    # --- episode -----------------------------------------------------------------------------------------------

    def _sample_scene(self) -> None:
        rng, layout = self.np_random, self.layout
        seen = {part: 0 for part in self.spec.product}
        for i, part in enumerate(self.part_types):
            x, y = layout.bins[part]
            xy = np.array([x + seen[part] * layout.bin_spacing, y]) + rng.uniform(-1, 1, 2) * layout.bin_jitter
            seen[part] += 1
            self.bin_slots[i] = [*xy, self.table_offset[2] + layout.part_half_sizes[part][2]]
            self.set_object_pose(i, self.bin_slots[i])
        self.assembled = {}
        self._plan = []
        self.goals = self.bin_slots.copy()

    def task_objects(self) -> list[int]:
        return sorted(self.assembled.values())

    def expert_plan(self) -> list[int]:
        return list(self._plan)

    # --- state -------------------------------------------------------------------------------------------------

    def in_bin(self, part: str) -> list[int]:
        """The cell objects of type ``part`` still in their bin slots."""
        positions = self.object_positions()
        return [i for i, kind in enumerate(self.part_types)
                if kind == part and i not in self.assembled.values()
                and np.linalg.norm(positions[i] - self.bin_slots[i]) <= MOVED]

    def assembly(self) -> list[tuple[str, int]]:
        """The (part type, position) pairs on the bracket, by position."""
        return [(self.part_types[i], p) for p, i in sorted(self.assembled.items())]

    def refusal(self, part: str, position: int) -> str:
        """Why ``(part, position)`` cannot be carried out now, or "" when it can."""
        if part not in self.spec.product:
            return f"unknown part type {part} (env.product: {list(self.spec.product)})"
        if not 1 <= position <= self.spec.n_positions:
            return f"no position p{position} on the bracket (p1..p{self.spec.n_positions})"
        if position not in self.spec.allowed_positions[part]:
            return f"{part} cannot go to p{position} (Table 5.1 allows {self.spec.allowed_positions[part]})"
        if position in self.assembled:
            return f"p{position} is occupied by {self.part_types[self.assembled[position]]}"
        if not self.in_bin(part):
            return f"no {part} left in its bin"
        return ""

    # --- the two hands ------------------------------------------------------------------------------------------

    def human_place(self, part: str, position: int) -> Placement:
        """The worker put a ``part`` on ``position``: the first one left in its bin appears there (no human
        model). Refused (nothing moves) like a robot command."""
        reason = self.refusal(part, position)
        if reason:
            return Placement(part, position, False, reason)
        index = self.in_bin(part)[0]
        self.set_object_pose(index, self.position_pose(position, part))
        self.sim.forward()
        self.assembled[position] = index
        return Placement(part, position, True, index=index, error_m=0.0)

    def pick_and_place(self, part: str, position: int, max_steps: int = 400,
                       observer: Callable[[int], None] | None = None) -> Placement:
        """Algorithm 3's PickandPlace(o, p) by the scripted expert (module docstring); at most ``max_steps``
        control steps; ``observer(step)`` after every control step (e.g. to render a video)."""
        reason = self.refusal(part, position)
        if reason:
            return Placement(part, position, False, reason)
        index = self.in_bin(part)[0]
        placement = self._carry(index, self.position_pose(position, part), part, position, f"p{position}",
                                max_steps, observer)
        if placement.success:
            self.assembled[position] = index
        return placement

    def part_at(self, position: int) -> str | None:
        """The part type on ``position``, or None when it is free."""
        index = self.assembled.get(position)
        return None if index is None else self.part_types[index]

    def return_to_bin(self, position: int, max_steps: int = 400,
                      observer: Callable[[int], None] | None = None) -> Placement:
        """The robot takes the part off ``position`` and puts it back into its bin slot (hrc_lab's recovery from
        a wrong placement, :class:`~hrc_lab.reasoning.hrc_loop.SemanticPlannerLoop`; not in Algorithm 3). The
        :class:`Placement` names the part and the position it cleared; refused when the position is free."""
        index = self.assembled.get(position)
        if index is None:
            return Placement("", position, False, f"p{position} is free")
        part = self.part_types[index]
        placement = self._carry(index, self.bin_slots[index], part, position, f"its {part} bin", max_steps,
                                observer)
        if placement.success:
            del self.assembled[position]
        return placement

    def _carry(self, index: int, target: np.ndarray, part: str, position: int, where: str, max_steps: int,
               observer: Callable[[int], None] | None) -> Placement:
        """The scripted expert moves cell object ``index`` to rest at ``target`` (its centre); scored like a
        placement: released, within ``place_tolerance`` in x-y, resting at the target's height, no collision."""
        start, started, collisions = time.perf_counter(), float("nan"), len(self.collisions)
        self._plan = [index]
        self.goals[index] = target
        expert, steps, reason = ScriptedExpert(self), 0, ""
        while (step := expert.act()) is not None:
            if steps >= max_steps or self.done:
                reason = f"not placed within {steps} control steps"
                break
            if not steps:
                started = time.perf_counter()
            self.step(step.action)
            steps += 1
            if observer is not None:
                observer(steps)
            if len(self.collisions) > collisions:
                reason = f"collision ({self.collisions[collisions]})"
                break
        for _ in range(SETTLE_STEPS):  # the cup off: a released part lands before it is scored
            if self.done:
                break
            self.step(RELEASE)
            steps += 1
            if observer is not None:
                observer(steps)
        self._plan = []
        placed = self.object_positions()[index]
        error = float(np.linalg.norm(placed[:2] - target[:2]))
        if not reason and len(self.collisions) > collisions:
            reason = f"collision ({self.collisions[collisions]})"
        if not reason and error > self.layout.place_tolerance:
            reason = f"the part ended {error * 100:.1f} cm from {where}"
        if not reason and abs(placed[2] - target[2]) > 0.01:
            reason = f"the part does not rest on {where} (height off by {(placed[2] - target[2]) * 100:.1f} cm)"
        return Placement(part, position, not reason, reason, index, steps, steps / self.control_freq,
                         time.perf_counter() - start, error, started)
