"""The robot cell shared by the Ch.3 and Ch.4 environments: a UR5e with a suction cup at a table with cuboids.

Physics: MuJoCo steps of ``physics_timestep`` (5 ms; robosuite's default 2 ms makes its Python controller loop
the bottleneck without changing what the experiments measure), ``1 / (control_freq * physics_timestep)`` per action,
each split as robosuite's lite physics does: ``mj_step1``, the arm torques, the collision scan, ``mj_step2``. With
``lean_step`` (the default) the cell runs these substeps itself with the control law of robosuite's JOINT_POSITION
controller (gains, input scaling and position limits read from robosuite's controller object), skipping robosuite's
per-substep controller, buffer and observable bookkeeping: the same physics bit for bit, about 2.5-3 times the
control steps per second (``scripts/bench_cell_step.py``). Off, robosuite's ``ManipulationEnv.step`` runs them.

Action (thesis 3.3 and 4.3), one control step at ``control_freq`` Hz:
    ``[dq_base, dq_shoulder, dq_elbow, suction]`` (+ ``dq_wrist3`` before suction with ``yaw_action=True``), joint
    deltas in radians clipped to +-``max_joint_step`` (5 deg); suction > 0 means on: the cup grips a part whose top
    face the lip touches when the command is applied (before the arm moves) and, with ``grip_after_step``, also
    at the end of the step. Wrist 1 and wrist 2 are not
    actuated by the policy: they follow so that the tool keeps pointing down (wrist1 = -pi/2 - shoulder - elbow,
    wrist2 = -pi/2). The six joint targets go to robosuite's BASIC composite controller whose arm part is
    JOINT_POSITION (delta input, no scaling), i.e. the robot's own PD loop with gravity compensation: per substep the
    arm torques M_arm (kp (q_target - q) - kd dq) + bias, clipped to the actuators' range, with the critically damped
    gains of :func:`arm_controller_config`. The suction cup has no actuators.

Collisions are scanned at every physics substep (all contacts looked up at once in a table of forbidden geom pairs,
filled in from the rule as pairs first touch): any arm link touching anything but its mount, the cup touching an
object while another object is held, the held object touching anything but its allowed supports, or a resting
object touching another object (:meth:`HRCCell.forbidden_contact`, the rule that RRT-Connect's collision
checker also applies to its scratch states, :meth:`HRCCell.scratch_state`). A collision fails the trial (Eq. 4.7)
and, with ``disable_effector_on_collision`` (the DRL setting of 3.3), switches the suction off for the rest of the
episode.

Reward (Eq. 3.6): 0 when every task object is within ``success_threshold`` (delta_r) of its goal, else -1.
Success (Eq. 3.7 / 4.7, :meth:`HRCCell.success`): that, with no collision during the episode.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass

# robosuite warns on import about optional extras (private macros, robosuite_models, mink) that we do not use. The
# modules of hrc_lab.env.robot reach robosuite through this one, so it is imported here first, quietly.
logging.disable(logging.WARNING)
try:
    import robosuite  # noqa: F401
finally:
    logging.disable(logging.NOTSET)
logging.getLogger("robosuite_logs").setLevel(logging.WARNING)  # its INFO lines (controller files) are noise here

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from robosuite import macros  # noqa: E402
from robosuite.controllers import load_composite_controller_config, load_part_controller_config  # noqa: E402
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv  # noqa: E402
from robosuite.models.arenas import TableArena  # noqa: E402
from robosuite.models.objects import BoxObject  # noqa: E402
from robosuite.models.tasks import ManipulationTask  # noqa: E402
from robosuite.utils.control_utils import set_goal_position  # noqa: E402
from robosuite.utils.observables import Observable, sensor  # noqa: E402

from hrc_lab.env.robot.settings import CELL_CAMERA  # noqa: E402
from hrc_lab.env.robot.suction import Suction, SuctionCup, weld_elements  # noqa: E402

PICK, PLACE = 0, 1
# Tool down, the lip 0.22 m above the table centre: the first reach of a trial starts at working height (from a
# higher home the dynamic planner, which sees only Delta, must generalise to configurations it rarely saw).
HOME_QPOS = np.array([-0.333, -1.474, 2.365, -np.pi / 2 + 1.474 - 2.365, -np.pi / 2, 0.0])
UNSEEN = -1  # a contact table entry for a geom pair that has not touched yet (else 0 allowed, 1 forbidden)


def arm_controller_config() -> dict:
    """BASIC composite controller with a JOINT_POSITION arm taking raw joint deltas (robosuite 1.5 API)."""
    config = load_composite_controller_config(robot="UR5e")
    arm = load_part_controller_config(default_controller="JOINT_POSITION")
    arm.update(input_max=np.pi, input_min=-np.pi, output_max=np.pi, output_min=-np.pi, kp=2500, damping_ratio=1)
    arm["gripper"] = config["body_parts"]["right"].get("gripper", {"type": "GRIP"})
    config["body_parts"]["right"] = arm
    return config


@dataclass
class CellObject:
    """A cuboid in the cell: name, half sizes (m) and colour."""

    name: str
    half_size: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


class HRCCell(ManipulationEnv):
    """Base class: subclasses define the objects, the fixtures and the task through the hooks below."""

    PARK = np.array([0.6, 1.2, 0.03])  # where absent objects wait: on the floor, out of the arm's reach
    transit_height = 0.15  # height of a carried object's centre above the table between stages, m

    def __init__(
        self,
        objects: list[CellObject],
        control_freq: float = 20,
        horizon: int = 600,
        success_threshold: float = 0.06,
        max_joint_step: float = np.deg2rad(5.0),
        yaw_action: bool = False,
        disable_effector_on_collision: bool = False,
        grip_after_step: bool = False,
        table_full_size: tuple[float, float, float] = (0.6, 1.0, 0.05),
        seed: int | None = None,
        has_offscreen_renderer: bool = False,
        camera_names: str | list[str] = "frontview",
        camera_heights: int = 240,
        camera_widths: int = 320,
        physics_timestep: float = 0.005,
        lean_step: bool = True,
    ) -> None:
        self.cell_objects = objects
        self.table_full_size = table_full_size
        self.table_offset = np.array((0.0, 0.0, 0.8))
        self.success_threshold = success_threshold
        self.max_joint_step = max_joint_step
        self.yaw_action = yaw_action
        self.disable_effector_on_collision = disable_effector_on_collision
        self.grip_after_step = grip_after_step
        self.lean_step = lean_step
        # lean_step only: step() returns robosuite's observation dict (else None), its observables updated after
        # every substep as robosuite's step updates them (so they sample the same substep); their clock restarts at
        # reset(), so switch this before a reset
        self.step_observations = False
        self._suction_on = False
        self.np_random = np.random.default_rng(seed)
        self.collisions: list[str] = []
        self.goals = np.zeros((len(objects), 3))
        # robosuite reads its physics step from a module global while it builds the model and controllers
        default_timestep, macros.SIMULATION_TIMESTEP = macros.SIMULATION_TIMESTEP, physics_timestep
        try:
            super().__init__(
                robots="UR5e",
                controller_configs=arm_controller_config(),
                gripper_types="SuctionCup",
                initialization_noise=None,
                use_camera_obs=False,
                has_renderer=False,
                has_offscreen_renderer=has_offscreen_renderer,
                render_camera=None,
                control_freq=control_freq,
                horizon=horizon,
                ignore_done=False,
                hard_reset=False,
                camera_names=camera_names,
                camera_heights=camera_heights,
                camera_widths=camera_widths,
                seed=seed,
            )
        finally:
            macros.SIMULATION_TIMESTEP = default_timestep

    # --- hooks for subclasses -------------------------------------------------------------------------------

    def _add_fixtures(self, arena: TableArena) -> None:
        """Add static bodies (a packaging box) to the arena."""

    def _sample_scene(self) -> None:
        """Choose object poses and goals for a new episode (``self.goals``; place objects with
        :meth:`set_object_pose`)."""
        raise NotImplementedError

    def task_objects(self) -> list[int]:
        """Indices of the objects that must reach their goals."""
        raise NotImplementedError

    def expert_plan(self) -> list[int]:
        """The objects the expert moves, in order, each to ``self.goals[object]``."""
        raise NotImplementedError

    def stage_label(self, obj: int, stage: int) -> int:
        """Label of a picking/placing stage of an object (pick/place x object)."""
        return 2 * obj + stage

    def allowed_supports(self, index: int) -> set[int]:
        """Geom ids a held object may touch (besides the cup): the table, box floor, the object it stacks on. Fixed
        within an episode: the contact scan caches the collision rule that reads it until the next reset."""
        return self._table_geoms

    def _after_step(self) -> None:
        """Task events after a control step (e.g. restocking missing products)."""

    # --- model ------------------------------------------------------------------------------------------------

    @property
    def _gripper(self) -> SuctionCup:
        robot = self.robots[0]
        return robot.gripper[robot.arms[0]]

    def _load_model(self) -> None:
        super()._load_model()
        robot = self.robots[0]
        robot.robot_model.set_base_xpos(robot.robot_model.base_xpos_offset["table"](self.table_full_size[0]))
        robot.init_qpos = HOME_QPOS.copy()
        arena = TableArena(table_full_size=self.table_full_size, table_offset=self.table_offset)
        arena.set_origin([0, 0, 0])
        # a camera facing the robot over the table (pending area left, box right), for videos
        arena.worldbody.append(ET.Element("camera", name=CELL_CAMERA, pos="1.35 0 1.85", xyaxes="0 1 0 -0.506 0 0.863"))
        self._add_fixtures(arena)
        self.objects = [
            BoxObject(name=o.name, size=o.half_size, rgba=o.rgba, density=500, friction=(1.0, 0.005, 0.0001))
            for o in self.cell_objects
        ]
        self.model = ManipulationTask(
            mujoco_arena=arena, mujoco_robots=[robot.robot_model], mujoco_objects=self.objects
        )
        cup_body = self._gripper.naming_prefix + "cup"
        for weld in weld_elements(cup_body, [o.root_body for o in self.objects]):
            self.model.equality.append(weld)

    def _setup_references(self) -> None:
        super()._setup_references()
        model = self.sim.model._model
        robot = self.robots[0]
        self._object_bodies = [model.body(o.root_body).id for o in self.objects]
        self._object_joints = [o.joints[0] for o in self.objects]
        self._object_geoms = [{model.geom(g).id for g in o.contact_geoms} for o in self.objects]
        self._geom_owner = {g: i for i, geoms in enumerate(self._object_geoms) for g in geoms}
        self._cup_geoms = {model.geom(g).id for g in self._gripper.contact_geoms}
        self._arm_geoms = {model.geom(g).id for g in robot.robot_model.contact_geoms}
        mount = {model.geom(g).id for g in robot.robot_model.base.contact_geoms} if robot.robot_model.base else set()
        self._mount_geoms = mount
        self._table_geoms = {model.geom("table_collision").id}
        self._arm_qpos = np.asarray(robot._ref_joint_pos_indexes)
        self._arm_dofs = np.asarray(robot._ref_joint_vel_indexes)
        self._mass_matrix = np.zeros((model.nv, model.nv))  # lean_step's buffer for mj_fullM
        self._arm_actuators = np.asarray(robot._ref_actuators_indexes_dict[robot.arms[0]])
        self._arm_torque_range = model.actuator_ctrlrange[self._arm_actuators].T.copy()
        self._scratch = mujoco.MjData(model)  # forward kinematics of commanded configurations
        self._grip_site = model.site(self._gripper.important_sites["grip_site"]).id
        self.suction = Suction(
            model, self.sim.data._data, cup_body=self._gripper.naming_prefix + "cup",
            grip_site=self._gripper.important_sites["grip_site"],
            object_bodies=[o.root_body for o in self.objects],
            half_sizes=np.array([o.half_size for o in self.cell_objects]),
        )

    def _setup_observables(self):
        observables = super()._setup_observables()

        @sensor(modality="object")
        def object_pos(obs_cache):
            return self.object_positions().ravel()

        @sensor(modality="object")
        def object_yaw(obs_cache):
            return self.object_yaws()

        @sensor(modality="object")
        def goal_pos(obs_cache):
            return self.goals.ravel().copy()

        @sensor(modality="object")
        def held(obs_cache):
            return np.array([self.suction.held], dtype=float)

        @sensor(modality="robot")
        def lip_target_pos(obs_cache):
            return self.lip_target_position()

        for s in (object_pos, object_yaw, goal_pos, held, lip_target_pos):
            observables[s.__name__] = Observable(name=s.__name__, sensor=s, sampling_rate=self.control_freq)
        return observables

    # --- episode ----------------------------------------------------------------------------------------------

    def reseed(self, seed: int) -> None:
        """Fix the scene sampler; the physics is deterministic given the scene and the actions."""
        self.np_random = np.random.default_rng(seed)

    def _reset_internal(self) -> None:
        super()._reset_internal()
        self.sim.data.qpos[self._arm_qpos] = HOME_QPOS
        self.sim.data.qvel[:] = 0.0
        self._q_cmd = HOME_QPOS.copy()
        self.suction.reset()
        self._suction_on = False
        self.collisions = []
        self._contact_tables: dict[int, np.ndarray] = {}  # held object -> forbidden[geom_a, geom_b] (UNSEEN at first)
        self._sample_scene()
        self.sim.forward()

    def set_object_pose(self, index: int, position: np.ndarray, yaw: float = 0.0) -> None:
        """Put object ``index`` at rest with its centre at ``position`` (m), turned ``yaw`` (rad) about z. Sets the
        joint state only: positions derived from it (``object_positions``, contacts) follow at ``sim.forward()`` or
        the next step."""
        quat = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])  # MuJoCo wxyz
        self.sim.data.set_joint_qpos(self._object_joints[index], np.concatenate([position, quat]))
        self.sim.data.set_joint_qvel(self._object_joints[index], np.zeros(6))

    # --- action -----------------------------------------------------------------------------------------------

    @property
    def policy_action_dim(self) -> int:
        """Size of the thesis action; robosuite's own ``action_dim`` stays the 6 arm joint deltas."""
        return 5 if self.yaw_action else 4

    @property
    def policy_action_spec(self) -> tuple[np.ndarray, np.ndarray]:
        high = np.full(self.policy_action_dim, self.max_joint_step)
        high[-1] = 1.0
        return -high, high

    def arm_qpos(self) -> np.ndarray:
        return self.sim.data.qpos[self._arm_qpos].copy()

    def commanded_qpos(self) -> np.ndarray:
        """The joint targets the servo is tracking (where the arm will be once it settles)."""
        return self._q_cmd.copy()

    def lip_kinematics(self, arm_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lip position at arm configuration ``arm_q`` and its 3x3 Jacobian w.r.t. [base, shoulder, elbow], with
        wrist 1 following the tool-down rule (d wrist1 / d shoulder = d wrist1 / d elbow = -1)."""
        model, scratch = self.sim.model._model, self._scratch
        scratch.qpos[:] = self.sim.data.qpos
        scratch.qpos[self._arm_qpos] = arm_q
        mujoco.mj_kinematics(model, scratch)
        mujoco.mj_comPos(model, scratch)
        jac = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, scratch, jac, None, self._grip_site)
        j = jac[:, self._arm_dofs]
        effective = np.column_stack([j[:, 0], j[:, 1] - j[:, 3], j[:, 2] - j[:, 3]])
        return scratch.site_xpos[self._grip_site].copy(), effective

    def lip_position(self, arm_q: np.ndarray) -> np.ndarray:
        """:meth:`lip_kinematics`' position alone (the same forward kinematics, without the Jacobian)."""
        model, scratch = self.sim.model._model, self._scratch
        scratch.qpos[:] = self.sim.data.qpos
        scratch.qpos[self._arm_qpos] = arm_q
        mujoco.mj_kinematics(model, scratch)
        return scratch.site_xpos[self._grip_site].copy()

    @staticmethod
    def wrist3_holding_yaw(dq_base: float) -> float:
        """The wrist-3 delta that keeps the tool's yaw, and a held part's, while the base turns by ``dq_base``:
        with the tool pointing down (wrist 2 at -pi/2) the tool's yaw about z is q_base - q_wrist3 + const."""
        return float(dq_base)

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """Six absolute joint targets for a thesis action (clipped; wrist 1/2 keep the tool pointing down).

        Deltas add to the previous command, not to the measured angles, so the servo's lag does not shrink the
        commanded motion; the command never leads the arm by more than two steps (a blocked arm does not wind up).
        """
        q = np.clip(self._q_cmd, self.arm_qpos() - 2 * self.max_joint_step, self.arm_qpos() + 2 * self.max_joint_step)
        delta = np.clip(np.asarray(action[:3], dtype=float), -self.max_joint_step, self.max_joint_step)
        target = q.copy()
        target[:3] = q[:3] + delta
        target[3] = -np.pi / 2 - target[1] - target[2]
        target[4] = -np.pi / 2
        if self.yaw_action:
            target[5] = q[5] + np.clip(action[3], -self.max_joint_step, self.max_joint_step)
        return target

    @property
    def _arm_controller(self):
        """robosuite's JOINT_POSITION controller of the arm (robosuite builds a new one at every reset)."""
        robot = self.robots[0]
        return robot.part_controllers[robot.arms[0]]

    def step(self, action, info: bool = True):
        """One control step (module docstring). ``info=False`` (the goal env, which reads the state itself): the
        same step, returning ``(None, None, done, {})`` without robosuite's reward and the info's distances."""
        action = np.asarray(action, dtype=float)
        if action.shape != (self.policy_action_dim,):
            raise ValueError(f"action must have shape ({self.policy_action_dim},), got {action.shape}")
        self._suction_on = bool(action[-1] > 0)
        self.suction.command(self._suction_on)
        self._step_collisions: list[str] = []
        self._q_cmd = self.joint_targets(action)
        low_level = self._q_cmd - self.arm_qpos()
        self._step_info = info
        if self.lean_step:
            return self._lean_step(low_level)
        return super().step(low_level)

    _step_info = True  # step()'s info argument, for _post_action

    def _lean_step(self, low_level: np.ndarray):
        """robosuite's ``step`` (lite physics) for the joint deltas ``low_level`` without its per-substep
        bookkeeping: the substeps with :meth:`_servo_torques` and the contact scan, then ``_post_action`` as there.
        The controller is the fixed-gain, delta-input one of :func:`arm_controller_config` (no interpolator).
        The observation dict is robosuite's with ``step_observations``, else None."""
        if self.done:
            raise ValueError("executing action in terminated episode")
        self.timestep += 1
        controller = self._arm_controller
        q = self.arm_qpos()  # JOINT_POSITION.set_goal: the delta input is added to the joints at the first substep
        goal = set_goal_position(controller.scale_action(low_level), q, position_limit=controller.position_limits)
        model, data = self.sim.model._model, self.sim.data._data
        for _ in range(int(self.control_timestep / self.model_timestep)):
            mujoco.mj_step1(model, data)
            data.ctrl[self._arm_actuators] = self._servo_torques(controller, goal)
            self._scan_contacts()
            mujoco.mj_step2(model, data)
            if self.step_observations:
                self._update_observables()
        self.cur_time += self.control_timestep
        reward, done, info = self._post_action(low_level)
        return (self._get_observations() if self.step_observations else None), reward, done, info

    def _servo_torques(self, controller, goal: np.ndarray) -> np.ndarray:
        """The arm torques robosuite's JOINT_POSITION ``run_controller`` computes after ``mj_step1`` (M_arm (kp
        (goal - q) - kd dq) + gravity and Coriolis bias), clipped to the actuators' range as ``Robot.control`` does;
        the same operations in the same order, so the same bits."""
        data = self.sim.data._data
        mujoco.mj_fullM(self.sim.model._model, self._mass_matrix, data.qM)
        desired = controller.kp * (goal - data.qpos[self._arm_qpos]) - controller.kd * data.qvel[self._arm_dofs]
        # robosuite's row-then-column indexing: its Fortran-ordered block takes the same BLAS path in np.dot
        arm_mass = self._mass_matrix[self._arm_dofs, :][:, self._arm_dofs]
        torques = np.dot(arm_mass, desired) + data.qfrc_bias[self._arm_dofs]
        return torques.clip(*self._arm_torque_range)  # what np.clip calls, without its Python wrapper

    def _pre_action(self, action, policy_step=False):
        super()._pre_action(action, policy_step)
        self._scan_contacts()

    def _post_action(self, action):
        self._after_step()
        if self._step_collisions:
            self.collisions.extend(self._step_collisions)
            if self.disable_effector_on_collision:
                self.suction.disable()
        if self.grip_after_step and self._suction_on:
            self.suction.command(True)  # a lip that reached a top face during the step grips now
        if not self._step_info:  # robosuite's _post_action without its reward (a read of the state)
            self.done = (self.timestep >= self.horizon) and not self.ignore_done
            return None, self.done, {}
        reward, done, info = super()._post_action(action)
        distances = self.goal_distances()
        info.update(
            collision=bool(self._step_collisions),
            collisions=list(self._step_collisions),
            collided=bool(self.collisions),
            held=self.suction.held,
            goal_distances=distances,
            at_goal=distances <= self.success_threshold,
            success=self.success(),
        )
        return reward, done, info

    # --- contacts ---------------------------------------------------------------------------------------------

    @property
    def mj_model(self) -> mujoco.MjModel:
        """The compiled MuJoCo model the cell simulates (robosuite's ``sim.model`` wraps it)."""
        return self.sim.model._model

    @property
    def arm_geoms(self) -> frozenset[int]:
        """Geom ids of the arm's links."""
        return frozenset(self._arm_geoms)

    @property
    def cup_geoms(self) -> frozenset[int]:
        """Geom ids of the suction cup."""
        return frozenset(self._cup_geoms)

    @property
    def mount_geoms(self) -> frozenset[int]:
        """Geom ids of the arm's mount (the only thing besides the arm and the cup that the arm may touch)."""
        return frozenset(self._mount_geoms)

    def object_geoms(self, index: int | None = None) -> frozenset[int]:
        """Geom ids of object ``index``, or of every object (None)."""
        return frozenset(self._geom_owner if index is None else self._object_geoms[index])

    def forbidden_contact(self, a: int, b: int, held: int, pick_target: int | None = None) -> str | None:
        """The collision (Eq. 4.7's rule, module docstring) that a contact of geoms ``a`` and ``b`` is while object
        ``held`` is in the cup (-1: none), named ``"<kind>: <geom> / <geom>"`` with the geoms in the order that
        matched the rule (e.g. ``"arm: robot0_wrist1_col / table_collision"``), or None when the rule allows it.

        ``pick_target`` None is the cell's own rule, which the contact scan applies. An object index (-1: none)
        adds a planner's stricter one for a cup that holds nothing: it may touch no object but ``pick_target``
        (RRT-Connect plans the approach to the product it picks so, :mod:`hrc_lab.motion.rrt_connect`)."""
        for first, second in ((a, b), (b, a)):
            kind = self._classify(first, second, held, pick_target)
            if kind:
                model = self.sim.model._model
                return f"{kind}: {model.geom(first).name} / {model.geom(second).name}"
        return None

    def touching_support(self, index: int) -> bool:
        """Whether a geom of object ``index`` is in contact with one of its ``allowed_supports`` (MuJoCo's contact
        list as the last physics substep left it)."""
        data = self.sim.data._data
        if not data.ncon:
            return False
        first, second = np.asarray(data.contact.geom1[: data.ncon]), np.asarray(data.contact.geom2[: data.ncon])
        part, supports = self._object_geoms[index], self.allowed_supports(index)
        return any((a in part and b in supports) or (b in part and a in supports) for a, b in zip(first, second))

    def scratch_state(self, model: mujoco.MjModel | None = None, held: int = -1) -> ScratchState:
        """A scratch state for collision checks of arm configurations (:class:`ScratchState`): the joint positions
        now in a new ``MjData`` of ``model`` (a copy of the cell's model, e.g. with other contact margins; default
        the cell's own), object ``held`` (-1: none) carried rigidly by the cup. The live simulation is untouched."""
        return ScratchState(self, self.sim.model._model if model is None else model, held)

    def _scan_contacts(self) -> None:
        """Add this substep's collisions to ``_step_collisions`` (each event once, in contact order). All contacts
        are looked up at once in the held object's :meth:`_contact_table`; only those marked forbidden or UNSEEN are
        classified (:meth:`forbidden_contact`), which fills in the UNSEEN entries."""
        held = self.suction.held
        pairs = self.sim.data._data.contact.geom
        table = self._contact_table(held)
        for k in table[pairs[:, 0], pairs[:, 1]].nonzero()[0]:
            a, b = int(pairs[k, 0]), int(pairs[k, 1])
            event = self.forbidden_contact(a, b, held)
            table[a, b] = table[b, a] = event is not None
            if event is not None and event not in self._step_collisions:
                self._step_collisions.append(event)

    def _contact_table(self, held: int) -> np.ndarray:
        """forbidden[geom_a, geom_b] while object ``held`` is held (-1: none): 1 when a contact of the two geoms is a
        collision, 0 when it is not, UNSEEN until the pair first touches; kept until the next reset, as the rule
        (:meth:`_classify` and ``allowed_supports``) is fixed within an episode."""
        table = self._contact_tables.get(held)
        if table is None:
            ngeom = self.sim.model._model.ngeom
            table = self._contact_tables[held] = np.full((ngeom, ngeom), UNSEEN, dtype=np.int8)
        return table

    def _classify(self, a: int, b: int, held: int, pick_target: int | None = None) -> str | None:
        """A collision name when geom ``a`` touching geom ``b`` is forbidden, else None (one way round; the rule
        checks both, :meth:`forbidden_contact`, which says what ``pick_target`` adds)."""
        if a in self._arm_geoms and b not in self._arm_geoms | self._mount_geoms | self._cup_geoms:
            return "arm"
        obj_a, obj_b = self._geom_owner.get(a), self._geom_owner.get(b)
        if a in self._cup_geoms and obj_b is None and b not in self._arm_geoms | self._cup_geoms:
            return "cup"
        if a in self._cup_geoms and obj_b is not None and held >= 0 and obj_b != held:
            return f"cup-{self.cell_objects[obj_b].name}"
        if (a in self._cup_geoms and obj_b is not None and held < 0 and pick_target is not None
                and obj_b != pick_target):
            return f"cup-{self.cell_objects[obj_b].name}"
        if obj_a is not None and obj_a == held and b not in self._cup_geoms | self.allowed_supports(held):
            return f"held-{self.cell_objects[held].name}"
        if obj_a is not None and obj_b is not None and obj_a < obj_b and held not in (obj_a, obj_b):
            if b not in self.allowed_supports(obj_a) and a not in self.allowed_supports(obj_b):
                return f"{self.cell_objects[obj_a].name}-{self.cell_objects[obj_b].name}"
        return None

    # --- state --------------------------------------------------------------------------------------------------

    def object_positions(self) -> np.ndarray:
        return self.sim.data._data.xpos[self._object_bodies]  # a copy (an index list)

    def object_yaws(self) -> np.ndarray:
        quats = self.sim.data._data.xquat[self._object_bodies]  # wxyz
        w, x, y, z = quats.T
        return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    def base_position(self) -> np.ndarray:
        """Where the arm's base joint axis meets its mount (the origin of the motion module's base frame)."""
        return self.sim.data.xpos[self.sim.model._model.body(self.robots[0].robot_model.root_body).id].copy()

    def eef_position(self) -> np.ndarray:
        """Position of the cup's lip (r in the thesis)."""
        return self.sim.data.site_xpos[self._grip_site].copy()

    def grip_offset(self) -> np.ndarray | None:
        """The lip minus the centre of the part the cup holds (m); None when it holds none."""
        held = self.suction.held
        return None if held < 0 else self.eef_position() - self.object_positions()[held]

    def eef_quaternion(self) -> np.ndarray:
        """Orientation (w, x, y, z) of the body that carries the lip (the end-effector pose of 3.3's DRL state)."""
        return self.sim.data.xquat[self.sim.model._model.site_bodyid[self._grip_site]].copy()

    def lip_target_position(self) -> np.ndarray:
        """Where the lip goes once the servo settles on the commanded joints: the servo lags about one control
        step (up to ~4 cm at full speed), so a joint-space controller acts from here, as the expert does."""
        return self.lip_position(self._q_cmd)

    def goal_distances(self) -> np.ndarray:
        """|P_obj - P_goal| of every task object (Eq. 3.6 / 4.7)."""
        idx = self.task_objects()
        return np.linalg.norm(self.object_positions()[idx] - self.goals[idx], axis=1)

    def reward(self, action=None) -> float:
        """Sparse reward of Eq. 3.6."""
        return 0.0 if np.all(self.goal_distances() <= self.success_threshold) else -1.0

    def success(self) -> bool:
        """Whether the trial has succeeded (Eq. 3.7 / 4.7): every task object within delta_r of its goal, released,
        and no collision during the episode."""
        return bool(self.reward() == 0.0 and self.suction.held < 0 and not self.collisions)

    def _check_success(self) -> bool:
        """robosuite's success hook (its wrappers call it): :meth:`success`."""
        return self.success()

    def observations(self) -> dict:
        """robosuite's observation dict of the cell's current state, computed now (e.g. for a recording that starts
        where a closed loop left the cell, :func:`hrc_lab.data.recording.record_episode`)."""
        return self._get_observations(force_update=True)

    def raw_observation(self) -> np.ndarray:
        """The flat DRL state of 3.3: joint angles, end-effector pose, object poses (x, y, z, yaw), goals."""
        poses = np.column_stack([self.object_positions(), self.object_yaws()])
        return np.concatenate([self.arm_qpos(), self.eef_position(), self.eef_quaternion(), poses.ravel(),
                               self.goals.ravel()])


class ScratchState:
    """A scratch ``MjData`` for collision checks of arm configurations, apart from the live simulation
    (:meth:`HRCCell.scratch_state`): ``data`` starts with the cell's joint positions at creation; ``model`` is the
    cell's model or a copy of it (same bodies, joints and geoms; e.g. other contact margins or filters).
    :meth:`set_arm_qpos` poses the arm there, object ``held`` (-1: none) moving rigidly with the cup at its pose
    relative to the cup at creation, and runs forward kinematics; the caller then runs e.g. ``mj_collision`` and
    judges the contacts with :meth:`HRCCell.forbidden_contact`."""

    def __init__(self, cell: HRCCell, model: mujoco.MjModel, held: int = -1) -> None:
        live = cell.sim.data._data
        self.model, self.held = model, held
        self.data = mujoco.MjData(model)
        self.data.qpos[:] = live.qpos
        self._arm_qpos = cell._arm_qpos
        self._cup = cell.suction.cup
        if held >= 0:
            cup, body = self._cup, cell._object_bodies[held]
            self._rel_pos = live.xmat[cup].reshape(3, 3).T @ (live.xpos[body] - live.xpos[cup])
            self._rel_quat = np.empty(4)
            cup_inv = np.empty(4)
            mujoco.mju_negQuat(cup_inv, live.xquat[cup])
            mujoco.mju_mulQuat(self._rel_quat, cup_inv, live.xquat[body])
            self._held_adr = model.jnt_qposadr[model.joint(cell._object_joints[held]).id]

    def set_arm_qpos(self, arm: np.ndarray) -> mujoco.MjData:
        """Set the six arm joints to ``arm`` (the held object follows the cup) and run ``mj_kinematics``; returns
        ``data``."""
        model, data = self.model, self.data
        data.qpos[self._arm_qpos] = arm
        mujoco.mj_kinematics(model, data)
        if self.held >= 0:
            cup, adr = self._cup, self._held_adr
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, data.xquat[cup], self._rel_quat)
            data.qpos[adr:adr + 3] = data.xpos[cup] + data.xmat[cup].reshape(3, 3) @ self._rel_pos
            data.qpos[adr + 3:adr + 7] = quat
            mujoco.mj_kinematics(model, data)
        return data
