"""Task and motion planning in the robot cell (thesis 4.2, Algorithm 2); ``conf/tamp/<name>.yaml`` selects one of
Table 4.3's systems (ours, RM+RRT-Connect, DRL) as a preset over the reasoning, motion and rl groups.

- :mod:`~hrc_lab.tamp.configs`: the ``tamp`` schema and registry ``TAMPS`` (no torch import);
- :mod:`~hrc_lab.tamp.algorithm2`: the reasoning module and a motion module in closed loop in the cell;
- :mod:`~hrc_lab.tamp.systems`: the systems ``TAMPS.build(cfg.tamp)`` makes, each with its own training, trials
  and videos (the Table 4.3 protocol runs them all the same way).
"""

from hrc_lab.tamp.configs import TAMPS

__all__ = ["TAMPS"]
