"""The robot cells as a gymnasium goal env: the DRL setting of thesis 3.3 and the DRL baseline of 4.4.3.

Observation (a ``Dict`` space, the layout HER relabels):

- ``observation``: joint angles (6), end-effector position (3) and orientation quaternion (4), every object's
  pose [x, y, z, yaw] (4 m), and 1.0 when the cup holds an object; the goal is not repeated here, so a relabelled
  ``desired_goal`` is the only goal the policy sees;
- ``achieved_goal``: the goal objects' poses, [x, y, z, yaw] each for error correction (3.3: P_obj = [x_obj,
  y_obj, z_obj, psi_yaw]), [x, y, z] of all m products for package-to-order (4.4.3). The yaw is taken under the
  part's rotational symmetry about z (``yaw_symmetry``, below);
- ``desired_goal``: error correction, P_goal = [x_goal, y_goal, z_goal, 0] of the object the task label names
  (blue for labels 0/1, red for 2/3); package-to-order, the selected products' slots and every other product's
  own position ("the rest objects' positions remain the same").

Reward, Eq. 3.6 / 4.7, on single goals or batches (``compute_reward`` recomputes it for HER's relabelled goals)::

    R = 0   if |P_obj - P_goal| <= delta_r for every goal object
       -1   otherwise

With ``reward="dense"`` (``rl.reward``; Fig. 3.12's "even with dense rewards") R = -sum_objects |P_obj - P_goal|
instead; ``info["is_success"]`` is Eq. 3.6's criterion either way.

Yaw under the part's symmetry (``yaw_symmetry`` n, ``rl.yaw_symmetry``; default 4): a 5 x 5 cm cuboid
(correction_cell.HALF, a square footprint) turned by 90 degrees is the same part in the same place, so the achieved
yaw is psi modulo 2 pi / n, wrapped to [-pi / n, pi / n), and every yaw error (the reward's, ``goal_distances``',
and those of HER's relabelled goals, which are wrapped achieved yaws) is wrapped the same way. It is done where
the achieved goals are made (``_achieved``), so the stored goals and ``compute_reward`` agree. Each goal object's
order is gcd(n, its footprint's own order): 4 for a square footprint, 2 for a rectangle (half sizes x != y), so a
rectangular part gets order 2 from n = 4 without a config of its own. n = 1: the raw yaw and raw differences (the
behaviour before the switch: a square part turned by 90 degrees is 1.57 rad off). Only error correction has a yaw
in its goals; package-to-order's [x, y, z] goals ignore the key.

Action: the cell's ``[dq_base, dq_shoulder, dq_elbow, (dq_wrist3), suction]`` scaled to [-1, 1]: joint deltas in
units of ``max_joint_step`` (5 degrees), suction on when > 0 (``suction="action"``). With ``suction="auto"`` the
action is the joint deltas only, as 3.3's ``[q'_base, q'_shoulder, q'_elbow, q'_wrist3]``: the cup is on, so it
grips the part whose top face it touches; Eq. 3.6 scores the part's pose, held or not.

Wrist 3 (``wrist3``, ``rl.wrist3``; only with the cell's ``yaw_action``): with the tool pointing down the tool's
yaw is q_base - q_wrist3 + const, so with ``"absolute"`` a held part turns with every base step unless the agent
matches it on wrist 3. ``"relative"`` (default) remaps the same action set one to one: the wrist-3 delta sent to the
cell is a_wrist3 * max_joint_step + ``HRCCell.wrist3_holding_yaw(dq_base)``, clipped to +-max_joint_step, so
a_wrist3 = 0 keeps the tool's (and a held part's) yaw while the base turns, and a_wrist3 turns the tool relative to
that (its yaw changes by -a_wrist3 * max_joint_step). :meth:`HRCGoalEnv.hold_yaw_action` is the action-space
wrist-3 value that holds the yaw in either mode (0 in ``"relative"``), :meth:`HRCGoalEnv.from_cell_action` the
inverse of :meth:`HRCGoalEnv.to_cell_action` (a scripted expert's cell action as this env's action).

Release on a support (``release``, ``rl.release``; ``suction="auto"`` only, with ``"action"`` the agent switches the
cup): with ``"never"`` the cup holds what it gripped to the episode's end (until a collision disables it), so the
cup, not the table, sets a placed part's final height. With ``"support"`` (default) the env releases the held part
once it has been lifted off its start support (its centre ``LIFT_M`` = 1 cm above where it was when gripped) and
then touches one of its allowed supports (``HRCCell.allowed_supports``: the table, or the part it stacks on;
MuJoCo's contact list at the end of a control step): the cup is then commanded off until the lip has left the part's
top face (``Suction.touching`` is -1 at the end of a step), and on again after that, so the part can be picked
again (a fresh grip needs a fresh 1 cm lift before it is released again) and a whole-plan episode can pick the
next part.

``start="held"`` (a diagnostic, not the thesis' setting): each error-correction episode starts once the scripted
expert has picked the goal object and lifted it to transit height, so the agent learns the placing half alone.

Episodes: error correction trains one subtask of the cell's correction plan per episode (``subtask`` k; the
objects of the subtasks before k start at their goals, the state once those succeeded, with the arm at home, or
with ``rl.start=sequence`` where the scripted expert's run of those subtasks left the arm and them;
``subtask=None``: the whole plan, one goal per object) for ``steps_per_subtask`` control steps per goal object (40
in 3.4.3). Package-to-order gives ``steps_per_subtask`` steps per product of the order (n_selected, also in CASE 2
where the human packs some first), so every episode of an env has the same length. Episodes are truncated, never
terminated (the goal-conditioned setting of HER); ``info["is_success"]`` (what stable-baselines3 logs as the
success rate) is R = 0 with no collision in the episode. As in 3.3 the effector is disabled after a collision (the
episode goes on).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hrc_lab.env.robot.cell import PICK, HRCCell
from hrc_lab.env.robot.correction_cell import ErrorCorrection
from hrc_lab.env.robot.expert import ScriptedExpert
from hrc_lab.env.robot.package_cell import PackageToOrder
from hrc_lab.rl.configs import REWARDS, STARTS, SUCTIONS

YAW_SYMMETRIES = (1, 2, 4)  # rl.yaw_symmetry: the subgroups of a square's rotations about z
WRIST3_MODES = ("relative", "absolute")  # rl.wrist3
RELEASES = ("support", "never")  # rl.release
LIFT_M = 0.01  # rl.release=support: a held part counts as lifted once its centre is this far above its grip height


def wrap_yaw(yaw: np.ndarray, order: np.ndarray | int) -> np.ndarray:
    """``yaw`` modulo 2 pi / ``order``, in [-pi / order, pi / order) (elementwise, ``order`` broadcast); order 1
    leaves the yaw as it is (no wrapping at all: the behaviour before ``rl.yaw_symmetry``)."""
    yaw, order = np.asarray(yaw, dtype=float), np.asarray(order)
    period = 2 * np.pi / order
    return np.where(order > 1, np.mod(yaw + period / 2, period) - period / 2, yaw)


def goal_differences(achieved_goal: np.ndarray, desired_goal: np.ndarray, dims_per_object: int,
                     yaw_orders: np.ndarray | None = None) -> np.ndarray:
    """P_obj - P_goal per object, shape ``(..., k, dims_per_object)``; with ``yaw_orders`` (one symmetry order per
    object) the last coordinate is a yaw and its difference is wrapped by :func:`wrap_yaw`."""
    achieved, desired = np.asarray(achieved_goal, dtype=float), np.asarray(desired_goal, dtype=float)
    difference = (achieved - desired).reshape(*achieved.shape[:-1], -1, dims_per_object)
    if yaw_orders is not None:
        difference[..., -1] = wrap_yaw(difference[..., -1], yaw_orders)
    return difference


def sparse_reward(achieved_goal: np.ndarray, desired_goal: np.ndarray, delta_r: float,
                  dims_per_object: int, yaw_orders: np.ndarray | None = None) -> np.ndarray:
    """Eq. 3.6 / 4.7 on goals of shape ``(..., k * dims_per_object)``: 0.0 where every one of the k objects is
    within ``delta_r`` (Euclidean, over its ``dims_per_object`` coordinates) of its goal, else -1.0; shape
    ``(...)`` (a 0-d array for one goal), float32. ``yaw_orders``: the k objects' yaw symmetry orders (the last
    coordinate is then a yaw whose error is taken modulo 2 pi / order); None: no yaw wrapping."""
    difference = goal_differences(achieved_goal, desired_goal, dims_per_object, yaw_orders)
    within = np.all(np.linalg.norm(difference, axis=-1) <= delta_r, axis=-1)
    return np.where(within, 0.0, -1.0).astype(np.float32)


def dense_reward(achieved_goal: np.ndarray, desired_goal: np.ndarray, dims_per_object: int,
                 yaw_orders: np.ndarray | None = None) -> np.ndarray:
    """-sum over the k goal objects of |P_obj - P_goal| (the norm Eq. 3.6 thresholds, yaw wrapped as in
    :func:`sparse_reward`), shape ``(...)``, float32: the dense reward of Fig. 3.12's text."""
    difference = goal_differences(achieved_goal, desired_goal, dims_per_object, yaw_orders)
    return (-np.linalg.norm(difference, axis=-1).sum(axis=-1)).astype(np.float32)


