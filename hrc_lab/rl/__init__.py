"""Reinforcement learning in the robot cells: DDPG with Hindsight Experience Replay and the hybrid hierarchical
guidance of Algorithm 1; ``conf/rl/<name>.yaml`` selects an agent by ``name``.

- :mod:`~hrc_lab.rl.configs`: the ``rl`` config schema and the registry ``RLS`` (no torch import);
- :mod:`~hrc_lab.rl.goal_env`: the cells of :mod:`hrc_lab.env.robot` as a gymnasium goal env (observation,
  achieved and desired goal; sparse reward of Eq. 3.6 / 4.7, recomputed in batches for HER): the DRL setting of
  thesis 3.3 (error correction, one pick-and-place subtask of 40 steps per episode, goal = the position and yaw
  of the object the task label names, effector disabled after a collision) and the DRL baseline of 4.4.3 /
  Table 4.3 (package-to-order, goal = the selected products in their slots, the others where they are);
- :mod:`~hrc_lab.rl.guidance`: Algorithm 1 (3.2.3, results 3.4.3, Fig. 3.13): in an episode guided with
  probability lambda, the policy's action is replaced by the neural dynamic planner's d(Delta_t) towards the
  sub-goal planner's p'_T when the end effector it would reach is farther than delta_g from p'_T;
- :mod:`~hrc_lab.rl.ddpg`: stable-baselines3's DDPG with the HER paper's action penalty, random exploration
  actions and clipped critic targets (``HerDDPG``), the base of both agents;
- :mod:`~hrc_lab.rl.agent`: the stable-baselines3 agents built from an ``rl`` config (``RLS.build``), training
  by episodes, evaluation, and checkpoints for MLflow;
- :mod:`~hrc_lab.rl.evaluation`: the held-out evaluation scenes of Ch.3's agents (their seed stream), which a saved
  agent's evaluation is replayed on.
"""

from hrc_lab.rl.configs import RLS

__all__ = ["RLS"]
