"""Assemble-to-order (ATO) domain of Ch.5 (Sec. 5.3, Table 5.1), pure Python.

A product is built from typed parts (o1 x3, o2 x2, o3 x1) on a bracket with six numbered positions. A goal
configuration says which part type goes to each position. Fig. 5.4 is not legible in the thesis' text, so the
default goals (:class:`AssembleToOrderSpec`) are our own, chosen so that every object-position pair of Table 5.1 is
used by at least one goal, o2's pairs are disjoint across goals and o3 sits at p1, p4, p5 in turn. Like the thesis'
goals, they share pairs (o1 at p2 in g0 and g1, o1 at p3 in g0 and g2, o1 at p6 in g1 and g2): a scene made only
of a shared pair cannot tell the goals apart, the thesis' main failure case.

- A *scenario* (5.4.2) is a partially assembled product: a goal and a non-empty, non-full set of assembled
  positions (the graph does not depend on the order they were assembled in): 2^6 - 2 = 62 per goal.
- The expert's task structure: the robot's next object is the part type of the first unassembled position from
  the right (the lowest position number) under the goal.
- The semantic plan of a part type lists its unassembled positions under the goal, "o1, p3, p4", or
  "o1, Finished" when none is left.
- Action labels follow Table 5.1: one per allowed (part type, position) pair, then fetch, transport, screw.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

FETCH, TRANSPORT, SCREW = "fetch", "transport", "screw"
FINISHED = "Finished"


def _default_goals() -> list[list[str]]:
    # position:  p1    p2    p3    p4    p5    p6
    return [
        ["o3", "o1", "o1", "o1", "o2", "o2"],  # g0
        ["o2", "o1", "o2", "o3", "o1", "o1"],  # g1
        ["o1", "o2", "o1", "o2", "o3", "o1"],  # g2
    ]


@dataclass
class AssemblyVideoSpec:
    """Camera, timing and the ranges every generated clip of the cell is sampled from (``env.video``: top-down
    videos of the cell with a rendered right hand for the Ch.5 perception; the videos themselves are made by
    :mod:`hrc_lab.env.assembly.video`)."""

    width: int = 320
    height: int = 240
    fps: int = 15  # thesis: 15 FPS camera
    window: int = 45  # frames per action segment (thesis: 45 at 15 FPS)
    # wrist to middle fingertip, px (MediaPipe finds hands under ~60 % of the frame height)
    hand_length: list[float] = field(default_factory=lambda: [85.0, 110.0])
    light: list[float] = field(default_factory=lambda: [0.8, 1.15])  # brightness gain of hand and scene
    # the motion takes 0.65 x window / speed frames, after a random delay
    speed: list[float] = field(default_factory=lambda: [0.85, 1.15])
    # fast sessions: each segment lasts window / speed frames and the hand is motion-blurred
    fast_speed: list[float] = field(default_factory=lambda: [1.8, 2.4])
    hand_blur: int = 9  # Gaussian kernel of the hand layer (the recipe MediaPipe detects)
    wobble_px: float = 4.0  # amplitude of the slow deviation from the minimum-jerk path
    jitter_px: float = 0.7  # per-frame tremor
    # hand out of view after a placement or a screw (5.2.3)
    gap_frames: list[int] = field(default_factory=lambda: [4, 10])
    camera_noise: float = 2.0  # std of per-pixel noise (grey levels)

    def __post_init__(self) -> None:
        if not (64 <= self.width <= 1920 and 64 <= self.height <= 1080):
            raise ValueError(f"env.video.width/height must be in 64..1920 x 64..1080, got {self.width}x{self.height}")
        for key in ("fps", "window"):
            if getattr(self, key) < 1:
                raise ValueError(f"env.video.{key} must be >= 1, got {getattr(self, key)}")
        for key in ("hand_length", "light", "speed", "fast_speed", "gap_frames"):
            lo_hi = getattr(self, key)
            if len(lo_hi) != 2 or not 0 < lo_hi[0] <= lo_hi[1]:
                raise ValueError(f"env.video.{key} must be [low, high] with 0 < low <= high, got {lo_hi}")
        if self.hand_length[1] > 0.6 * self.height:
            raise ValueError(f"env.video.hand_length must stay under 60 % of env.video.height, got {self.hand_length}")
        if self.hand_blur < 1 or self.hand_blur % 2 == 0:
            raise ValueError(f"env.video.hand_blur must be an odd kernel size >= 1, got {self.hand_blur}")


@dataclass
class AssembleToOrderSpec:
    """Part types and counts, positions, allowed pairs (Table 5.1) and goal configurations; the first ``n_goals``
    goals are in play."""

    product: dict[str, int] = field(default_factory=lambda: {"o1": 3, "o2": 2, "o3": 1})
    n_positions: int = 6
    allowed_positions: dict[str, list[int]] = field(
        default_factory=lambda: {"o1": [1, 2, 3, 4, 5, 6], "o2": [1, 2, 3, 4, 5, 6], "o3": [1, 4, 5]}
    )
    goals: list[list[str]] = field(default_factory=_default_goals)  # part type at positions p1 .. p6, per goal
    n_goals: int = 3  # the first n goals are in play
    video: AssemblyVideoSpec = field(default_factory=AssemblyVideoSpec)

    def __post_init__(self) -> None:
        if sum(self.product.values()) != self.n_positions:
            raise ValueError(f"env.product uses {sum(self.product.values())} parts for {self.n_positions} positions")
        if set(self.allowed_positions) != set(self.product):
            raise ValueError("env.allowed_positions must list exactly the part types of env.product")
        if not 1 <= self.n_goals <= len(self.goals):
            raise ValueError(
                f"env.n_goals must be between 1 and {len(self.goals)} (the goals defined), got {self.n_goals}"
            )
        for z, goal in enumerate(self.goals):
            if len(goal) != self.n_positions:
                raise ValueError(f"env.goals[{z}] has {len(goal)} entries for {self.n_positions} positions")
            counts = {t: goal.count(t) for t in self.product}
            if counts != dict(self.product) or set(goal) - set(self.product):
                raise ValueError(f"env.goals[{z}] uses {counts}, the product needs {dict(self.product)}")
            for position, part in enumerate(goal, start=1):
                if position not in self.allowed_positions[part]:
                    raise ValueError(f"env.goals[{z}]: {part} cannot go to p{position} (env.allowed_positions)")

    @property
    def types(self) -> list[str]:
        return list(self.product)

    @property
    def cell(self) -> str:
        return f"{self.n_goals}goal" + ("s" if self.n_goals > 1 else "")

    def goal(self, z: int) -> list[str]:
        return list(self.goals[z])


def action_labels(spec: AssembleToOrderSpec) -> list[str]:
    """Table 5.1: "o1->p1", ..., "o3->p5", then fetch, transport, screw (18 labels with the default spec)."""
    pairs = [f"{t}->p{p}" for t in spec.types for p in sorted(spec.allowed_positions[t])]
    return [*pairs, FETCH, TRANSPORT, SCREW]


def parse_assembly(label: str) -> tuple[str, int] | None:
    """("o1", 3) for "o1->p3"; None for fetch, transport and screw."""
    if "->p" not in label:
        return None
    part, position = label.split("->p")
    return part, int(position)


@dataclass(frozen=True)
class Scenario:
    """A goal and the set of assembled positions (1-based)."""

    goal: int
    assembled: frozenset[int]


def scenarios(spec: AssembleToOrderSpec) -> list[Scenario]:
    """Every partially assembled state of every goal in play: (2^n_positions - 2) x n_goals."""
    positions = range(1, spec.n_positions + 1)
    subsets = [frozenset(s) for k in range(1, spec.n_positions) for s in itertools.combinations(positions, k)]
    return [Scenario(z, s) for z in range(spec.n_goals) for s in subsets]


def assembled_pairs(spec: AssembleToOrderSpec, scenario: Scenario) -> list[tuple[str, int]]:
    goal = spec.goal(scenario.goal)
    return [(goal[p - 1], p) for p in sorted(scenario.assembled)]


def next_object(spec: AssembleToOrderSpec, scenario: Scenario) -> str:
    """The expert's choice: the part type of the lowest-numbered unassembled position."""
    first = min(set(range(1, spec.n_positions + 1)) - scenario.assembled)
    return spec.goal(scenario.goal)[first - 1]


