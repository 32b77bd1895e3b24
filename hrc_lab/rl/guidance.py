"""Algorithm 1 (thesis 3.2.3, results 3.4.3, Fig. 3.13): hybrid hierarchical guided RL, as DDPG + HER whose
exploration the trained two-level planner corrects.

Per episode, with probability lambda (drawn from the wrapper's own seeded generator), the episode is guided: the
classifier c(x_1) names the object (the task label), and in every control step t of high-level step T

    p'_T       = h(x_T, l_T)                        the sub-goal planner's current sub-goal
    a_t        = the policy's action (with its exploration noise)
    p_{t+1}    = FK(q_cmd + a_t)                    the lip after a_t, by forward kinematics, not by stepping
    if |p'_T - p_{t+1}| > delta_g:                  (delta_g = 0.05 m)
        a_t    = d(Delta_t),  Delta_t = p'_T - p_t  the neural dynamic planner's action

and the executed a_t, corrected or not, is what the replay buffer stores. Unguided episodes are pure DDPG
exploration; HER relabels both alike (with ``rl.guided_episodes=demos`` the guided episodes are also the agent's
demonstrations, :mod:`hrc_lab.rl.ddpg`).

:class:`GuidedEnv` is an env wrapper: it receives the policy's action, corrects it, and reports the executed action
in ``info``, which :class:`~hrc_lab.rl.ddpg.HerDDPG` stores; so guidance runs beside its env, in the env's own
process with ``rl.n_envs`` > 1. The correction rule itself is the pure function :func:`needs_correction`;
:func:`corrected_action` builds the executed action.

The guide is an object with the :class:`Guide` interface; :class:`CorrectionGuide` is the two-level planner of
:mod:`hrc_lab.motion` in the error-correction cell (the classifier, the sub-goal planner and the dynamic planner
as :func:`hrc_lab.motion.two_level.run_correction` uses them).
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from hrc_lab.env.robot.cell import PICK, PLACE
from hrc_lab.motion.two_level import (
    correction_input,
    correction_object,
    correction_reference,
    grasp_shift,
    picking_label,
)


def needs_correction(predicted: np.ndarray, subgoal: np.ndarray, delta_g: float) -> bool:
    """Algorithm 1's rule: correct the action when the lip it leads to, ``predicted`` (p_{t+1}), is farther than
    ``delta_g`` from the sub-goal p'_T."""
    return bool(np.linalg.norm(np.asarray(subgoal, dtype=float) - np.asarray(predicted, dtype=float)) > delta_g)


def corrected_action(action: np.ndarray, joint_deltas: np.ndarray, suction: float | None,
                     wrist3: float | None = None) -> np.ndarray:
    """The executed action in [-1, 1] when the guide corrects ``action``: the dynamic planner's [base, shoulder,
    elbow] deltas (already in [-1, 1] units), the guide's wrist-3 delta (``None`` when the action has no wrist-3
    dimension, ``env.sim.yaw_action=false``) and its suction command (``None`` when the action has no suction
    dimension, ``rl.suction=auto``)."""
    out = np.array(action, dtype=np.float32, copy=True)
    out[:3] = np.clip(joint_deltas, -1.0, 1.0)
    if wrist3 is not None:
        out[3] = np.clip(wrist3, -1.0, 1.0)
    if suction is not None:
        out[-1] = suction
    return out


class Guide(Protocol):
    """What Algorithm 1 asks of the trained two-level planner in a guided episode (``env``: the
    :class:`~hrc_lab.rl.goal_env.HRCGoalEnv`)."""

    def reset(self, env: Any) -> None:
        """A guided episode starts: classify the task from x_1."""

    def subgoal(self, env: Any) -> np.ndarray:
        """p'_T for this control step (called once per step of a guided episode)."""

    def act(self, env: Any, subgoal: np.ndarray) -> tuple[np.ndarray, float]:
        """d(Delta_t): [dq_base, dq_shoulder, dq_elbow] in radians, and a suction command (+1 on, -1 off)."""


