"""Config schemas of the robosuite cells (no simulator import: validating a config stays fast).

``conf/env/package_to_order*.yaml`` validate to :class:`PackageToOrderConfig` (the task spec the reasoning module
uses, plus a ``sim`` block for the robot cell), ``conf/env/error_correction*.yaml`` to
:class:`ErrorCorrectionConfig` and ``conf/env/ato*.yaml`` to :class:`AssembleToOrderConfig` (the Ch.5 spec plus
its robot cell).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrc_lab.env.assembly.spec import AssembleToOrderSpec
from hrc_lab.env.robot.spec import PackageToOrderSpec

EC_TASKS = ("one_object", "two_object", "place", "stack")
CELL_CAMERA = "cellview"  # every robot cell's camera facing the robot over the table (the worker's side)
YAW_ORDERS = ("narrowest", "smallest_turn")  # how ClutterCell.grasp_yaw ranks the clear approach yaws


@dataclass(frozen=True)
class SimSettings:
    """The robot cell: control rate, horizon, success threshold, action limits and the scenario case."""

    control_freq: int = 20  # Hz; one action per 50 ms
    physics_timestep: float = 0.005  # s per MuJoCo step (10 per action at 20 Hz)
    horizon: int = 1000  # control steps per episode
    success_threshold: float = 0.06  # delta_r of Eq. 3.6 / 4.7, m (Table 3.1 also scores at 0.08)
    max_joint_step_deg: float = 5.0  # per-step joint delta limit (thesis 4.4.3: -5 ... 5 deg)
    yaw_action: bool = False  # add a wrist-3 delta to the action (DRL agent of 3.3)
    disable_effector_on_collision: bool = False  # DRL setting of 3.3
    # the cup also grips at the end of a control step when suction is on and the lip touches a top face (issue 20);
    # off: it grips only when the command is applied, before the arm moves (a lip that reaches the face during a
    # step grips one step later)
    grip_after_step: bool = False
    # the cell runs MuJoCo's substeps itself with robosuite's JOINT_POSITION control law instead of robosuite's step
    # and its per-substep controller/observable bookkeeping: the same physics bit for bit (tests/test_sim_cells.py),
    # 2.4-2.7x the control steps/s of the DRL goal env and ~3x the cell's own (scripts/bench_cell_step.py, 2 shared
    # cores: 86 -> 206-228 steps/s); off: robosuite's ManipulationEnv.step
    lean_step: bool = True
    # CASE 1 / CASE 2 of the scenario. package_to_order: 1 robot alone, 2 a simulated human packs a random subset
    # first; error_correction one_object: 1 blue wrong, 2 red wrong; two_object: 1 blue on red's place, 2 red on blue's
    case: int = 1
    n_missing: int = 0  # products absent at the start, restocked later (package_to_order, 4.4.5)

    def __post_init__(self) -> None:
        if self.control_freq < 1:
            raise ValueError(f"env.sim.control_freq must be >= 1, got {self.control_freq}")
        substeps = 1.0 / (self.control_freq * self.physics_timestep) if self.physics_timestep > 0 else 0.0
        if not 0 < self.physics_timestep <= 0.01 or abs(substeps - round(substeps)) > 1e-6:
            raise ValueError(
                f"env.sim.physics_timestep must be in (0, 0.01] s and divide the control period "
                f"1/{self.control_freq} s, got {self.physics_timestep}"
            )
        if self.horizon < 1:
            raise ValueError(f"env.sim.horizon must be >= 1, got {self.horizon}")
        if not 0 < self.success_threshold < 0.5:
            raise ValueError(f"env.sim.success_threshold must be in (0, 0.5) m, got {self.success_threshold}")
        if not 0 < self.max_joint_step_deg <= 30:
            raise ValueError(f"env.sim.max_joint_step_deg must be in (0, 30], got {self.max_joint_step_deg}")
        if self.case not in (1, 2):
            raise ValueError(f"env.sim.case must be 1 or 2, got {self.case}")
        if self.n_missing < 0:
            raise ValueError(f"env.sim.n_missing must be >= 0, got {self.n_missing}")


@dataclass(frozen=True)
class PackageToOrderConfig(PackageToOrderSpec):
    """The package-to-order spec plus the robot cell settings (``sim``: robosuite UR5e + suction cup,
    :mod:`hrc_lab.env.robot.factory`; unused by the reasoning-only experiments)."""

    sim: SimSettings = field(default_factory=SimSettings)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.sim.n_missing >= self.n_objects:
            raise ValueError(f"env.sim.n_missing={self.sim.n_missing} must be smaller than env.n_objects")
        if self.sim.case == 2 and self.n_selected < 2:
            raise ValueError("env.sim.case=2 needs env.n_selected >= 2 (the human packs a proper subset)")

    @property
    def scenario(self) -> str:
        """The cell plus the robot-cell case when it is not the default (``4of5``, ``4of5_case2_missing1``)."""
        case = f"_case{self.sim.case}" if self.sim.case != 1 else ""
        missing = f"_missing{self.sim.n_missing}" if self.sim.n_missing else ""
        return f"{self.cell}{case}{missing}"


@dataclass(frozen=True)
class ErrorCorrectionConfig:
    """Ch.3 error correction: ``task`` one_object | two_object | place | stack (case 1 only for place/stack)."""

    task: str = "one_object"
    sim: SimSettings = field(default_factory=lambda: SimSettings(horizon=400))  # 400 control steps per episode

    def __post_init__(self) -> None:
        if self.task not in EC_TASKS:
            raise ValueError(f"env.task must be one of {list(EC_TASKS)}, got '{self.task}'")
        if self.task in ("place", "stack") and self.sim.case != 1:
            raise ValueError(f"env.sim.case: the {self.task} task has one case only (1), got {self.sim.case}")

    @property
    def cell(self) -> str:
        return self.task if self.task in ("place", "stack") else f"{self.task}_case{self.sim.case}"

    @property
    def scenario(self) -> str:
        return self.cell


@dataclass
class AssemblyCellLayout:
    """The Ch.5 robot cell (Sec. 5.3, Fig. 5.8 with a UR5e; :mod:`hrc_lab.env.robot.assembly_cell`), in table
    coordinates (m, the robot's base at the table's -x edge). Each part type has a bin, its parts in a row along x
    from ``bins[type]`` at ``bin_spacing``; the bracket's positions p1..p6 lie along y from ``bracket_p1`` (the
    worker's right, +y) at ``position_spacing`` towards -y; ``part_half_sizes`` per type (x, y, z): the types differ
    in footprint and height, and every part has a flat top face for the suction cup."""

    part_half_sizes: dict[str, list[float]] = field(default_factory=lambda: {
        "o1": [0.02, 0.02, 0.02], "o2": [0.03, 0.02, 0.025], "o3": [0.02, 0.02, 0.035]})
    bins: dict[str, list[float]] = field(default_factory=lambda: {
        "o1": [-0.16, -0.30], "o2": [0.08, -0.30], "o3": [-0.16, -0.20]})
    bin_spacing: float = 0.08
    bin_jitter: float = 0.005  # uniform x-y jitter of each part in its bin slot, from the seed
    bracket_p1: list[float] = field(default_factory=lambda: [0.06, 0.25])
    position_spacing: float = 0.07
    bracket_thickness: float = 0.01
    place_tolerance: float = 0.02  # a placed part rests within this x-y distance of its position, m

    def __post_init__(self) -> None:
        for part, half in self.part_half_sizes.items():
            if len(half) != 3 or min(half) < 0.015:
                raise ValueError(f"env.robot.part_half_sizes.{part} must be 3 half sizes >= 0.015 m (the cup's "
                                 f"lip needs a 3 cm top face), got {half}")
        for part, xy in self.bins.items():
            if len(xy) != 2:
                raise ValueError(f"env.robot.bins.{part} must be [x, y], got {xy}")
        if len(self.bracket_p1) != 2:
            raise ValueError(f"env.robot.bracket_p1 must be [x, y], got {self.bracket_p1}")
        widest = 2 * max(h[1] for h in self.part_half_sizes.values())
        if self.position_spacing <= widest + 0.01:
            raise ValueError(f"env.robot.position_spacing={self.position_spacing} m leaves under 1 cm between parts "
                             f"{widest} m wide")
        longest = 2 * max(h[0] for h in self.part_half_sizes.values()) + 2 * self.bin_jitter
        if self.bin_spacing <= longest + 0.01:
            raise ValueError(f"env.robot.bin_spacing={self.bin_spacing} m leaves under 1 cm between parts in a bin")
        for key in ("bin_jitter",):
            if getattr(self, key) < 0:
                raise ValueError(f"env.robot.{key} must be >= 0, got {getattr(self, key)}")
        for key in ("bracket_thickness", "place_tolerance"):
            if not getattr(self, key) > 0:
                raise ValueError(f"env.robot.{key} must be > 0, got {getattr(self, key)}")


@dataclass
class AssembleToOrderConfig(AssembleToOrderSpec):
    """The assemble-to-order spec the semantic planner and the videos use, plus the robot cell that executes
    Algorithm 3's PickandPlace (``robot``: layout and part shapes; ``sim``: the robosuite cell's settings)."""

    robot: AssemblyCellLayout = field(default_factory=AssemblyCellLayout)
    sim: SimSettings = field(default_factory=lambda: SimSettings(horizon=5000))  # a whole session's control steps

    def __post_init__(self) -> None:
        super().__post_init__()
        for part in self.product:
            if part not in self.robot.part_half_sizes or part not in self.robot.bins:
                raise ValueError(f"env.robot: part type {part} needs part_half_sizes.{part} and bins.{part}")
