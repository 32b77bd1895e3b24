"""Package-to-order task specification, independent of any simulator (thesis Sec. 4.3, Fig. 4.5-4.6).

m products wait in a pending area; a customer order selects n of them and assigns each to one goal slot of a
packaging box. A *goal configuration* is that assignment, so an n-of-m experiment with a box of n slots has
mCn x n! configurations (position-specified labels, Fig. 4.6). With more slots than selected products
(``n_slots > n_selected``, used by the varying-order-size scenario of 4.4.5) the count is mCn x n_slots!/(n_slots-n)!.

An :class:`Episode` is one trial: a configuration, sampled product positions and a task structure.

- CASE 1: the expert packs the lowest-numbered selected, available, unpacked product first.
- CASE 2: a simulated human first packs a random non-empty proper subset of the selected products in random
  order; the robot then continues with the CASE 1 structure.
- Missing products (4.4.5): some products are absent at the start; the robot packs what is there, the missing
  ones are restocked into their pending cells, and the robot finishes the order.

:func:`stage_observations` turns an episode into the observations the reasoning module sees at the start of every
picking and placing stage, each carrying its ground truth (P_o and P_g as class indices).
The robosuite environment builds its scenes from the same spec and sampler.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

PICK, PLACE = 0, 1


@dataclass(frozen=True)
class PackageToOrderSpec:
    """Geometry and order size of one n-of-m experiment. Lengths in metres, world frame (z up, table top at
    ``table_z``). Each product has its own pending cell along x (or, with ``pending_shuffle``, a random one per
    episode); positions jitter inside the cell."""

    n_objects: int = 5  # m
    n_selected: int = 4  # n
    n_slots: int | None = None  # goal slots in the box; None means n_selected (the thesis' setting)
    table_z: float = 0.8
    product_size: float = 0.04
    pending_origin: tuple[float, float] = (-0.16, -0.30)  # nominal x-y of product 1
    pending_spacing: float = 0.08  # along x between neighbouring products' cells
    pick_jitter: tuple[float, float] = (0.015, 0.075)  # +-x, +-y around a product's nominal position
    # each episode puts the products in a random permutation of the pending cells (then jitters them), so a
    # product's picking position spans the whole pending area: one reading of Table 4.1's "positions randomly
    # initialised within the pending area" (4.4.1) and of 4.4.3's 0.3 m in x. False: product i stays in cell i
    pending_shuffle: bool = False
    box_center: tuple[float, float] = (0.0, 0.30)
    # +-x, +-y of the whole box; fixed by default. Tables 4.1 and 4.2 set Sec. 4.4.3's ranges (0.135, 0.1: goal
    # spans of 0.35 x 0.2 m and more), Table 4.3 (0.1, 0.05); Fig. 4.7 and 4.4.5 keep it fixed
    box_jitter: tuple[float, float] = (0.0, 0.0)
    slot_spacing: float = 0.08
    box_floor: float = 0.01
    lift_height: float = 0.15  # height above the table of a product held at the start of a placing stage
    place_noise: float = 0.005  # +- error of a packed product around its slot

    def __post_init__(self) -> None:
        if self.n_objects < 1:
            raise ValueError(f"env.n_objects must be >= 1, got {self.n_objects}")
        if not 1 <= self.n_selected <= self.n_objects:
            raise ValueError(
                f"env.n_selected must be between 1 and env.n_objects={self.n_objects}, got {self.n_selected}"
            )
        if self.slots < self.n_selected:
            raise ValueError(f"env.n_slots={self.n_slots} must be >= env.n_selected={self.n_selected}")
        if 2 * self.pick_jitter[0] + self.product_size >= self.pending_spacing:
            raise ValueError(
                "env.pick_jitter[0] lets neighbouring products overlap; reduce it or widen env.pending_spacing"
            )

    @property
    def slots(self) -> int:
        return self.n_selected if self.n_slots is None else self.n_slots

    @property
    def cell(self) -> str:
        """The experiment's name in the thesis' tables, e.g. "4of5"."""
        return f"{self.n_selected}of{self.n_objects}"

    def slot_offsets(self) -> np.ndarray:
        """(n_slots, 2) slot positions relative to the box centre: one row up to 3 slots, else two rows."""
        cols = self.slots if self.slots <= 3 else math.ceil(self.slots / 2)
        rows = math.ceil(self.slots / cols)
        offsets = [
            ((c - (cols - 1) / 2) * self.slot_spacing, (r - (rows - 1) / 2) * self.slot_spacing)
            for r in range(rows)
            for c in range(cols)
        ]
        return np.asarray(offsets[: self.slots])

    def nominal_pending(self) -> np.ndarray:
        """(m, 2) nominal x-y position of every product's pending cell."""
        x0, y0 = self.pending_origin
        return np.asarray([(x0 + i * self.pending_spacing, y0) for i in range(self.n_objects)])


