"""Ch.6 grasp-solution reasoning: detector features -> weighted scene graph -> WL-GNN graspability and an LSTM with
attention decoding the solution; ``conf/grasp/<name>.yaml`` selects the method (the thesis' GNN_Att or a baseline)."""

from hrc_lab.grasp.configs import GRASPS

__all__ = ["GRASPS"]