class CorrectionGuide:
    """The two-level planner of Ch.3 guiding an error-correction subtask.

    ``classifier`` c(x) (x = three object positions, end effector; :class:`~hrc_lab.motion.subgoal.StageClassifier`)
    names the object at the episode's start; ``planner`` h (:class:`~hrc_lab.motion.subgoal.SubgoalPlanner`)
    proposes ``n_subgoals`` sub-goals per stage from [object positions at the stage's start, lip]; ``ndp`` d
    (:class:`~hrc_lab.motion.subgoal.DynamicPlanner`, regression or direction mode) acts towards the sub-goal.
    The next sub-goal is planned once the lip is within ``tolerance`` of the current one or after
    ``subgoal_steps`` steps (H_lo). ``stage_labels`` (``rl.stage_labels``) names the object: c(x_1) by a rule of
    :func:`~hrc_lab.motion.two_level.picking_label`, or the episode's goal object (``ground_truth``). The stage
    is picking until the cup holds the object, then placing (the object is named once per episode, as per
    manipulation in the closed loop of :func:`~hrc_lab.motion.two_level.run_correction`). Suction as there: on
    from a picking stage's second sub-goal and through placing, off once the last placing sub-goal is reached.
    With the planner's ``place_through_grasp``, placing sub-goals move by the grip's offset from the part's centre
    (:func:`~hrc_lab.motion.two_level.grasp_shift`), as in the closed loop.
    """

    def __init__(self, classifier: Any, planner: Any, ndp: Any, n_subgoals: int = 5, subgoal_steps: int = 30,
                 tolerance: float = 0.008, stage_labels: str = "classifier") -> None:
        self.classifier, self.planner, self.ndp = classifier, planner, ndp
        self.n_subgoals, self.subgoal_steps, self.tolerance = n_subgoals, subgoal_steps, tolerance
        self.stage_labels = stage_labels

    @classmethod
    def from_config(cls, cfg: Any, classifier: Any, planner: Any, ndp: Any, n_subgoals: int = 5) -> CorrectionGuide:
        """H_lo, the reach tolerance and the picking rule from an ``rl`` config (``subgoal_steps``,
        ``subgoal_tolerance``, ``stage_labels``)."""
        return cls(classifier, planner, ndp, n_subgoals, cfg.subgoal_steps, cfg.subgoal_tolerance, cfg.stage_labels)

    def reset(self, env: Any) -> None:
        cell = env.cell
        if self.stage_labels == "ground_truth":  # the object whose goal the episode trains
            self.label = cell.stage_label(env.goal_objects[0], PICK)
        else:  # the object c(x_1) names, by the rule
            x = np.concatenate([cell.object_positions().ravel(), cell.eef_position()])
            self.label = picking_label(self.classifier, x, self.stage_labels)
        self.object = correction_object(self.label)
        self.stage, self.index, self.steps, self.done = PICK, 0, 0, False
        self.objects = cell.object_positions().ravel()
        self.current: np.ndarray | None = None

    def subgoal(self, env: Any) -> np.ndarray:
        cell = env.cell
        if self.stage == PICK and cell.suction.held == self.object:  # picked: the placing stage starts
            self.stage, self.label, self.index, self.done = PLACE, self.label + 1, 0, False
            self.objects, self.current = cell.object_positions().ravel(), None
        if self.current is not None and not self.done:
            reached = np.linalg.norm(self.current - cell.eef_position()) < self.tolerance
            if reached or self.steps >= self.subgoal_steps:
                if self.index + 1 < self.n_subgoals:
                    self.index, self.current = self.index + 1, None
                else:
                    self.done = True  # the stage's last sub-goal: hold it
        if self.current is None:
            x = correction_input(self.objects, env.lip(), self.label, self.planner.config.planner_input)
            reference = correction_reference(self.objects, self.label)
            mean, _ = self.planner.predict(x[None], np.array([self.label]), np.array([self.index]), reference[None])
            self.current, self.steps = mean[0], 0
            if self.planner.config.place_through_grasp:
                self.current = self.current + grasp_shift(cell.object_positions(), cell.eef_position(), self.label)
        self.steps += 1
        return self.current

    def act(self, env: Any, subgoal: np.ndarray) -> tuple[np.ndarray, float]:
        suction = (self.stage == PICK and self.index > 0) or (self.stage == PLACE and not self.done)
        return self.ndp.act(env.lip(), subgoal), 1.0 if suction else -1.0

    @property
    def ndp_mode(self) -> str:
        return self.ndp.config.mode


class GuidedEnv(gym.Wrapper):
    """Algorithm 1 around a :class:`~hrc_lab.rl.goal_env.HRCGoalEnv` (module docstring): at each reset the episode
    is guided with probability ``lam`` (drawn from a generator seeded with ``seed``); in a guided episode the
    action the policy proposes is replaced by the guide's when the lip it leads to is farther than ``delta_g``
    from the guide's sub-goal. The reset's ``info`` says ``guided``; each step's says ``guided``, ``corrected``
    and, when corrected, the ``executed_action`` (in [-1, 1]), which the agent stores instead of its own
    (:class:`~hrc_lab.rl.ddpg.HerDDPG`). A wrapper, so that it runs where its env runs (one process per env with
    ``rl.n_envs`` > 1); the guide is pickled into that process."""

    def __init__(self, env: gym.Env, guide: Guide, lam: float, delta_g: float, seed: int | None = None) -> None:
        super().__init__(env)
        self.guide, self.lam, self.delta_g = guide, lam, delta_g
        self.rng = np.random.default_rng(seed)
        self.guided = False

    def reset(self, **kwargs) -> tuple[dict, dict]:
        obs, info = self.env.reset(**kwargs)
        self.guided = bool(self.rng.random() < self.lam)
        if self.guided:
            self.guide.reset(self.unwrapped)
        return obs, {**info, "guided": self.guided}

    def correction(self, action: np.ndarray) -> np.ndarray | None:
        """The guide's action when Algorithm 1 corrects ``action`` in this step, else None."""
        env = self.unwrapped
        subgoal = self.guide.subgoal(env)
        if not needs_correction(env.predicted_lip(action), subgoal, self.delta_g):
            return None
        deltas, suction = self.guide.act(env, subgoal)
        deltas = np.asarray(deltas) / env.max_joint_step
        # the planner moves the lip; wrist 3 keeps the tool's yaw, as in the demonstrations it learned from
        return corrected_action(action, deltas, suction if env.suction_action else None, env.hold_yaw_action(deltas[0]))

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        executed = self.correction(action) if self.guided else None
        obs, reward, terminated, truncated, info = self.env.step(action if executed is None else executed)
        info.update(guided=self.guided, corrected=executed is not None, executed_action=executed)
        return obs, reward, terminated, truncated, info
