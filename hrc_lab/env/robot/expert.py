"""Scripted expert of the thesis' demonstration protocol (4.3; preference of 3.2.2), for every cell environment.

Each object manipulation is two stages of three designed sub-goals for the cup's lip:

- picking: above the object -> down to its top face -> (suction on) lifted to transit height;
- placing: a point before the goal at transit height -> above the goal -> down onto the goal (suction off).

Between sub-goals the expert acts in joint space: a damped least-squares step on the MuJoCo Jacobian of the lip
w.r.t. [base, shoulder, elbow] (wrist joints follow the tool-down rule), scaled so no joint moves more than 5 deg.
It prefers to reduce the x-y error before the vertical one (3.2.2); only when the sub-goal is higher than the
lip does it rise first, so it never drags a part sideways through the box wall. The Jacobian and the error are
taken at the commanded configuration (the servo lags by about one step). At most 30 steps per sub-goal, then it
moves on whether or not the sub-goal was reached, so its own success rate is a measurement.

``placement_noise`` (m, std per x-y axis) aims each placing stage at a point around the goal instead of the goal,
as the thesis' keyboard-teleoperated demonstrations did (Fig. 3.8: goal-state differences up to 0.1 m); the aim
is drawn from the expert's own ``rng``, so the scenes stay those of the noise-free expert. Without it, a part the
expert placed sits exactly where the benchmark says in every demonstration of a later stage. Off by default:
0.015 m did not rescue Table 3.1's second objects (issue 4's notes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrc_lab.env.robot.cell import PICK, PLACE, HRCCell

HOVER = 0.08  # above an object / goal before descending, m
APPROACH_OFFSET = np.array([0.0, -0.10])  # x-y of the "point relative to the goal" (towards the pending area)


@dataclass
class ExpertStep:
    action: np.ndarray
    obj: int
    stage: int  # PICK or PLACE
    label: int  # the environment's stage label (pick/place x object)
    subgoal_index: int  # 0..2 within the stage
    subgoal: np.ndarray  # (3,) target of the lip


class ScriptedExpert:
    """Call :meth:`act` once per control step until it returns None. ``objects``: the objects it moves, in order
    (default: the cell's whole plan, ``expert_plan()``; e.g. one subtask's object in the RL goal env)."""

    def __init__(self, env: HRCCell, max_steps_per_subgoal: int = 30, tolerance: float = 0.006,
                 damping: float = 0.05, placement_noise: float = 0.0,
                 rng: np.random.Generator | None = None, objects: list[int] | None = None) -> None:
        if placement_noise < 0:
            raise ValueError(f"placement_noise must be >= 0 m, got {placement_noise}")
        if placement_noise and rng is None:
            raise ValueError("placement_noise needs an rng (the scene's own generator must not be consumed)")
        self.env = env
        self.placement_noise = placement_noise
        self.rng = rng
        self.max_steps = max_steps_per_subgoal
        self.tolerance = tolerance
        self.damping = damping
        self.objects = None if objects is None else list(objects)  # None: the cell's whole plan
        self.reset()

    def reset(self) -> None:
        self.plan = list(self.env.expert_plan()) if self.objects is None else list(self.objects)
        self.move = 0
        self.stage = PICK
        self.index = 0
        self.steps = 0
        self.suction = False
        self.subgoals: np.ndarray | None = None

    # --- sub-goals ----------------------------------------------------------------------------------------------

    def _transit_z(self, half_z: float) -> float:
        return self.env.table_offset[2] + self.env.transit_height + half_z

    def designed_subgoals(self, obj: int, stage: int) -> np.ndarray:
        """(3, 3) lip targets of one stage, from the scene as it is now."""
        env = self.env
        half_z = env.cell_objects[obj].half_size[2]
        transit = self._transit_z(half_z)
        if stage == PICK:
            top = env.object_positions()[obj] + np.array([0.0, 0.0, half_z])
            return np.array([top + [0, 0, HOVER], top + [0, 0, 0.002], [top[0], top[1], transit]])
        goal_top = env.goals[obj] + np.array([0.0, 0.0, half_z])
        if self.placement_noise:  # a human teleoperator's aim (Fig. 3.8): the whole placing stage shifted in x-y
            goal_top[:2] += self.rng.normal(0.0, self.placement_noise, 2)
        approach = np.array([*(goal_top[:2] + APPROACH_OFFSET), transit])
        return np.array([approach, goal_top + [0, 0, HOVER], goal_top + [0, 0, 0.003]])

    # --- control ------------------------------------------------------------------------------------------------

    def _waypoint(self, lip: np.ndarray, subgoal: np.ndarray) -> np.ndarray:
        """Expert preference: rise first if the sub-goal is higher, then x-y, then the vertical approach."""
        planar = np.linalg.norm(subgoal[:2] - lip[:2])
        if planar > self.tolerance and subgoal[2] > lip[2] + self.tolerance:
            return np.array([lip[0], lip[1], subgoal[2]])
        if planar > self.tolerance:
            return np.array([subgoal[0], subgoal[1], lip[2]])
        return subgoal

    def joint_step(self, subgoal: np.ndarray) -> np.ndarray:
        """Damped least-squares joint deltas towards the next waypoint, scaled to the 5 deg limit."""
        lip, jac = self.env.lip_kinematics(self.env.commanded_qpos())
        error = self._waypoint(lip, subgoal) - lip
        dq = jac.T @ np.linalg.solve(jac @ jac.T + self.damping**2 * np.eye(3), error)
        largest = np.abs(dq).max()
        if largest > self.env.max_joint_step:
            dq *= self.env.max_joint_step / largest
        return dq

    def reached(self, subgoal: np.ndarray) -> bool:
        """Whether the lip is at ``subgoal``: within ``tolerance`` at the commanded joints and twice that measured."""
        lip_cmd, _ = self.env.lip_kinematics(self.env.commanded_qpos())
        lip = self.env.eef_position()
        return np.linalg.norm(subgoal - lip_cmd) < self.tolerance and np.linalg.norm(subgoal - lip) < 2 * self.tolerance

    def _advance(self) -> bool:
        """Next sub-goal; False when the plan is finished."""
        if self.stage == PICK and self.index == 1:
            self.suction = True
        if self.stage == PLACE and self.index == 2:
            self.suction = False
        self.index += 1
        self.steps = 0
        if self.index == 3:
            self.index = 0
            self.subgoals = None
            if self.stage == PICK:
                self.stage = PLACE
            else:
                self.stage = PICK
                self.move += 1
        return self.move < len(self.plan)

    def act(self) -> ExpertStep | None:
        if self.move >= len(self.plan):
            return None
        obj = self.plan[self.move]
        if self.subgoals is None:
            self.subgoals = self.designed_subgoals(obj, self.stage)
        subgoal = self.subgoals[self.index]
        if self.steps >= self.max_steps or self.reached(subgoal):
            releasing = self.stage == PLACE and self.index == 2
            label = self.env.stage_label(obj, self.stage)
            if not self._advance() or releasing:
                # one step with suction off releases the part before the next stage starts
                return ExpertStep(self._action(np.zeros(3)), obj, PLACE, label, 2, subgoal)
            return self.act()
        self.steps += 1
        return ExpertStep(
            self._action(self.joint_step(subgoal)), obj, self.stage, self.env.stage_label(obj, self.stage),
            self.index, subgoal.copy(),
        )

    def _action(self, dq: np.ndarray) -> np.ndarray:
        # with a wrist-3 action (3.3's q'_wrist3), wrist 3 turns with the base, so the tool's yaw and a held
        # part's stay as they were gripped: a part is delivered at the yaw it had (the goal's, Eq. 3.6's psi = 0)
        extra = [self.env.wrist3_holding_yaw(dq[0])] if self.env.yaw_action else []
        return np.array([*dq, *extra, 1.0 if self.suction else -1.0])


def run_episode(env: HRCCell, expert: ScriptedExpert | None = None, record: bool = False):
    """Reset ``env`` and let the expert act until its plan ends or the horizon is hit.

    Returns ``(success, steps, trace)``; ``trace`` holds per-step dicts when ``record`` (with robosuite's
    observations: the cell then computes them at every step).
    """
    env.step_observations = env.step_observations or record
    env.reset()
    expert = expert or ScriptedExpert(env)
    expert.reset()
    trace, info, steps = [], {"success": False}, 0
    while (step := expert.act()) is not None and not env.done:
        obs, reward, done, info = env.step(step.action)
        steps += 1
        if record:
            trace.append({"step": step, "obs": obs, "reward": reward, "done": done, "info": info})
    return bool(info.get("success", False)), steps, trace
