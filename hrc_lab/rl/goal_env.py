"""The robot cells as a gymnasium goal env: the DRL setting of thesis 3.3 and the DRL baseline of 4.4.3.

Observation (a ``Dict`` space, the layout HER relabels):

- ``observation``: joint angles (6), end-effector position (3) and orientation quaternion (4), every object's
  pose [x, y, z, yaw] (4 m), and 1.0 when the cup holds an object; the goal is not repeated here, so a relabelled
  ``desired_goal`` is the only goal the policy sees;
- ``achieved_goal``: the goal objects' poses, [x, y, z, yaw] each for error correction (3.3: P_obj = [x_obj,
  y_obj, z_obj, psi_yaw]), [x, y, z] of all m products for package-to-order (4.4.3);
- ``desired_goal``: error correction, P_goal = [x_goal, y_goal, z_goal, 0] of the object the task label names
  (blue for labels 0/1, red for 2/3); package-to-order, the selected products' slots and every other product's
  own position ("the rest objects' positions remain the same").

Reward, Eq. 3.6 / 4.7, on single goals or batches (``compute_reward`` recomputes it for HER's relabelled goals)::

    R = 0   if |P_obj - P_goal| <= delta_r for every goal object
       -1   otherwise

Action: the cell's ``[dq_base, dq_shoulder, dq_elbow, (dq_wrist3), suction]`` scaled to [-1, 1]: joint deltas in
units of ``max_joint_step`` (5 degrees), suction on when > 0 (``suction="action"``). With ``suction="auto"`` the
action is the joint deltas only, as 3.3's ``[q'_base, q'_shoulder, q'_elbow, q'_wrist3]``: the cup is always on,
so it grips the part whose top face it touches and holds it to the episode's end (until a collision disables it);
Eq. 3.6 scores the part's pose, held or not.

``start="held"`` (a diagnostic, not the thesis' setting): each error-correction episode starts once the scripted
expert has picked the goal object and lifted it to transit height, so the agent learns the placing half alone.

Episodes: error correction trains one subtask of the cell's correction plan per episode (``subtask`` k; the
objects of the subtasks before k start at their goals, the state once those succeeded; ``subtask=None``: the
whole plan, one goal per object) for ``steps_per_subtask`` control steps per goal object (40 in 3.4.3).
Package-to-order gives ``steps_per_subtask`` steps per product of the order (n_selected, also in CASE 2 where the
human packs some first), so every episode of an env has the same length. Episodes are truncated, never
terminated (the goal-conditioned setting of HER); ``info["is_success"]`` (what stable-baselines3 logs as the
success rate) is R = 0 with no collision in the episode. As in 3.3 the effector is disabled after a collision (the
episode goes on).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hrc_lab.env.robot.cell import PICK, HRCCell
from hrc_lab.env.robot.correction_cell import ErrorCorrection
from hrc_lab.env.robot.package_cell import PackageToOrder
from hrc_lab.rl.configs import STARTS, SUCTIONS


def sparse_reward(achieved_goal: np.ndarray, desired_goal: np.ndarray, delta_r: float,
                  dims_per_object: int) -> np.ndarray:
    """Eq. 3.6 / 4.7 on goals of shape ``(..., k * dims_per_object)``: 0.0 where every one of the k objects is
    within ``delta_r`` (Euclidean, over its ``dims_per_object`` coordinates) of its goal, else -1.0; shape
    ``(...)`` (a 0-d array for one goal), float32."""
    achieved, desired = np.asarray(achieved_goal, dtype=float), np.asarray(desired_goal, dtype=float)
    difference = (achieved - desired).reshape(*achieved.shape[:-1], -1, dims_per_object)
    within = np.all(np.linalg.norm(difference, axis=-1) <= delta_r, axis=-1)
    return np.where(within, 0.0, -1.0).astype(np.float32)


class HRCGoalEnv(gym.Env):
    """A gymnasium goal env around an :class:`~hrc_lab.env.robot.cell.HRCCell` (error correction or
    package-to-order); see the module docstring. The cell stays reachable as ``env.cell``."""

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, cell: HRCCell, subtask: int | None = 0, steps_per_subtask: int = 40,
                 delta_r: float | None = None, disable_effector_on_collision: bool = True,
                 cases: tuple[int, ...] = (), suction: str = "action", start: str = "scene") -> None:
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
        if start == "held" and not isinstance(cell, ErrorCorrection):
            raise ValueError("rl.start=held: episodes start with the part picked in error correction only")
        self.cell = cell
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
        self.cell.step(self.to_cell_action(action))
        self.elapsed_steps += 1
        obs = self._obs()
        reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], {}))
        collided = bool(self.cell.collisions)
        success = reward == 0.0 and not collided
        info = {
            "is_success": success,
            "success": success,
            "collided": collided,
            "collisions": list(self.cell.collisions),
            "goal_distances": self.goal_distances(),
            "held": bool(self.cell.suction.held >= 0),
            "moved_m": self.moved(),
        }
        truncated = self.elapsed_steps >= self.horizon
        return obs, reward, False, truncated, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """Eq. 3.6 / 4.7 (:func:`sparse_reward`) on one goal or a batch; ``info`` is unused."""
        return sparse_reward(achieved_goal, desired_goal, self.delta_r, self.dims_per_object)

    def close(self) -> None:
        self.cell.close()

    # --- what Algorithm 1 reads ---------------------------------------------------------------------------------

    @property
    def max_joint_step(self) -> float:
        return float(self.cell.max_joint_step)

    def to_cell_action(self, action: np.ndarray) -> np.ndarray:
        """The cell's action (radians, suction command) for an action in [-1, 1] (the cup on with ``auto``)."""
        scaled = np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * self.action_scale
        return scaled if self.suction_action else np.append(scaled, 1.0)

    def lip(self) -> np.ndarray:
        """p_t: the lip at the commanded joints (where the arm is going; the servo lags one control step)."""
        return self.cell.lip_target_position()

    def predicted_lip(self, action: np.ndarray) -> np.ndarray:
        """p_{t+1}: the lip after ``action`` (in [-1, 1]), by forward kinematics at the joints it would command;
        the simulation is not stepped."""
        return self.cell.lip_kinematics(self.cell.joint_targets(self.to_cell_action(action)))[0]

    def moved(self) -> float:
        """How far the goal object that moved most is from where it was at the episode's start, m."""
        difference = (self._achieved() - self._start).reshape(-1, self.dims_per_object)[:, :3]
        return float(np.linalg.norm(difference, axis=1).max())

    def goal_distances(self) -> np.ndarray:
        """|P_obj - P_goal| of every goal object."""
        difference = (self._achieved() - self._desired).reshape(-1, self.dims_per_object)
        return np.linalg.norm(difference, axis=1)

    # --- internals ------------------------------------------------------------------------------------------------

    def _reset_scene(self) -> None:
        cell = self.cell
        if self.cases:
            cell.case = self.cases[int(self.np_random.integers(len(self.cases)))]
        cell.reset()
        if self.correction:
            plan = cell.expert_plan()
            if self.subtask is None:
                self.goal_objects = list(plan)
            elif not 0 <= self.subtask < len(plan):
                raise ValueError(f"subtask must be in [0, {len(plan)}) for the {cell.task} task (its correction "
                                 f"plan has {len(plan)} objects) or None (the whole plan), got {self.subtask}")
            else:
                for done in plan[: self.subtask]:  # earlier subtasks succeeded: their objects are at their goals
                    cell._set_object(done, cell.goals[done])
                cell.sim.forward()
                self.goal_objects = [plan[self.subtask]]
            if self.start == "held":
                self._pick(self.goal_objects[0])
            goals = np.column_stack([cell.goals[self.goal_objects], np.zeros(len(self.goal_objects))])
        else:
            self.goal_objects = list(range(len(cell.cell_objects)))
            goals = cell.goals
        self._desired = np.asarray(goals, dtype=float).ravel()
        self._start = self._achieved()
        self.elapsed_steps = 0

    def _pick(self, obj: int) -> None:
        """``rl.start=held``: the scripted expert's picking stage of ``obj`` (above it, down onto its top face, cup
        on, lifted to transit height), so the episode is the placing half alone. Its steps are not the episode's."""
        from hrc_lab.env.robot.expert import ScriptedExpert

        expert = ScriptedExpert(self.cell)
        expert.move = expert.plan.index(obj)
        while (step := expert.act()) is not None and step.stage == PICK and step.obj == obj:
            self.cell.step(step.action)

    def _poses(self) -> np.ndarray:
        return np.column_stack([self.cell.object_positions(), self.cell.object_yaws()])

    def _achieved(self) -> np.ndarray:
        return self._poses()[self.goal_objects, : self.dims_per_object].ravel()

    def _observation(self) -> np.ndarray:
        cell = self.cell
        eef_quat = cell.sim.data.xquat[cell.sim.model._model.site_bodyid[cell._grip_site]]
        held = [float(cell.suction.held >= 0)]
        return np.concatenate([cell.arm_qpos(), cell.eef_position(), eef_quat, self._poses().ravel(), held])

    def _obs(self) -> dict[str, np.ndarray]:
        return {
            "observation": self._observation().astype(np.float32),
            "achieved_goal": self._achieved().astype(np.float32),
            "desired_goal": self._desired.astype(np.float32),
        }


def make_goal_env(env_cfg: Any, rl_cfg: Any, seed: int | None = None, subtask: int | None = 0,
                  cases: tuple[int, ...] = ()) -> HRCGoalEnv:
    """The goal env of an ``env`` config of a robot cell (what ``ENVS.build`` makes of it) and an ``rl`` config
    (``steps_per_subtask``, ``delta_r``, ``suction``); ``subtask`` as in :class:`HRCGoalEnv` (error correction
    only); ``cases``: a package-to-order cell draws its CASE from these per episode (the DRL baseline of Table 4.3
    trains on both)."""
    from hrc_lab.env import ENVS

    cell = ENVS.build(env_cfg, seed=seed)
    return HRCGoalEnv(cell, subtask=subtask, steps_per_subtask=rl_cfg.steps_per_subtask, delta_r=rl_cfg.delta_r,
                      cases=cases, suction=rl_cfg.suction, start=rl_cfg.start)
