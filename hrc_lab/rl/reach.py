"""A reach in the robot cell: the agent's sanity check before any pick and place.

:class:`ReachGoalEnv` is :class:`~hrc_lab.rl.goal_env.HRCGoalEnv` with the lip as the achieved goal and a point up
to ``reach_m`` from the lip's start (never below it) as the desired goal: the same cell, observation, 3.3 action
and Eq. 3.6 reward (over [x, y, z]); the part stays in the scene but is not the goal. If DDPG + HER cannot learn
this, no result of Fig. 3.12 / 3.13 or Table 4.3's DRL row says anything about guidance;
``scripts/rl_reach_check.py`` prints its curve.
"""

from __future__ import annotations

import numpy as np

from hrc_lab.rl.goal_env import HRCGoalEnv


class ReachGoalEnv(HRCGoalEnv):
    """Reach a point up to ``reach_m`` (per axis, upwards only in z) from the lip's start within ``delta_r``."""

    def __init__(self, *args, reach_m: float = 0.15, **kwargs) -> None:
        if reach_m <= 0:
            raise ValueError(f"reach_m must be > 0 m, got {reach_m}")
        self.reach_m = reach_m
        super().__init__(*args, **kwargs)  # its spaces already come from this class's 3-D goals
        self.dims_per_object = 3  # Eq. 3.6 over [x, y, z]

    def _reset_scene(self) -> None:
        super()._reset_scene()
        offset = self.np_random.uniform(-self.reach_m, self.reach_m, 3)
        offset[2] = abs(offset[2])
        self._desired = self.lip() + offset

    def _achieved(self, poses: np.ndarray | None = None) -> np.ndarray:
        return self.lip()


def make_reach_env(env_cfg, rl_cfg, seed: int | None = None, reach_m: float = 0.15) -> ReachGoalEnv:
    """:class:`ReachGoalEnv` in the cell of ``env_cfg`` (an error-correction config), with ``rl_cfg``'s
    ``steps_per_subtask``, ``delta_r`` and ``suction``."""
    from hrc_lab.env import ENVS

    return ReachGoalEnv(ENVS.build(env_cfg, seed=seed), steps_per_subtask=rl_cfg.steps_per_subtask,
                        delta_r=rl_cfg.delta_r, suction=rl_cfg.suction, reach_m=reach_m)
