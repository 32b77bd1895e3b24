"""Package-to-order cell of Ch.4 (thesis 4.3, Fig. 4.5): products in a pending area, a packaging box, an order.

Scenes come from the simulator-independent spec and sampler of :mod:`hrc_lab.env.robot.spec`, so the robot
meets exactly the scenes the reasoning module learned on. Per episode a goal configuration is drawn (from all
mCn x n! or from a given list), then :func:`sample_episode` draws product positions and, for CASE 2, the products a
simulated human packs first (placed into their slots one by one before the robot starts). With ``n_missing`` some
products are absent at the start and restocked into their pending cells once everything present is packed (4.4.5).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from hrc_lab.env.robot.cell import CellObject, HRCCell  # first: it imports robosuite quietly

# isort: split
from robosuite.utils.observables import Observable, sensor

from hrc_lab.env.robot.spec import (
    Episode,
    GoalConfiguration,
    PackageToOrderSpec,
    expert_order,
    goal_configurations,
    sample_episode,
)

PRODUCT_COLOURS = [
    (0.85, 0.33, 0.10, 1), (0.93, 0.69, 0.13, 1), (0.47, 0.67, 0.19, 1), (0.30, 0.75, 0.93, 1),
    (0.49, 0.18, 0.56, 1), (0.64, 0.08, 0.18, 1), (0.00, 0.45, 0.74, 1), (0.60, 0.60, 0.60, 1),
]
WALL_HEIGHT = 0.05  # above the box floor; a product held at lift height clears it
WALL_THICKNESS = 0.01
BOX_MARGIN = 0.035  # free floor between the outermost slot's product and the wall


class PackageToOrder(HRCCell):
    """n-of-m packaging with a UR5e and a suction cup; CASE 1/2 and missing products as in the thesis."""

    def __init__(
        self,
        spec: PackageToOrderSpec | None = None,
        case: int = 1,
        n_missing: int = 0,
        configurations: list[GoalConfiguration] | None = None,
        **cell_kwargs,
    ) -> None:
        self.spec = spec or PackageToOrderSpec()
        if case not in (1, 2):
            raise ValueError(f"env.case must be 1 or 2, got {case}")
        self.case = case
        self.n_missing = n_missing
        self.configurations = list(configurations) if configurations else goal_configurations(self.spec)
        self.episode: Episode | None = None
        self.restocked = False
        self.transit_height = self.spec.lift_height  # the placing-stage height the reasoning module sees
        half = self.spec.product_size / 2
        objects = [
            CellObject(f"product{i + 1}", (half, half, half), PRODUCT_COLOURS[i % len(PRODUCT_COLOURS)])
            for i in range(self.spec.n_objects)
        ]
        super().__init__(objects, **cell_kwargs)

    # --- model -------------------------------------------------------------------------------------------------

    def box_half_extent(self) -> np.ndarray:
        """Half extent (x, y) of the box's free floor inside its walls, m."""
        offsets = self.spec.slot_offsets()
        return np.abs(offsets).max(axis=0) + self.spec.product_size / 2 + BOX_MARGIN

    def _add_fixtures(self, arena) -> None:
        half = self.box_half_extent()
        t, h, floor = WALL_THICKNESS / 2, WALL_HEIGHT / 2, self.spec.box_floor / 2
        x, y = self.spec.box_center
        box = ET.Element("body", name="box", pos=f"{x} {y} {self.spec.table_z}")
        colour = "0.55 0.70 0.90 1"
        geoms = [
            ("box_floor", (0, 0, floor), (half[0] + 2 * t, half[1] + 2 * t, floor)),
            ("box_wall_n", (0, half[1] + t, 2 * floor + h), (half[0] + 2 * t, t, h)),
            ("box_wall_s", (0, -half[1] - t, 2 * floor + h), (half[0] + 2 * t, t, h)),
            ("box_wall_e", (half[0] + t, 0, 2 * floor + h), (t, half[1], h)),
            ("box_wall_w", (-half[0] - t, 0, 2 * floor + h), (t, half[1], h)),
        ]
        for name, pos, size in geoms:
            box.append(ET.Element("geom", name=name, type="box", pos=" ".join(map(str, pos)),
                                  size=" ".join(map(str, size)), rgba=colour, group="0"))
            box.append(ET.Element("geom", name=f"{name}_vis", type="box", pos=" ".join(map(str, pos)),
                                  size=" ".join(map(str, size)), rgba=colour, group="1", contype="0", conaffinity="0"))
        arena.worldbody.append(box)

    def _setup_references(self) -> None:
        super()._setup_references()
        model = self.sim.model._model
        self._box_body = model.body("box").id
        self._box_floor_geoms = {model.geom("box_floor").id}

    def allowed_supports(self, index: int) -> set[int]:
        return self._table_geoms | self._box_floor_geoms

    def _setup_observables(self):
        observables = super()._setup_observables()

        @sensor(modality="object")
        def box_pos(obs_cache):
            return self.box_position()

        observables["box_pos"] = Observable(name="box_pos", sensor=box_pos, sampling_rate=self.control_freq)
        return observables

    def box_position(self) -> np.ndarray:
        """Centre of the box floor's top face (the packaging-area position p of Fig. 4.4)."""
        return self.sim.data.xpos[self._box_body] + np.array([0.0, 0.0, self.spec.box_floor])

    # --- episode -----------------------------------------------------------------------------------------------

    def _sample_scene(self) -> None:
        spec, rng = self.spec, self.np_random
        configuration = self.configurations[int(rng.integers(len(self.configurations)))]
        episode = sample_episode(spec, configuration, rng, case=self.case, n_missing=self.n_missing)
        box_xy = episode.slot_positions[:, :2].mean(axis=0) - spec.slot_offsets().mean(axis=0)
        self.sim.model.body_pos[self._box_body][:2] = box_xy
        self.episode = episode
        self.restocked = not episode.missing
        for i in range(spec.n_objects):
            if i in episode.missing:
                self.set_object_pose(i, self.PARK + np.array([0.0, 0.1 * i, 0.0]))
            else:
                self.set_object_pose(i, episode.positions[i])
        for product in episode.human_order:  # the simulated human packs these, one by one, before the robot
            self.set_object_pose(product, episode.packed_positions[product])
        self.goals = np.where(episode.goal_slot[:, None] >= 0, episode.packed_positions, episode.positions)

    def task_objects(self) -> list[int]:
        return [p for p, _ in self.episode.configuration]

    def expert_plan(self) -> list[int]:
        """CASE 1 structure: lowest-numbered selected product first, skipping what the human packed."""
        return expert_order(self.episode)

    def _after_step(self) -> None:
        """Restock the missing products once every present selected product is packed (thesis 4.4.5)."""
        if self.restocked or self.suction.held >= 0:
            return
        present = [p for p in self.task_objects() if p not in self.episode.missing]
        distances = np.linalg.norm(self.object_positions()[present] - self.goals[present], axis=1)
        if np.all(distances <= self.success_threshold):
            for product in self.episode.missing:
                self.set_object_pose(product, self.episode.positions[product])
            self.restocked = True
            self.sim.forward()

    # --- observations ------------------------------------------------------------------------------------------

    def present(self) -> np.ndarray:
        present = np.ones(self.spec.n_objects, dtype=bool)
        if not self.restocked:
            present[list(self.episode.missing)] = False
        return present

    def structured_observation(self) -> dict[str, np.ndarray | int]:
        """What the reasoning and motion modules consume (Fig. 4.2-4.4): product positions (NaN when absent), the
        selection flags I, packed flags, the goal slot of each product, box and slot positions, the end effector r,
        the stage (0 picking, 1 placing) and the held product."""
        positions = self.object_positions()
        present = self.present()
        packed = np.zeros(self.spec.n_objects, dtype=bool)
        selected = self.episode.goal_slot >= 0
        packed[selected] = np.linalg.norm(positions[selected] - self.goals[selected], axis=1) <= self.success_threshold
        held = self.suction.held
        if held >= 0:
            packed[held] = False
        return {
            "positions": np.where(present[:, None], positions, np.nan),
            "present": present,
            "selected": selected,
            "packed": packed,
            "goal_slot": self.episode.goal_slot.copy(),
            "box_position": self.box_position(),
            "slot_positions": self.episode.slot_positions.copy(),
            "eef": self.eef_position(),
            "stage": int(held >= 0),
            "held": held,
        }