def plan_tokens(spec: AssembleToOrderSpec, scenario: Scenario, part: str) -> list[str]:
    """The semantic plan of one part type as tokens: ["o1", "p3", "p4"] or ["o1", "Finished"]."""
    goal = spec.goal(scenario.goal)
    todo = [f"p{p}" for p in range(1, spec.n_positions + 1) if goal[p - 1] == part and p not in scenario.assembled]
    return [part, *(todo or [FINISHED])]


def plan_text(tokens: list[str]) -> str:
    return ", ".join(tokens)


def indistinguishable(spec: AssembleToOrderSpec, scenario: Scenario) -> list[Scenario]:
    """The scenarios of every goal whose assembled pairs are ``scenario``'s (itself included): what a planner that
    observes only the assembly cannot tell apart (every goal before the first placement)."""
    pairs = assembled_pairs(spec, scenario)
    same = (Scenario(z, scenario.assembled) for z in range(spec.n_goals))
    return [s for s in same if assembled_pairs(spec, s) == pairs]


def ambiguous_scenarios(spec: AssembleToOrderSpec) -> list[Scenario]:
    """Scenarios whose assembled pairs are the same as another goal's scenario: no planner can tell them apart."""
    return [s for s in scenarios(spec) if len(indistinguishable(spec, s)) > 1]


class HumanWorker:
    """A simulated human for whole sessions: assembles the goal's positions in a random order (fetch, transport,
    then the assembly action) and now and then screws instead, which hands the next part to the robot."""

    def __init__(self, spec: AssembleToOrderSpec, goal: int, rng: np.random.Generator, p_screw: float = 0.3):
        self.spec, self.goal, self.rng, self.p_screw = spec, goal, rng, p_screw

    def next_actions(self, assembled: set[int]) -> list[str]:
        """The human's next action labels given the positions assembled so far."""
        todo = sorted(set(range(1, self.spec.n_positions + 1)) - assembled)
        if assembled and self.rng.random() < self.p_screw:
            return [SCREW]
        position = int(self.rng.choice(todo))
        return [FETCH, TRANSPORT, f"{self.spec.goal(self.goal)[position - 1]}->p{position}"]
