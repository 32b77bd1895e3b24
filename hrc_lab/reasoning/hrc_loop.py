"""Algorithm 3 (Sec. 5.2.3) as an event loop over action labels, without the camera: the action detector of a later
issue feeds it the same labels from video.

- An assembly action "o_i->p_j" adds an edge to the assembly graph; the planner infers the goal and prints the
  Semantic Guidance of every part type.
- fetch and transport are intermediate motions and change nothing.
- screw hands the next part to the robot: the planner's Semantic Control [o_next, p, ...] becomes a
  ``PickandPlace(o_next, p)`` call, and whatever the robot reports it placed is added to the graph.

``human`` (optional) hears of every human placement the loop records, e.g. the robot cell, which puts the part
there (:meth:`hrc_lab.env.robot.assembly_cell.AssemblyCell.human_place`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

from hrc_lab.env.assembly.spec import FINISHED, SCREW, AssembleToOrderSpec, parse_assembly, plan_text
from hrc_lab.reasoning.semantic_planner import Plan, SemanticPlanner

#: PickandPlace(part, position) -> the (part, position) the robot actually placed, or None if it placed nothing
PickAndPlace = Callable[[str, int], tuple[str, int] | None]


@dataclass
class LoopEvent:
    label: str
    plan: Plan
    command: tuple[str, int] | None = None  # the PickandPlace call made on a screw event

    def describe(self) -> str:
        guidance = " | ".join(plan_text(tokens) for tokens in self.plan.guidance.values())
        text = f"[{self.label}] goal g{self.plan.goal} | guidance: {guidance}"
        if self.label == SCREW:
            text += f" | control: {plan_text(self.plan.control)}"
            text += (
                f" -> PickandPlace({self.command[0]}, p{self.command[1]})" if self.command else " -> nothing to place"
            )
        return text


class SemanticPlannerLoop:
    def __init__(
        self,
        planner: SemanticPlanner,
        robot: PickAndPlace,
        echo: Callable[[str], None] | None = print,
        human: Callable[[str, int], object] | None = None,
    ) -> None:
        self.planner = planner
        self.spec: AssembleToOrderSpec = planner.spec
        self.robot = robot
        self.human = human
        self.echo = echo
        self.pairs: list[tuple[str, int]] = []

    @property
    def assembled(self) -> set[int]:
        return {position for _, position in self.pairs}

    @property
    def finished(self) -> bool:
        return len(self.assembled) == self.spec.n_positions

    def step(self, label: str) -> LoopEvent | None:
        """Consume one action label; return what the planner said, or None for fetch and transport."""
        assembly = parse_assembly(label)
        if assembly is not None:
            self.pairs.append(assembly)
            if self.human is not None:
                self.human(*assembly)
            event = LoopEvent(label, self.planner.plan([self.pairs])[0])
        elif label == SCREW:
            plan = self.planner.plan([self.pairs])[0]
            event = LoopEvent(label, plan)
            targets = [t for t in plan.control[1:] if t != FINISHED]
            if targets:
                event.command = (plan.control[0], int(targets[0][1:]))
                placed = self.robot(*event.command)
                if placed is not None:
                    self.pairs.append(placed)
        else:
            return None
        if self.echo:
            self.echo(event.describe())
        return event

    def run(self, labels: Iterable[str]) -> list[LoopEvent]:
        events = [self.step(label) for label in labels]
        return [e for e in events if e is not None]
