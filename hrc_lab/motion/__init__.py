"""Motion module of Ch.3 and Ch.4: sub-goal planners (task-conditioned VI and the VI, GPR, MLP baselines), the
neural dynamic planner and the two-level execution, and the RRT-Connect baseline of Table 4.3;
``conf/motion/<name>.yaml`` selects one by ``name``."""

from hrc_lab.motion.configs import MOTIONS

__all__ = ["MOTIONS"]