class HRCGoalEnv(gym.Env):
    """A gymnasium goal env around an :class:`~hrc_lab.env.robot.cell.HRCCell` (error correction or
    package-to-order); see the module docstring. The cell stays reachable as ``env.cell``."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, cell: HRCCell, subtask: int | None = 0, steps_per_subtask: int = 40,
                 delta_r: float | None = None, disable_effector_on_collision: bool = True,
                 cases: tuple[int, ...] = (), suction: str = "action", start: str = "scene",
                 yaw_symmetry: int = 4, wrist3: str = "relative", release: str = "support",
                 collision_fails: bool = False, reward: str = "sparse") -> None:
        if not isinstance(cell, ErrorCorrection | PackageToOrder):
            raise TypeError(f"HRCGoalEnv wraps ErrorCorrection or PackageToOrder cells, got {type(cell).__name__}")
        if steps_per_subtask < 1:
            raise ValueError(f"rl.steps_per_subtask must be >= 1, got {steps_per_subtask}")
        if isinstance(cell, PackageToOrder) and cell.n_missing:
            raise ValueError("env.sim.n_missing: the DRL baseline has every product present (a parked product "
                             "has no reachable goal); use n_missing=0")
        if cases and (not isinstance(cell, PackageToOrder) or set(cases) - {1, 2}):
            raise ValueError(f"cases: a package-to-order cell draws CASE 1 or 2 per episode, got {list(cases)}")
        if suction not in SUCTIONS:
            raise ValueError(f"rl.suction must be one of {list(SUCTIONS)}, got '{suction}'")
        if start not in STARTS:
            raise ValueError(f"rl.start must be one of {list(STARTS)}, got '{start}'")
        if start in ("held", "sequence") and not isinstance(cell, ErrorCorrection):
            raise ValueError(f"rl.start={start}: the scripted expert's moves before an episode exist in error "
                             "correction only")
        if yaw_symmetry not in YAW_SYMMETRIES:
            raise ValueError(f"rl.yaw_symmetry must be one of {list(YAW_SYMMETRIES)}, got {yaw_symmetry}")
        if wrist3 not in WRIST3_MODES:
            raise ValueError(f"rl.wrist3 must be one of {list(WRIST3_MODES)}, got '{wrist3}'")
        if release not in RELEASES:
            raise ValueError(f"rl.release must be one of {list(RELEASES)}, got '{release}'")
        if reward not in REWARDS:
            raise ValueError(f"rl.reward must be one of {list(REWARDS)}, got '{reward}'")
        self.cell = cell
        self.yaw_symmetry = int(yaw_symmetry)
        self.wrist3_relative = wrist3 == "relative"
        self.release_on_support = release == "support" and suction == "auto"
        self.collision_fails = collision_fails
        self.dense = reward == "dense"
        self.yaw_orders = np.zeros(0, dtype=int)
        self._cup_off = False  # rl.release=support: the cup released a part and stays off until the lip left it
        self._grip, self._grip_z, self._lifted = -1, 0.0, False
        self.cases = tuple(cases)
        self.suction_action = suction == "action"
        self.start = start
        self.subtask = subtask
        self.steps_per_subtask = steps_per_subtask
        self.delta_r = float(cell.success_threshold if delta_r is None else delta_r)
        cell.disable_effector_on_collision = disable_effector_on_collision  # the DRL setting of 3.3
        self.correction = isinstance(cell, ErrorCorrection)
        self.dims_per_object = 4 if self.correction else 3  # [x, y, z, yaw] (3.3) or [x, y, z] (4.4.3)
        self.elapsed_steps = 0
        self.goal_objects: list[int] = []
        self._desired = np.zeros(0)
        self._reset_scene()
        # a fixed episode length: steps_per_subtask per goal object, or per product of the order
        n_subtasks = len(self.goal_objects) if self.correction else cell.spec.n_selected
        self.horizon = steps_per_subtask * n_subtasks
        if cell.horizon < self.horizon:
            raise ValueError(f"env.sim.horizon={cell.horizon} is shorter than an RL episode ({steps_per_subtask} "
                             f"steps x {n_subtasks} subtasks = {self.horizon})")
        n_joints = cell.policy_action_dim - 1
        self.action_scale = np.concatenate([np.full(n_joints, cell.max_joint_step), [1.0] * self.suction_action])
        self.action_space = spaces.Box(-1.0, 1.0, self.action_scale.shape, dtype=np.float32)
        goal = spaces.Box(-np.inf, np.inf, self._desired.shape, dtype=np.float32)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-np.inf, np.inf, self._observation().shape, dtype=np.float32),
            "achieved_goal": goal,
            "desired_goal": goal,
        })

    # --- gymnasium API --------------------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """A new scene; with ``seed`` the cell's scene sampler is reseeded first (bit-identical scenes)."""
        super().reset(seed=seed)
        if seed is not None:
            self.cell.reseed(seed)
        self._reset_scene()
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        rest_z = self.cell.object_positions()[:, 2] if self.release_on_support else None
        self.cell.step(self.to_cell_action(action), info=False)  # the cell's own reward and info are not read
        if self.release_on_support:
            self._release_on_support(rest_z)
        self.elapsed_steps += 1
        poses = self._poses()  # the state after the step, read once
        achieved = self._achieved(poses)
        obs = self._obs(poses, achieved)
        collided = bool(self.cell.collisions)
        within = sparse_reward(obs["achieved_goal"], obs["desired_goal"], self.delta_r, self.dims_per_object,
                               self._yaw_orders())  # Eq. 3.6 on the observation's goals
        reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], {"collided": collided})
                       if self.dense or self.collision_fails else within)
        success = not collided and bool(within == 0.0)
        info = {
            "is_success": success,
            "success": success,
            "collided": collided,
            "collisions": list(self.cell.collisions),
            "goal_distances": self.goal_distances(achieved),
            "held": bool(self.cell.suction.held >= 0),
            "moved_m": self.moved(achieved),
        }
        truncated = self.elapsed_steps >= self.horizon
        return obs, reward, False, truncated, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """Eq. 3.6 / 4.7 (:func:`sparse_reward`, or :func:`dense_reward` with ``rl.reward=dense``) on one goal or a
        batch, yaw errors under the goal objects' symmetry (``yaw_orders``); with ``rl.collision_fails`` at most -1
        where the transition's ``info`` (a dict, or one per goal of a batch, as stable-baselines3's HER buffer passes
        them) says the episode ``collided``."""
        if self.dense:
            reward = dense_reward(achieved_goal, desired_goal, self.dims_per_object, self._yaw_orders())
        else:
            reward = sparse_reward(achieved_goal, desired_goal, self.delta_r, self.dims_per_object,
                                   self._yaw_orders())
        if not self.collision_fails:
            return reward
        if isinstance(info, dict):
            return np.minimum(reward, np.float32(-1.0)) if info.get("collided", False) else reward
        collided = np.array([bool(i.get("collided", False)) for i in info]).reshape(reward.shape)
        return np.where(collided, np.minimum(reward, np.float32(-1.0)), reward)

    def close(self) -> None:
        self.cell.close()

    # --- what Algorithm 1 reads ---------------------------------------------------------------------------------

    @property
    def max_joint_step(self) -> float:
        return float(self.cell.max_joint_step)

    def to_cell_action(self, action: np.ndarray) -> np.ndarray:
        """The cell's action (radians, suction command) for an action in [-1, 1]: with ``wrist3="relative"`` the
        wrist-3 delta is the action's plus the one holding the yaw while the base turns (clipped to the cell's max
        joint step); with ``suction="auto"`` the cup is on, or off after a release on a support (module docstring)."""
        scaled = np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * self.action_scale
        if self.wrist3_relative and self.cell.yaw_action:
            step = self.cell.max_joint_step
            scaled[3] = np.clip(scaled[3] + self.cell.wrist3_holding_yaw(scaled[0]), -step, step)
        return scaled if self.suction_action else np.append(scaled, -1.0 if self._cup_off else 1.0)

    def from_cell_action(self, cell_action: np.ndarray) -> np.ndarray:
        """This env's action in [-1, 1] (float32) for a cell action ``[dq_base, dq_shoulder, dq_elbow, (dq_wrist3),
        suction]`` in radians, e.g. a :class:`~hrc_lab.env.robot.expert.ScriptedExpert` step's: the inverse of
        :meth:`to_cell_action` (``wrist3="relative"`` subtracts the yaw-holding delta; the suction command is
        dropped with ``suction="auto"``), clipped to [-1, 1]."""
        cell_action = np.asarray(cell_action, dtype=float)
        joints = cell_action[:-1].copy()
        if self.wrist3_relative and self.cell.yaw_action:
            joints[3] -= self.cell.wrist3_holding_yaw(joints[0])
        action = joints / self.cell.max_joint_step
        if self.suction_action:
            action = np.append(action, cell_action[-1])
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def hold_yaw_action(self, dq_base: float) -> float | None:
        """The action-space wrist-3 value that keeps the tool's yaw while the base turns by ``dq_base`` (in [-1, 1]
        units of ``max_joint_step``): 0 with ``wrist3="relative"``, ``HRCCell.wrist3_holding_yaw`` in action units
        with ``"absolute"``; None when the action has no wrist-3 dimension (the cell's ``yaw_action`` off)."""
        if not self.cell.yaw_action:
            return None
        if self.wrist3_relative:
            return 0.0
        step = self.cell.max_joint_step
        return float(self.cell.wrist3_holding_yaw(float(dq_base) * step) / step)

    def lip(self) -> np.ndarray:
        """p_t: the lip at the commanded joints (where the arm is going; the servo lags one control step)."""
        return self.cell.lip_target_position()

    def predicted_lip(self, action: np.ndarray) -> np.ndarray:
        """p_{t+1}: the lip after ``action`` (in [-1, 1]), by forward kinematics at the joints it would command;
        the simulation is not stepped."""
        return self.cell.lip_position(self.cell.joint_targets(self.to_cell_action(action)))

    def moved(self, achieved: np.ndarray | None = None) -> float:
        """How far the goal object that moved most is from where it was at the episode's start, m (``achieved``:
        :meth:`_achieved` of the state now, when the caller has it)."""
        achieved = self._achieved() if achieved is None else achieved
        difference = (achieved - self._start).reshape(-1, self.dims_per_object)[:, :3]
        return float(np.linalg.norm(difference, axis=1).max())

    def desired_goal(self) -> np.ndarray:
        """The episode's desired goal g, flat: [x, y, z(, yaw)] per goal object (the observation's
        ``desired_goal`` before its float32 cast)."""
        return self._desired.copy()

    def goal_distances(self, achieved: np.ndarray | None = None) -> np.ndarray:
        """|P_obj - P_goal| of every goal object (its yaw error under its symmetry, as the reward's; ``achieved``:
        :meth:`_achieved` of the state now, when the caller has it)."""
        achieved = self._achieved() if achieved is None else achieved
        difference = goal_differences(achieved, self._desired, self.dims_per_object, self._yaw_orders())
        return np.linalg.norm(difference, axis=-1)

    # --- internals ------------------------------------------------------------------------------------------------

    def _reset_scene(self) -> None:
        cell = self.cell
        if self.cases:
            cell.case = self.cases[int(self.np_random.integers(len(self.cases)))]
        cell.reset()
        rest_z = cell.object_positions()[:, 2]
        if self.correction:
            plan = cell.expert_plan()
            if self.subtask is None:
                self.goal_objects = list(plan)
            elif not 0 <= self.subtask < len(plan):
                raise ValueError(f"subtask must be in [0, {len(plan)}) for the {cell.task} task (its correction "
                                 f"plan has {len(plan)} objects) or None (the whole plan), got {self.subtask}")
            elif self.start == "sequence":
                self._expert_moves(plan[: self.subtask])
                self.goal_objects = [plan[self.subtask]]
            else:
                for done in plan[: self.subtask]:  # earlier subtasks succeeded: their objects are at their goals
                    cell.set_object_pose(done, cell.goals[done])
                cell.sim.forward()
                self.goal_objects = [plan[self.subtask]]
            if self.start == "held":
                self._pick(self.goal_objects[0])
            goals = np.column_stack([cell.goals[self.goal_objects], np.zeros(len(self.goal_objects))])
        else:
            self.goal_objects = list(range(len(cell.cell_objects)))
            goals = cell.goals
        self._desired = np.asarray(goals, dtype=float).ravel()
        self.yaw_orders = np.array([self._yaw_order(i) for i in self.goal_objects], dtype=int)
        self._start = self._achieved()
        self.elapsed_steps = 0
        # rl.start=sequence: the expert has just released a part under the lip; as after a release in an episode,
        # the cup stays off until the lip has left it (rl.release=never: it grips that part again)
        self._cup_off = self.start == "sequence" and self.release_on_support and cell.suction.touching() >= 0
        self._grip, self._lifted = -1, False
        if self.release_on_support:
            self._release_on_support(rest_z)  # rl.start=held: the part the expert lifted counts as lifted

    def _yaw_order(self, obj: int) -> int:
        """``yaw_symmetry`` capped at the object's footprint symmetry: 4 for a square, 2 for a rectangle."""
        half_x, half_y = self.cell.cell_objects[obj].half_size[:2]
        return math.gcd(self.yaw_symmetry, 4 if math.isclose(half_x, half_y) else 2)

    def _yaw_orders(self) -> np.ndarray | None:
        """The goal objects' yaw orders when the goals carry a yaw (error correction), else None."""
        return self.yaw_orders if self.dims_per_object == 4 and len(self.yaw_orders) else None

    def _release_on_support(self, rest_z: np.ndarray) -> None:
        """``release="support"`` after a control step (module docstring); ``rest_z``: the objects' heights before
        the step, the grip height of a part gripped in it."""
        cell = self.cell
        if self._cup_off:
            if cell.suction.touching() < 0:  # the lip left the released part: the cup is on again
                self._cup_off = False
            return
        held = cell.suction.held
        if held < 0:
            self._grip, self._lifted = -1, False
            return
        z = cell.object_positions()[held, 2]
        if held != self._grip:  # a new grip
            self._grip, self._grip_z, self._lifted = held, float(rest_z[held]), False
        self._lifted = self._lifted or z >= self._grip_z + LIFT_M
        if self._lifted and cell.touching_support(held):
            cell.suction.release()
            self._cup_off, self._grip, self._lifted = True, -1, False

    def _pick(self, obj: int) -> None:
        """``rl.start=held``: the scripted expert's picking stage of ``obj`` (above it, down onto its top face, cup
        on, lifted to transit height), so the episode is the placing half alone. Its steps are not the episode's."""
        expert = ScriptedExpert(self.cell)
        expert.move = expert.plan.index(obj)
        while (step := expert.act()) is not None and step.stage == PICK and step.obj == obj:
            self.cell.step(step.action)

    def _expert_moves(self, objects: list[int]) -> None:
        """``rl.start=sequence``: the scripted expert picks and places ``objects`` (the subtasks before this one),
        and the episode starts where it left the arm and the parts. Its steps are not the episode's, nor are its
        contacts (the episode's collision record starts empty)."""
        expert = ScriptedExpert(self.cell, objects=objects)
        while (step := expert.act()) is not None:
            self.cell.step(step.action)
        self.cell.collisions = []

    def _poses(self) -> np.ndarray:
        return np.column_stack([self.cell.object_positions(), self.cell.object_yaws()])

    def _achieved(self, poses: np.ndarray | None = None) -> np.ndarray:
        poses = (self._poses() if poses is None else poses)[self.goal_objects, : self.dims_per_object]
        if self.dims_per_object == 4:  # the yaw under each goal object's symmetry
            poses[:, 3] = wrap_yaw(poses[:, 3], self.yaw_orders)
        return poses.ravel()

    def _observation(self, poses: np.ndarray | None = None) -> np.ndarray:
        cell = self.cell
        held = [float(cell.suction.held >= 0)]
        poses = self._poses() if poses is None else poses
        return np.concatenate([cell.arm_qpos(), cell.eef_position(), cell.eef_quaternion(), poses.ravel(), held])

    def _obs(self, poses: np.ndarray | None = None, achieved: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """The observation of the state now (``poses``, ``achieved``: :meth:`_poses` and :meth:`_achieved` of it,
        when the caller has them)."""
        poses = self._poses() if poses is None else poses
        return {
            "observation": self._observation(poses).astype(np.float32),
            "achieved_goal": (self._achieved(poses) if achieved is None else achieved).astype(np.float32),
            "desired_goal": self._desired.astype(np.float32),
        }


def make_goal_env(env_cfg: Any, rl_cfg: Any, seed: int | None = None, subtask: int | None = 0,
                  cases: tuple[int, ...] = (), **cell_kwargs: Any) -> HRCGoalEnv:
    """The goal env of an ``env`` config of a robot cell (what ``ENVS.build`` makes of it, with ``cell_kwargs``, e.g.
    an off-screen renderer) and an ``rl`` config (``steps_per_subtask``, ``delta_r``, ``suction``, ``start``,
    ``yaw_symmetry``, ``wrist3``, ``release``); ``subtask`` as in :class:`HRCGoalEnv` (error correction only);
    ``cases``: a package-to-order cell draws its CASE from these per episode (the DRL baseline of Table 4.3 trains on
    both)."""
    from hrc_lab.env import ENVS

    cell = ENVS.build(env_cfg, seed=seed, **cell_kwargs)
    return HRCGoalEnv(cell, subtask=subtask, steps_per_subtask=rl_cfg.steps_per_subtask, delta_r=rl_cfg.delta_r,
                      cases=cases, suction=rl_cfg.suction, start=rl_cfg.start, **task_switches(rl_cfg))


def task_switches(rl_cfg: Any) -> dict[str, Any]:
    """The ``rl`` config's ``yaw_symmetry``, ``wrist3``, ``release``, ``collision_fails`` and ``reward`` as
    :class:`HRCGoalEnv` keywords (an env built without a config gets the defaults, the faithful reading of 3.3)."""
    return {"yaw_symmetry": rl_cfg.yaw_symmetry, "wrist3": rl_cfg.wrist3, "release": rl_cfg.release,
            "collision_fails": rl_cfg.collision_fails, "reward": rl_cfg.reward}
