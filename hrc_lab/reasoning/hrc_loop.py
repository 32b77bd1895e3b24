"""Algorithm 3 (Sec. 5.2.3) as an event loop over action labels, without the camera: the action detector of a later
issue feeds it the same labels from video.

- An assembly action "o_i->p_j" adds an edge to the assembly graph; the planner infers the goal and prints the
  Semantic Guidance of every part type.
- fetch and transport are intermediate motions and change nothing.
- screw hands the next part to the robot: the planner's Semantic Control [o_next, p, ...] becomes a
  ``PickandPlace(o_next, p)`` call, and whatever the robot reports it placed is added to the graph.

``human`` (optional) hears of every human placement the loop records, e.g. the robot cell, which puts the part
there (:meth:`hrc_lab.env.robot.assembly_cell.AssemblyCell.human_place`).

``fix`` (optional; hrc_lab's recovery, beyond Algorithm 3, which never corrects a placement): after every plan, a
recorded pair that contradicts the inferred goal (the goal wants another part type on that position; two parts
recorded on one position) is dropped and ``fix(position, part)`` makes the goal's part sit there (the robot
clears the position and places it); the loop says so and plans again (the event's ``replan``). Only a goal that
agrees with most recorded pairs is trusted to fix the others, and each position is fixed at most once per session,
so a wrong goal guess cannot take down a right assembly or start a loop of removals. A worker's placement
recorded on a position that already holds the same part type cannot be (one of the two was read on the wrong
position): it is re-read as the nearest free position where the inferred goal wants that part.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from hrc_lab.env.assembly.spec import FINISHED, SCREW, AssembleToOrderSpec, parse_assembly, plan_text
from hrc_lab.reasoning.semantic_planner import Plan, SemanticPlanner

#: PickandPlace(part, position) -> the (part, position) the robot actually placed, or None if it placed nothing
PickAndPlace = Callable[[str, int], tuple[str, int] | None]
#: Fix(position, part) -> the (part, position) now on that position, or None if the robot could not fix it
Fix = Callable[[int, str], tuple[str, int] | None]


@dataclass
class Recovery:
    """One recovery: the recorded pair that contradicted goal ``goal``, the part the goal wants there, and what the
    position holds after the fix (None: the fix failed); or, ``reread``, a worker's placement recorded on a
    position that already held that part, re-read as ``placed``."""

    wrong: tuple[str, int]
    goal: int
    wanted: str
    placed: tuple[str, int] | None
    reread: bool = False

    def describe(self) -> str:
        part, position = self.wrong
        if self.reread:
            return (f"recovery: p{position} already holds {part}; the worker's {part} read as p{self.placed[1]}, "
                    f"where goal g{self.goal} needs one")
        outcome = f"now {self.placed[0]} on p{self.placed[1]}" if self.placed else "the robot could not fix it"
        return f"recovery: p{position} holds {part}, goal g{self.goal} needs {self.wanted} there -> {outcome}"


@dataclass
class LoopEvent:
    label: str
    plan: Plan
    command: tuple[str, int] | None = None  # the PickandPlace call made on a screw event
    recoveries: list[Recovery] = field(default_factory=list)
    replan: Plan | None = None  # the plan after the recoveries (``plan`` stays the one the event acted on)

    def describe(self) -> str:
        guidance = " | ".join(plan_text(tokens) for tokens in self.plan.guidance.values())
        text = f"[{self.label}] goal g{self.plan.goal} | guidance: {guidance}"
        if self.label == SCREW:
            text += f" | control: {plan_text(self.plan.control)}"
            text += (
                f" -> PickandPlace({self.command[0]}, p{self.command[1]})" if self.command else " -> nothing to place"
            )
        lines = [text, *(r.describe() for r in self.recoveries)]
        if self.replan is not None:
            lines.append(f"re-planned: goal g{self.replan.goal} | control: {plan_text(self.replan.control)}")
        return "\n".join(lines)


class SemanticPlannerLoop:
    def __init__(
        self,
        planner: SemanticPlanner,
        robot: PickAndPlace,
        echo: Callable[[str], None] | None = print,
        human: Callable[[str, int], object] | None = None,
        fix: Fix | None = None,
    ) -> None:
        self.planner = planner
        self.spec: AssembleToOrderSpec = planner.spec
        self.robot = robot
        self.human = human
        self.fix = fix
        self.echo = echo
        self.pairs: list[tuple[str, int]] = []
        self.fixed: set[int] = set()  # positions fixed so far (at most once each)

    @property
    def assembled(self) -> set[int]:
        return {position for _, position in self.pairs}

    @property
    def finished(self) -> bool:
        return len(self.assembled) == self.spec.n_positions

    def step(self, label: str) -> LoopEvent | None:
        """Consume one action label; return what the planner said, or None for fetch and transport."""
        assembly = parse_assembly(label)
        reread = None
        if assembly is not None:
            if self.fix is not None and assembly in self.pairs:
                assembly, reread = self._reread(assembly)
            self.pairs.append(assembly)
            if self.human is not None:
                self.human(*assembly)
            event = LoopEvent(label, self.planner.plan([self.pairs])[0])
            if reread is not None:
                event.recoveries.append(reread)
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
        if self.fix is not None:
            self._recover(event)
        if self.echo:
            self.echo(event.describe())
        return event

    def contradictions(self, goal: int) -> list[tuple[str, int]]:
        """The recorded pairs goal ``goal`` does not have: another part type on their position."""
        wanted = self.spec.goal(goal)
        return [(part, position) for part, position in self.pairs if wanted[position - 1] != part]

    def _reread(self, assembly: tuple[str, int]) -> tuple[tuple[str, int], Recovery | None]:
        """A worker's placement of ``part`` on a position the record already gives that part: one of the two was
        read on the wrong position (adjacent positions are the detector's usual confusion), so the new one is read
        as the free position nearest to it where the inferred goal wants ``part``; unchanged if there is none."""
        part, position = assembly
        goal = self.planner.plan([self.pairs])[0].goal
        wanted = self.spec.goal(goal)
        free = [q for q in range(1, self.spec.n_positions + 1) if q not in self.assembled and wanted[q - 1] == part]
        if not free:
            return assembly, None
        nearest = min(free, key=lambda q: (abs(q - position), q))
        return (part, nearest), Recovery(assembly, goal, part, (part, nearest), reread=True)

    def _recover(self, event: LoopEvent) -> None:
        """Fix every contradiction of the event's inferred goal once per position, then plan again; nothing when the
        goal contradicts as many recorded pairs as it agrees with (then the guess, not the assembly, is wrong: in a
        measured run a transient wrong goal had the robot take down four right parts)."""
        goal = event.plan.goal
        wrong = self.contradictions(goal)
        if 2 * len(wrong) >= len(self.pairs):
            return
        fixes = []
        for part, position in wrong:
            if position in self.fixed:
                continue
            self.fixed.add(position)
            wanted = self.spec.goal(goal)[position - 1]
            self.pairs = [pair for pair in self.pairs if pair[1] != position]
            placed = self.fix(position, wanted)
            if placed is not None:
                self.pairs.append(placed)
            fixes.append(Recovery((part, position), goal, wanted, placed))
        if fixes:
            event.recoveries.extend(fixes)
            event.replan = self.planner.plan([self.pairs])[0]

    def run(self, labels: Iterable[str]) -> list[LoopEvent]:
        events = [self.step(label) for label in labels]
        return [e for e in events if e is not None]