# Goal configurations ---------------------------------------------------------------------------------------------

GoalConfiguration = tuple[tuple[int, int], ...]  # ((product, slot), ...) sorted by product, 0-based


def combinations(spec: PackageToOrderSpec) -> list[tuple[int, ...]]:
    """The mCn product selections, in lexicographic order."""
    return list(itertools.combinations(range(spec.n_objects), spec.n_selected))


def configurations_of(spec: PackageToOrderSpec, selection: tuple[int, ...]) -> list[GoalConfiguration]:
    """Every assignment of the selected products to distinct slots (n! of them when n_slots == n)."""
    return [tuple(zip(selection, slots)) for slots in itertools.permutations(range(spec.slots), len(selection))]


def goal_configurations(spec: PackageToOrderSpec) -> list[GoalConfiguration]:
    """All mCn x n_slots!/(n_slots-n)! goal configurations, grouped by selection."""
    return [cfg for sel in combinations(spec) for cfg in configurations_of(spec, sel)]


def count_goal_configurations(spec: PackageToOrderSpec) -> int:
    return math.comb(spec.n_objects, spec.n_selected) * math.perm(spec.slots, spec.n_selected)


# Episodes --------------------------------------------------------------------------------------------------------


@dataclass
class Episode:
    """One trial: a goal configuration, the scene it starts from and the human's part in it."""

    spec: PackageToOrderSpec
    configuration: GoalConfiguration
    positions: np.ndarray  # (m, 3) pending positions of every product (restock position for missing ones)
    slot_positions: np.ndarray  # (n_slots, 3) where a packed product rests
    human_order: tuple[int, ...] = ()  # CASE 2: products the human packs first, in that order
    missing: tuple[int, ...] = ()  # products absent at the start and restocked once the rest is packed
    packed_positions: np.ndarray = field(init=False)  # (m, 3) where each product ends up if packed

    def __post_init__(self) -> None:
        self.packed_positions = np.full((self.spec.n_objects, 3), np.nan)

    @property
    def goal_slot(self) -> np.ndarray:
        """(m,) slot of every product, -1 where the product is not selected."""
        slot = np.full(self.spec.n_objects, -1)
        for product, s in self.configuration:
            slot[product] = s
        return slot


def sample_episode(
    spec: PackageToOrderSpec,
    configuration: GoalConfiguration,
    rng: np.random.Generator,
    case: int = 1,
    n_missing: int = 0,
) -> Episode:
    """Sample positions (and, for CASE 2, the human's packing order; with ``n_missing``, the absent products)."""
    if case not in (1, 2):
        raise ValueError(f"case must be 1 or 2, got {case}")
    m = spec.n_objects
    jitter = np.asarray(spec.pick_jitter)
    cells = spec.nominal_pending()
    if spec.pending_shuffle:
        cells = cells[rng.permutation(m)]
    xy = cells + rng.uniform(-jitter, jitter, size=(m, 2))
    positions = np.column_stack([xy, np.full(m, spec.table_z + spec.product_size / 2)])
    box = np.asarray(spec.box_center) + rng.uniform(-1, 1, size=2) * np.asarray(spec.box_jitter)
    slot_xy = box + spec.slot_offsets()
    slot_positions = np.column_stack(
        [slot_xy, np.full(spec.slots, spec.table_z + spec.box_floor + spec.product_size / 2)]
    )
    selection = [p for p, _ in configuration]
    human_order: tuple[int, ...] = ()
    if case == 2:
        if len(selection) < 2:
            raise ValueError("CASE 2 needs at least two selected products (the human packs a proper subset)")
        k = int(rng.integers(1, len(selection)))
        human_order = tuple(int(p) for p in rng.permutation(selection)[:k])
    missing: tuple[int, ...] = ()
    if n_missing:
        if n_missing >= m:
            raise ValueError(f"n_missing={n_missing} must be smaller than n_objects={m}")
        missing = tuple(sorted(int(p) for p in rng.choice(m, size=n_missing, replace=False)))
    episode = Episode(spec, configuration, positions, slot_positions, human_order, missing)
    noise = rng.uniform(-spec.place_noise, spec.place_noise, size=(m, 2))
    for product, slot in configuration:
        episode.packed_positions[product] = slot_positions[slot] + np.append(noise[product], 0.0)
    return episode


