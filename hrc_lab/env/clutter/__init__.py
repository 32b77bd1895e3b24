"""The cluttered-parts world of Ch.6 (thesis Sec. 6.3): parts a, b, c dropped on a table, seen from above.

- :mod:`~hrc_lab.env.clutter.spec`: the scene spec (``conf/env/clutter*.yaml``: parts, drop, camera, gripper) and
  the data a rendered scene carries, no simulator;
- :mod:`~hrc_lab.env.clutter.scenes`: the simulator, pure MuJoCo: drop, settle and render scenes, the data sets of
  the Ch.6 experiments (saved as ``.npz``);
- :mod:`~hrc_lab.env.clutter.rule`: the labelling rule (the expert the models learn from): graspable parts,
  blockers, solutions and Algorithm 4's iteration, pure numpy.

This package imports nothing itself: the spec and the rule stay light, MuJoCo is imported with the scenes module.
"""