def position_ranges(episodes: list[Episode]) -> dict[str, float]:
    """The test conditions of Sec. 4.4.3 as they occur in ``episodes``: the span (max - min, metres) in x and y of
    the selected products' picking positions and of their goal positions, and the range of object-goal distances."""
    picks, goals = [], []
    for episode in episodes:
        for product, slot in episode.configuration:
            picks.append(episode.positions[product])
            goals.append(episode.slot_positions[slot])
    picks, goals = np.asarray(picks), np.asarray(goals)
    distances = np.linalg.norm(picks - goals, axis=1)
    return {
        "pick_span_x_m": float(np.ptp(picks[:, 0])),
        "pick_span_y_m": float(np.ptp(picks[:, 1])),
        "goal_span_x_m": float(np.ptp(goals[:, 0])),
        "goal_span_y_m": float(np.ptp(goals[:, 1])),
        "object_goal_min_m": float(distances.min()),
        "object_goal_max_m": float(distances.max()),
    }


# Stage observations ----------------------------------------------------------------------------------------------


@dataclass
class StageObservation:
    """What the reasoning module sees at the start of one picking or placing stage, with its ground truth.

    ``o_label`` indexes P_o (m+1): 0 is the packaging area p (placing stage), 1+i is product i (picking stage).
    ``g_label`` indexes P_g (n_slots+1): 0 is the picking stage l_pi, 1+s is goal slot s (position-specified).
    ``order`` counts products already packed (the goal-order label of the GNN baseline of [74]).
    """

    positions: np.ndarray  # (m, 3); rows of absent products are NaN
    present: np.ndarray  # (m,) bool
    selected: np.ndarray  # (m,) bool, the feature I
    packed: np.ndarray  # (m,) bool
    goal_slot: np.ndarray  # (m,) int, -1 if not selected
    slot_positions: np.ndarray  # (n_slots, 3)
    stage: int  # PICK or PLACE
    target: int  # product handled in this stage
    held: int  # product in the gripper (placing stage) or -1
    order: int
    o_label: int
    g_label: int
    g_selected: np.ndarray  # (3,) goal position of the handled product

    def goal_of(self, product: int) -> np.ndarray:
        """Goal position of a product, zeros when it is not selected (a wrong pick has no goal)."""
        if 0 <= product < len(self.goal_slot) and self.goal_slot[product] >= 0:
            return self.slot_positions[self.goal_slot[product]]
        return np.zeros(3)


def expert_order(episode: Episode) -> list[int]:
    """The robot's packing order: lowest-numbered first among the available selected products not packed by the
    human; missing products after the restock."""
    todo = [p for p, _ in episode.configuration if p not in episode.human_order]
    available = [p for p in todo if p not in episode.missing]
    return available + [p for p in todo if p in episode.missing]


def stage_observations(episode: Episode) -> list[StageObservation]:
    """Replay the episode and record the observation and labels at the start of every robot stage (2 per product)."""
    spec = episode.spec
    m = spec.n_objects
    positions = episode.positions.copy()
    present = np.ones(m, dtype=bool)
    present[list(episode.missing)] = False
    packed = np.zeros(m, dtype=bool)
    for product in episode.human_order:
        positions[product] = episode.packed_positions[product]
        packed[product] = True
    goal_slot = episode.goal_slot
    selected = goal_slot >= 0

    observations = []
    for target in expert_order(episode):
        if not present[target]:  # everything available is packed: the missing products are restocked now
            present[:] = True
        for stage in (PICK, PLACE):
            view = np.where(present[:, None], positions, np.nan)
            held = target if stage == PLACE else -1
            if stage == PLACE:
                view[target, 2] = spec.table_z + spec.lift_height
            observations.append(
                StageObservation(
                    positions=view,
                    present=present.copy(),
                    selected=selected,
                    packed=packed.copy(),
                    goal_slot=goal_slot,
                    slot_positions=episode.slot_positions,
                    stage=stage,
                    target=target,
                    held=held,
                    order=int(packed.sum()),
                    o_label=0 if stage == PLACE else 1 + target,
                    g_label=1 + int(goal_slot[target]) if stage == PLACE else 0,
                    g_selected=episode.slot_positions[goal_slot[target]],
                )
            )
        positions[target] = episode.packed_positions[target]
        packed[target] = True
    return observations
